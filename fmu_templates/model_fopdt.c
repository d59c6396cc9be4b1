/* Scheduled FOPDT dynamics: T dx/dt = K u(t - L) - x, exact for piecewise-constant input.
 * A step is one piece, or the pieces of the actuator's grid when a rate limit moves the gate
 * (see effects.h); the sensor lag is integrated with x over every interval.
 *
 * The dead time is served from a history of input change points; mirrors
 * PlantSimulator._fopdt_step / _prune_history / _last_arrived_index in
 * gatetwin/plant/simulate.py operation by operation.
 */
#include <math.h>

#include "blocks.h"
#include "plant.h"

#if GT_ENVELOPE
/* Envelope FOPDT: the target is the gate law's steady level at the arrived opening and the
 * step's discharge, the time constant the storage's secant from the level to there
 * (kernel_support.c, physical_kernel.c). */
#include "kernel_support.h"
#include "physical_kernel.h"
#define KERNEL(m) (&(m)->real[VR_KERNEL_FIRST])
#endif

#define GAIN(m) (&(m)->real[VR_COL_GAIN_MM_PER_MM])
#define TIME_CONSTANT(m) (&(m)->real[VR_COL_TIME_CONSTANT_S])
#define DEAD_TIME(m) (&(m)->real[VR_COL_DEAD_TIME_S])

/* logical history index j (0 = oldest) -> ring slot */
static int slot(const DynamicsState *d, int j)
{
    return (d->head + j) % GT_HISTORY_CAPACITY;
}

PlantStatus dynamics_check_parameters(const ModelData *m, PlantMessage *msg)
{
    int k;
    for (k = 0; k < GT_N_KNOTS; k++) {
        const int vr_tau = VR_COL_TIME_CONSTANT_S + k;
        const int vr_delay = VR_COL_DEAD_TIME_S + k;
        if (!(m->real[vr_tau] > 0.0)) {
            plant_message(msg, "%s = %.17g must be > 0", plant_variables[vr_tau].name,
                          m->real[vr_tau]);
            return PLANT_ERROR;
        }
        if (!(m->real[vr_delay] >= 0.0)) {
            plant_message(msg, "%s = %.17g must be >= 0", plant_variables[vr_delay].name,
                          m->real[vr_delay]);
            return PLANT_ERROR;
        }
        if (m->initialized && m->real[vr_delay] > m->dyn.max_dead_time_s) {
            plant_message(msg,
                          "%s = %.17g exceeds the dead-time horizon %.17g s fixed at "
                          "initialisation (older inputs are no longer held)",
                          plant_variables[vr_delay].name, m->real[vr_delay],
                          m->dyn.max_dead_time_s);
            return PLANT_ERROR;
        }
    }
#if GT_ENVELOPE
    return kernel_check_parameters(m, msg);
#else
    return PLANT_OK;
#endif
}

PlantStatus dynamics_equilibrium(const ModelData *m, double u_mm, const KnotPosition *at,
                                 double *x0_mm, PlantMessage *msg)
{
    double k = plant_interp(at, GAIN(m));
    double tau = plant_interp(at, TIME_CONSTANT(m));
    (void)msg;
    effects_fopdt_parameters(m, m->real[VR_FLOW_M3H], &k, &tau);
#if GT_ENVELOPE
    kernel_envelope_point(KERNEL(m), u_mm + m->real[VR_OPENING_REF_MM], m->real[VR_FLOW_M3H],
                          x0_mm, &tau);
#else
    *x0_mm = k * u_mm;
#endif
    return PLANT_OK;
}

void dynamics_initialize(ModelData *m, double u_mm, double x0_mm)
{
    DynamicsState *d = &m->dyn;
    int k;
    d->x = x0_mm;
    d->head = 0;
    d->count = 1;
    d->change_t[0] = m->time_s;
    d->change_u[0] = u_mm;
    d->tail_m = 0.0;
#if GT_ENVELOPE
    gt_tail_steady_m(m->real[VR_FLOW_M3H], KERNEL(m), &d->tail_m);
#endif
    d->max_dead_time_s = DEAD_TIME(m)[0];
    for (k = 1; k < GT_N_KNOTS; k++) {
        if (DEAD_TIME(m)[k] > d->max_dead_time_s) {
            d->max_dead_time_s = DEAD_TIME(m)[k];
        }
    }
}

