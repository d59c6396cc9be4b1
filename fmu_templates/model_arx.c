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
    return PLANT_OK;
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

/* The input blocks are sampled at the start of every ARX sample (see effects.h). */
void dynamics_step(ModelData *m, double step_s, double command_mm, const KnotPosition *at)
{
    PlantMessage unused;
    const double n = samples_in_step(m, step_s, &unused);
    const double ts = m->real[VR_SAMPLE_PERIOD_S];
    const double level_ref = plant_interp(at, &m->real[VR_COL_LEVEL_REF_MM]);
    double a[GT_NA], b[GT_NB];
    double sample;
    double duration = GT_HAS_RATE_LIMIT ? 0.0 : ts;
    coefficients(m, at, a, b);
    for (sample = 0.0; sample < n; sample += 1.0) {
        double x_new;
        effects_actuate(m, &m->fx, command_mm, duration);
        m->fx.held_gate_mm = m->fx.gate_mm;
#if GT_ENVELOPE
        {
            const double tau_ref = plant_interp(at, &m->real[VR_COL_TIME_CONSTANT_REF_S]);
            double level_mm, tau_s, a_now[GT_NA], b_now[GT_NB];
            kernel_envelope_point(KERNEL(m),
                                  effects_input(m, m->fx.gate_mm) + m->real[VR_OPENING_REF_MM],
                                  m->real[VR_FLOW_M3H], &level_mm, &tau_s);
            gt_arx_envelope_coefficients(a, b, a_now, b_now, GT_NB, tau_ref, tau_s);
            x_new = sample_step(&m->dyn, a_now, b_now, level_mm);
        }
#else
        x_new = sample_step(&m->dyn, a, b, effects_input(m, m->fx.gate_mm));
#endif
        effects_lag_sample(m, level_ref + x_new, ts);
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
