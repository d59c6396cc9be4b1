/* Scheduled ARX(na, nb, nk) dynamics, paper's sign convention:
 *   x(k) = sum_i a_i x(k-i) + sum_j b_j u(k-nk-j+1),
 * stepped at the sample period; a communication step runs a whole number of samples, the input
 * blocks sampled at the start of each. The sample's arithmetic and the rest state are blocks.c's
 * gt_arx_sample and gt_arx_equilibrium (generated from gatetwin/plant/blocks.py); the control
 * flow mirrors PlantSimulator._arx_pieces in gatetwin/plant/simulate.py.
 *
 * Envelope ARX (GT_ENVELOPE): the input is the gate law's steady level at the gate and the
 * step's discharge, the pole a1 scaled by the pool's time constant there and the b rescaled to
 * unit gain (blocks.c: gt_arx_envelope_coefficients); mirrors PlantSimulator._arx_envelope.
 */
#include <math.h>

#include "blocks.h"
#include "plant.h"

#if GT_ENVELOPE
#include "kernel_support.h"
#define KERNEL(m) (&(m)->real[VR_KERNEL_FIRST])
#if GT_NA != 1
#error "an envelope ARX has one a coefficient (gatetwin.plant.model.ArxPlant)"
#endif
#endif

/* column of coefficient a_(i+1) / b_(j+1), i and j counted from 0 */
#define COLUMN_A(m, i) (&(m)->real[VR_COL_A1 + (i) * GT_N_KNOTS])
#define COLUMN_B(m, j) (&(m)->real[VR_COL_B1 + (j) * GT_N_KNOTS])

PlantStatus dynamics_check_parameters(const ModelData *m, PlantMessage *msg)
{
    if (!(m->real[VR_SAMPLE_PERIOD_S] > 0.0)) {
        plant_message(msg, "sample_period_s = %.17g must be > 0", m->real[VR_SAMPLE_PERIOD_S]);
        return PLANT_ERROR;
    }
#if GT_ENVELOPE
    return kernel_check_parameters(m, msg);
#else
    return PLANT_OK;
#endif
}

static void coefficients(const ModelData *m, const KnotPosition *at, double a[GT_NA],
                         double b[GT_NB])
{
    int i;
    for (i = 0; i < GT_NA; i++) {
        a[i] = plant_interp(at, COLUMN_A(m, i));
    }
    for (i = 0; i < GT_NB; i++) {
        b[i] = plant_interp(at, COLUMN_B(m, i));
    }
}

PlantStatus dynamics_equilibrium(const ModelData *m, double u_mm, const KnotPosition *at,
                                 double *x0_mm, PlantMessage *msg)
{
#if GT_ENVELOPE
    double tau_s;
    (void)at;
    (void)msg;
    kernel_envelope_point(KERNEL(m), u_mm + m->real[VR_OPENING_REF_MM], m->real[VR_FLOW_M3H],
                          x0_mm, &tau_s);
    return PLANT_OK;
#else
    double a[GT_NA], b[GT_NB];
    double sum_a, x0;
    coefficients(m, at, a, b);
    gt_arx_equilibrium(a, b, u_mm, GT_NA, GT_NB, &sum_a, &x0);
    if (sum_a == 1.0) {
        plant_message(msg, "arx: no equilibrium at flow_m3h = %.17g (sum of a coefficients is 1)",
                      m->real[VR_FLOW_M3H]);
        return PLANT_ERROR;
    }
    *x0_mm = x0;
    return PLANT_OK;
#endif
}

void dynamics_initialize(ModelData *m, double u_mm, double x0_mm)
{
    DynamicsState *d = &m->dyn;
    int i;
    d->x = x0_mm;
    for (i = 0; i < GT_NA; i++) {
        d->x_hist[i] = x0_mm;
    }
    for (i = 0; i < GT_ARX_U_LAGS; i++) {
        d->u_hist[i] = GT_ENVELOPE ? x0_mm : u_mm; /* an envelope ARX's input is a level */
    }
}

/* Number of samples in the step, or -1 if the step is not a whole multiple of the period. */
static double samples_in_step(const ModelData *m, double step_s, PlantMessage *msg)
{
    const double n_float = step_s / m->real[VR_SAMPLE_PERIOD_S];
    double n;
    if (!(n_float <= GT_ARX_MAX_SUBSTEPS)) {
        plant_message(msg,
                      "communication step %.17g s spans %.17g ARX samples; the limit is %.0e "
                      "samples per step",
                      step_s, n_float, GT_ARX_MAX_SUBSTEPS);
        return -1.0;
    }
    n = nearbyint(n_float); /* round half to even, as Python's round() */
    if (n < 1.0 || fabs(n_float - n) > GT_ARX_STEP_RTOL * fmax(1.0, n_float)) {
        plant_message(msg,
                      "communication step %.17g s is not a whole multiple of the ARX sample "
                      "period %.17g s",
                      step_s, m->real[VR_SAMPLE_PERIOD_S]);
        return -1.0;
    }
    return n;
}

PlantStatus dynamics_check_step(const ModelData *m, double step_s, double command_mm,
                                PlantMessage *msg)
{
    (void)command_mm;
    return samples_in_step(m, step_s, msg) < 0.0 ? PLANT_ERROR : PLANT_OK;
}

/* One ARX sample with the input u (blocks.c: gt_arx_sample); returns x(k+1). */
static double sample_step(DynamicsState *d, const double a[GT_NA], const double b[GT_NB],
                          double u_mm)
{
    d->x = gt_arx_sample(d->x_hist, d->u_hist, a, b, u_mm, GT_NA, GT_NB, GT_NK);
    return d->x;
}