/* Refuse a step whose input changes would overflow the history, before anything changes. */
PlantStatus dynamics_check_step(const ModelData *m, double step_s, double command_mm,
                                PlantMessage *msg)
{
    const DynamicsState *d = &m->dyn;
#if GT_HAS_RATE_LIMIT
    const double delta = m->real[VR_FX_RATE_LIMIT_SUBSTEP_S];
    const double origin = m->fx.grid_origin_s;
    const double t0 = m->time_s;
    const double k0 = gt_grid_index_at_or_after(t0, origin, delta);
    const double k1 = gt_grid_index_at_or_after(t0 + step_s, origin, delta);
    const double pieces = k1 - k0 + (origin + k0 * delta == t0 ? 0.0 : 1.0);
    (void)command_mm;
    if (d->count + pieces > GT_HISTORY_CAPACITY) {
        plant_message(msg,
                      "communication step %.17g s spans %.0f actuator sub-steps; with the %d "
                      "input changes held for the dead time they exceed the dead-time history "
                      "(%d)",
                      step_s, pieces, d->count, GT_HISTORY_CAPACITY);
        return PLANT_ERROR;
    }
#else
    EffectState probe = m->fx;
    double u_mm;
    effects_actuate(m, &probe, command_mm, step_s);
    u_mm = effects_input(m, probe.gate_mm);
    if (u_mm != d->change_u[slot(d, d->count - 1)] && d->count >= GT_HISTORY_CAPACITY) {
        plant_message(msg, "input changes faster than the dead-time history can hold "
                           "(%d change points within the longest dead time)",
                      GT_HISTORY_CAPACITY);
        return PLANT_ERROR;
    }
#endif
    return PLANT_OK;
}

/* Newest change that has arrived at the plant by t: change_t[j] + delay <= t (0 if none). */
static int last_arrived(const DynamicsState *d, double delay_s, double t)
{
    int j = d->count - 1;
    while (j > 0 && d->change_t[slot(d, j)] + delay_s > t) {
        j--;
    }
    return j;
}

/* Drop the oldest change once the next one has arrived for every dead time up to the horizon. */
static void prune(DynamicsState *d, double t_now)
{
    while (d->count > 1 && d->change_t[slot(d, 1)] + d->max_dead_time_s <= t_now) {
        d->head = slot(d, 1);
        d->count--;
    }
}

void dynamics_derive(const ModelData *m, double flow_m3h, const KnotPosition *at,
                     DynamicsCache *c)
{
    c->gain = plant_interp(at, GAIN(m));
    c->tau_s = plant_interp(at, TIME_CONSTANT(m));
    c->delay_s = plant_interp(at, DEAD_TIME(m));
    c->level_ref_mm = plant_interp(at, &m->real[VR_COL_LEVEL_REF_MM]);
    effects_fopdt_parameters(m, flow_m3h, &c->gain, &c->tau_s);
    c->decay_filled = 0;
    c->decay_next = 0;
#if GT_ENVELOPE
    c->point_valid = 0;
#endif
}

/* The first-order decay over duration_s at the time constant tau_s, from the cache when a
 * slot holds it for both (the exponential only for a piece unlike the last few). */
static double cached_decay(ModelData *m, double duration_s, double tau_s)
{
    DynamicsCache *c = &m->cache.dyn;
    int i;
    for (i = 0; i < c->decay_filled; i++) {
        if (plant_same_bits(c->decay_duration_s[i], duration_s) &&
            plant_same_bits(c->decay_tau_s[i], tau_s)) {
            return c->decay[i];
        }
    }
    i = c->decay_next;
    c->decay[i] = gt_first_order_decay(duration_s, tau_s);
    c->decay_duration_s[i] = duration_s;
    c->decay_tau_s[i] = tau_s;
    c->decay_next = (i + 1) % GT_DECAY_SLOTS;
    if (c->decay_filled < GT_DECAY_SLOTS) {
        c->decay_filled++;
    }
    return c->decay[i];
}

#if GT_ENVELOPE
/* The envelope's steady level, tangent time constant and depth at the input deviation u and
 * the cached discharge. */
static void steady_point(const ModelData *m, double u_mm, double *level_mm, double *tau_s,
                         double *depth_m)
{
    kernel_envelope_steady(KERNEL(m), u_mm + m->real[VR_OPENING_REF_MM], m->cache.flow_m3h,
                           level_mm, tau_s, depth_m);
}

/* The time constant of a piece that starts at the level x for the input u: the secant of the
 * storage equation from x to the steady point at u (the steady solve only when the arrived
 * input, the discharge or a parameter changed). */
