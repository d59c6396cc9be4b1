/* Scheduled FOPDT dynamics: T dx/dt = K u(t - L) - x, exact for piecewise-constant input.
 *
 * The dead time is served from a history of input change points; mirrors
 * PlantSimulator._fopdt_step / _prune_history / _last_arrived_index in
 * gatetwin/plant/simulate.py operation by operation.
 */
#include <math.h>

#include "plant.h"

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
    return PLANT_OK;
}

PlantStatus dynamics_equilibrium(const ModelData *m, double u_mm, const KnotPosition *at,
                                 double *x0_mm, PlantMessage *msg)
{
    (void)msg;
    *x0_mm = plant_interp(at, GAIN(m)) * u_mm;
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
    d->max_dead_time_s = DEAD_TIME(m)[0];
    for (k = 1; k < GT_N_KNOTS; k++) {
        if (DEAD_TIME(m)[k] > d->max_dead_time_s) {
            d->max_dead_time_s = DEAD_TIME(m)[k];
        }
    }
}

PlantStatus dynamics_check_step(const ModelData *m, double step_s, double u_mm,
                                PlantMessage *msg)
{
    const DynamicsState *d = &m->dyn;
    (void)step_s;
    if (u_mm != d->change_u[slot(d, d->count - 1)] && d->count >= GT_HISTORY_CAPACITY) {
        plant_message(msg, "input changes faster than the dead-time history can hold "
                           "(%d change points within the longest dead time)",
                      GT_HISTORY_CAPACITY);
        return PLANT_ERROR;
    }
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

void dynamics_step(ModelData *m, double step_s, double u_mm, const KnotPosition *at)
{
    DynamicsState *d = &m->dyn;
    const double k = plant_interp(at, GAIN(m));
    const double tau = plant_interp(at, TIME_CONSTANT(m));
    const double delay = plant_interp(at, DEAD_TIME(m));
    const double t0 = m->time_s;
    const double t1 = t0 + step_s;
    double t = t0;
    if (u_mm != d->change_u[slot(d, d->count - 1)]) {
        d->change_t[slot(d, d->count)] = t0;
        d->change_u[slot(d, d->count)] = u_mm;
        d->count++;
    }
    while (t < t1) {
        const int j = last_arrived(d, delay, t);
        double t_next = t1;
        double target;
        if (j + 1 < d->count) {
            const double arrival = d->change_t[slot(d, j + 1)] + delay;
            if (arrival < t_next) {
                t_next = arrival;
            }
        }
        target = k * d->change_u[slot(d, j)];
        d->x = target + (d->x - target) * exp(-(t_next - t) / tau);
        t = t_next;
    }
    prune(d, t1);
}