void dynamics_derive(const ModelData *m, double flow_m3h, const KnotPosition *at,
                     DynamicsCache *c)
{
    (void)flow_m3h;
    coefficients(m, at, c->a, c->b);
    c->level_ref_mm = plant_interp(at, &m->real[VR_COL_LEVEL_REF_MM]);
#if GT_ENVELOPE
    c->time_constant_ref_s = plant_interp(at, &m->real[VR_COL_TIME_CONSTANT_REF_S]);
    c->point_valid = 0;
#endif
}

#if GT_ENVELOPE
/* An envelope ARX's input (the gate law's steady level) and its pole and b at the input
 * deviation u and the cached discharge: a1 scaled by the pool's time constant there, the b
 * rescaled to unit gain (an envelope ARX has one a). */
static void steady_point(const ModelData *m, double u_mm, double *level_mm, double *a1,
                         double b_now[GT_NB])
{
    const DynamicsCache *c = &m->cache.dyn;
    double tau_s;
    kernel_envelope_point(KERNEL(m), u_mm + m->real[VR_OPENING_REF_MM], m->cache.flow_m3h,
                          level_mm, &tau_s);
    gt_arx_envelope_coefficients(c->a, c->b, a1, b_now, GT_NB, c->time_constant_ref_s, tau_s);
}

/* One sample of the envelope ARX at the input deviation u; the steady point from the cache
 * when it holds for u (the steady solve only when the input, the discharge or a parameter
 * changed). */
static double envelope_sample(ModelData *m, double u_mm)
{
    DynamicsCache *c = &m->cache.dyn;
    if (!c->point_valid || !plant_same_bits(c->point_u_mm, u_mm)) {
        steady_point(m, u_mm, &c->point_level_mm, &c->point_a1, c->point_b);
        c->point_u_mm = u_mm;
        c->point_valid = 1;
    }
    return sample_step(&m->dyn, &c->point_a1, c->point_b, c->point_level_mm);
}
#endif

/* The input blocks are sampled at the start of every ARX sample (see effects.h). */
void dynamics_step(ModelData *m, double step_s, double command_mm)
{
    PlantMessage unused;
    const double n = samples_in_step(m, step_s, &unused);
    const double ts = m->real[VR_SAMPLE_PERIOD_S];
    const DynamicsCache *c = &m->cache.dyn; /* derived for this step's discharge (plant.c) */
    double sample;
    double duration = GT_HAS_RATE_LIMIT ? 0.0 : ts;
    for (sample = 0.0; sample < n; sample += 1.0) {
        double x_new;
        effects_actuate(m, &m->fx, command_mm, duration);
        m->fx.held_gate_mm = m->fx.gate_mm;
#if GT_ENVELOPE
        x_new = envelope_sample(m, effects_input(m, m->fx.gate_mm));
#else
        x_new = sample_step(&m->dyn, c->a, c->b, effects_input(m, m->fx.gate_mm));
#endif
        effects_lag_sample(m, c->level_ref_mm + x_new, ts);
        effects_seiche_piece(m, ts, m->fx.gate_mm);
        duration = ts;
    }
    if (GT_HAS_RATE_LIMIT) {
        effects_actuate(m, &m->fx, command_mm, ts);
    }
}

/* A restored state: every value finite. */
PlantStatus dynamics_check_state(const ModelData *m, PlantMessage *msg)
{
    const DynamicsState *d = &m->dyn;
    int i, finite = isfinite(d->x);
    for (i = 0; i < GT_NA; i++) {
        finite = finite && isfinite(d->x_hist[i]);
    }
    for (i = 0; i < GT_ARX_U_LAGS; i++) {
        finite = finite && isfinite(d->u_hist[i]);
    }
    if (!finite) {
        plant_message(msg, "ARX state (x or its input and output lags) is not finite");
        return PLANT_ERROR;
    }
    return PLANT_OK;
}

/* A restored cache: the coefficients and level_ref those of its discharge; an envelope ARX's
 * input and coefficients those of its input. */
PlantStatus dynamics_check_cache(const ModelData *m, PlantMessage *msg)
{
    const DynamicsCache *c = &m->cache.dyn;
    DynamicsCache fresh;
    int i, same;
    dynamics_derive(m, m->cache.flow_m3h, &m->cache.at, &fresh);
    same = plant_same_bits(c->level_ref_mm, fresh.level_ref_mm);
    for (i = 0; i < GT_NA; i++) {
        same = same && plant_same_bits(c->a[i], fresh.a[i]);
    }
    for (i = 0; i < GT_NB; i++) {
        same = same && plant_same_bits(c->b[i], fresh.b[i]);
    }
#if GT_ENVELOPE
    same = same && plant_same_bits(c->time_constant_ref_s, fresh.time_constant_ref_s);
#endif
    if (!same) {
        plant_message(msg, "state's cached ARX coefficients are not those of its discharge "
                           "%.17g m3/h",
                      m->cache.flow_m3h);
        return PLANT_ERROR;
    }
#if GT_ENVELOPE
    if (plant_check_flag(c->point_valid, "cached steady-point", msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    if (c->point_valid) {
        steady_point(m, c->point_u_mm, &fresh.point_level_mm, &fresh.point_a1, fresh.point_b);
        same = isfinite(c->point_u_mm) &&
               plant_same_bits(c->point_level_mm, fresh.point_level_mm) &&
               plant_same_bits(c->point_a1, fresh.point_a1);
        for (i = 0; i < GT_NB; i++) {
            same = same && plant_same_bits(c->point_b[i], fresh.point_b[i]);
        }
        if (!same) {
            plant_message(msg, "state's cached steady point (%.17g mm, a1 %.17g) is not the one "
                               "at its input %.17g mm",
                          c->point_level_mm, c->point_a1, c->point_u_mm);
            return PLANT_ERROR;
        }
    }
#endif
    return PLANT_OK;
}