static void piece_point(ModelData *m, double u_mm, double x_mm, double *level_mm, double *tau_s)
{
    DynamicsCache *c = &m->cache.dyn;
    if (!c->point_valid || !plant_same_bits(c->point_u_mm, u_mm)) {
        steady_point(m, u_mm, &c->point_level_mm, &c->point_tau_s, &c->point_depth_m);
        c->point_u_mm = u_mm;
        c->point_valid = 1;
    }
    *level_mm = c->point_level_mm;
    gt_secant_time_constant_s(x_mm, c->point_level_mm, c->point_depth_m, c->point_tau_s,
                              u_mm + m->real[VR_OPENING_REF_MM], m->cache.flow_m3h, KERNEL(m),
                              tau_s);
}

/* Whether the gate discharges into a pool of its own. */
static int tail_pool(const ModelData *m)
{
    double has;
    gt_has_tail(KERNEL(m), &has);
    return has != 0.0;
}

/* A piece of an envelope FOPDT with a pool below the gate: the kernel's tail_pool_piece over
 * its sub-steps, the steady depth at the pool's depth at the start of each
 * (PlantSimulator._tail_pool_piece). */
static void tail_piece(ModelData *m, double u_mm, double duration_s)
{
    DynamicsState *d = &m->dyn;
    const double *p = KERNEL(m);
    const double e = u_mm + m->real[VR_OPENING_REF_MM];
    const double q = m->cache.flow_m3h;
    double n, k;
    gt_substep_count(duration_s, p, &n);
    for (k = 0.0; k < n; k += 1.0) {
        const double steady = kernel_tail_steady_depth_m(p, d->tail_m, e, q);
        gt_tail_pool_piece(d->x, d->tail_m, steady, e, q, duration_s / n, p, &d->x, &d->tail_m);
    }
}
#endif

/* The dynamics over [t_start, t_end) with the input u held (one piece of a step); p holds
 * the step's K, T, L and level_ref. */
static void piece(ModelData *m, double t_start, double t_end, double u_mm,
                  const DynamicsCache *p)
{
    DynamicsState *d = &m->dyn;
    double t = t_start;
    if (u_mm != d->change_u[slot(d, d->count - 1)]) {
        d->change_t[slot(d, d->count)] = t_start;
        d->change_u[slot(d, d->count)] = u_mm;
        d->count++;
    }
    while (t < t_end) {
        const int j = last_arrived(d, p->delay_s, t);
        double t_next = t_end;
        double target;
        double tau_s = p->tau_s;
        if (j + 1 < d->count) {
            const double arrival = d->change_t[slot(d, j + 1)] + p->delay_s;
            if (arrival < t_next) {
                t_next = arrival;
            }
        }
#if GT_ENVELOPE
        if (tail_pool(m)) {
            tail_piece(m, d->change_u[slot(d, j)], t_next - t);
            t = t_next;
            continue;
        }
        piece_point(m, d->change_u[slot(d, j)], d->x, &target, &tau_s);
#else
        target = p->gain * d->change_u[slot(d, j)];
#endif
        effects_lag_interval(m, p->level_ref_mm + target, d->x - target, t_next - t, tau_s);
        d->x = gt_relax(d->x, target, cached_decay(m, t_next - t, tau_s));
        t = t_next;
    }
    prune(d, t_end);
}

void dynamics_step(ModelData *m, double step_s, double command_mm)
{
    EffectState *fx = &m->fx;
    const DynamicsCache *p = &m->cache.dyn; /* derived for this step's discharge (plant.c) */
    const double t0 = m->time_s;
    const double t1 = t0 + step_s;
#if GT_HAS_RATE_LIMIT
    {
        /* the gate moves; the dynamics see it sampled on the grid origin + k * substep */
        const double delta = m->real[VR_FX_RATE_LIMIT_SUBSTEP_S];
        const double origin = fx->grid_origin_s;
        double k = gt_grid_index_at_or_after(t0, origin, delta);
        double tk = origin + k * delta;
        double t_start = t0, t_act = t0;
        for (;;) {
            if (tk > t_start) {
                const double t_end = tk < t1 ? tk : t1;
                piece(m, t_start, t_end, effects_input(m, fx->held_gate_mm), p);
                effects_seiche_piece(m, t_end - t_start, fx->held_gate_mm);
                if (!(tk < t1)) {
                    break;
                }
                t_start = tk;
            }
            effects_actuate(m, fx, command_mm, tk - t_act);
            fx->held_gate_mm = fx->gate_mm;
            t_act = tk;
            k += 1.0;
            tk = origin + k * delta;
        }
        effects_actuate(m, fx, command_mm, t1 - t_act);
    }
#else
    effects_actuate(m, fx, command_mm, step_s);
    fx->held_gate_mm = fx->gate_mm;
    piece(m, t0, t1, effects_input(m, fx->gate_mm), p);
    effects_seiche_piece(m, t1 - t0, fx->gate_mm);
#endif
}

/* A restored history: ring indices in range, >= 1 change once initialised, every entry finite,
 * the held change times in order and not after the state's time. */
PlantStatus dynamics_check_state(const ModelData *m, PlantMessage *msg)
{
    const DynamicsState *d = &m->dyn;
    int j;
    if (!(d->head >= 0 && d->head < GT_HISTORY_CAPACITY && d->count >= m->initialized &&
          d->count <= GT_HISTORY_CAPACITY)) {
        plant_message(msg, "dead-time history head %d / count %d outside 0..%d", d->head,
                      d->count, GT_HISTORY_CAPACITY);
        return PLANT_ERROR;
    }
    if (!isfinite(d->x) || !isfinite(d->tail_m) ||
        !(isfinite(d->max_dead_time_s) && d->max_dead_time_s >= 0.0)) {
        plant_message(msg,
                      "state x = %g, tail depth %g m or dead-time horizon %g s is not finite "
                      "(and >= 0)",
                      d->x, d->tail_m, d->max_dead_time_s);
        return PLANT_ERROR;
    }
    for (j = 0; j < GT_HISTORY_CAPACITY; j++) {
        if (!isfinite(d->change_t[j]) || !isfinite(d->change_u[j])) {
            plant_message(msg, "dead-time history entry %d is not finite", j);
            return PLANT_ERROR;
        }
    }
    for (j = 0; j < d->count; j++) {
        const double t = d->change_t[slot(d, j)];
        if (t > m->time_s || (j > 0 && t < d->change_t[slot(d, j - 1)])) {
            plant_message(msg, "dead-time history time %g s (entry %d) is out of order", t, j);
            return PLANT_ERROR;
        }
    }
    return PLANT_OK;
}

/* A restored cache: K, T, L and level_ref those of its discharge, each decay that of its
 * duration and T; an envelope's steady point that of its input. */
PlantStatus dynamics_check_cache(const ModelData *m, PlantMessage *msg)
{
    const DynamicsCache *c = &m->cache.dyn;
    DynamicsCache fresh;
    int i;
    dynamics_derive(m, m->cache.flow_m3h, &m->cache.at, &fresh);
    if (!plant_same_bits(c->gain, fresh.gain) || !plant_same_bits(c->tau_s, fresh.tau_s) ||
        !plant_same_bits(c->delay_s, fresh.delay_s) ||
        !plant_same_bits(c->level_ref_mm, fresh.level_ref_mm)) {
        plant_message(msg, "state's cached K, T, L, level_ref (%.17g, %.17g, %.17g, %.17g) are "
                           "not those of its discharge",
                      c->gain, c->tau_s, c->delay_s, c->level_ref_mm);
        return PLANT_ERROR;
    }
    /* the slots fill in turn: until all are in use, the next is the first free one */
    if (c->decay_filled < 0 || c->decay_filled > GT_DECAY_SLOTS || c->decay_next < 0 ||
        c->decay_next >= GT_DECAY_SLOTS ||
        (c->decay_filled < GT_DECAY_SLOTS && c->decay_next != c->decay_filled)) {
        plant_message(msg, "state's cached decays (%d filled, next %d) are not %d slots filled "
                           "in turn", c->decay_filled, c->decay_next, GT_DECAY_SLOTS);
        return PLANT_ERROR;
    }
    for (i = 0; i < c->decay_filled; i++) {
        if (!plant_same_bits(c->decay[i],
                             gt_first_order_decay(c->decay_duration_s[i], c->decay_tau_s[i]))) {
            plant_message(msg, "state's cached decay %.17g is not the one over %.17g s at T "
                               "%.17g s", c->decay[i], c->decay_duration_s[i], c->decay_tau_s[i]);
            return PLANT_ERROR;
        }
    }
#if GT_ENVELOPE
    if (plant_check_flag(c->point_valid, "cached steady-point", msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    if (c->point_valid) {
        steady_point(m, c->point_u_mm, &fresh.point_level_mm, &fresh.point_tau_s,
                     &fresh.point_depth_m);
        if (!isfinite(c->point_u_mm) ||
            !plant_same_bits(c->point_level_mm, fresh.point_level_mm) ||
            !plant_same_bits(c->point_tau_s, fresh.point_tau_s) ||
            !plant_same_bits(c->point_depth_m, fresh.point_depth_m)) {
            plant_message(msg, "state's cached steady point (%.17g mm, %.17g s) is not the one "
                               "at its input %.17g mm",
                          c->point_level_mm, c->point_tau_s, c->point_u_mm);
            return PLANT_ERROR;
        }
    }
#endif
    return PLANT_OK;
}
