/* The envelope observer behind component.h: gatetwin.mpc.online.OnlineObserver with
 * linearisation "envelope" (the plant's gate law re-linearised at every sample around the
 * measured discharge and opening, and the slow rule's second filter) as one FMU component.
 *
 * This file only orders calls. The steady points of the tangent come from the plant kernel's
 * C (physical_kernel.c, generated from gatetwin.plant.physical_kernel; kernel_point.c runs its
 * steady-depth solve), at the openings the generated `openings` asks for; every other number is
 * computed by the functions casadi generated from the observer's Python code
 * (observer_envelope_generated.c, gatetwin.mpc.observer_codegen.build_envelope_functions).
 * Per sample, as OnlineObserver.step: the tangent at the inputs now; correct with the measured
 * level (model of the last prediction) and apply the rules; the slow filter's sample and the
 * slow rule; rescale the disturbance to the new gain and predict; forecast horizon_s ahead.
 *
 * Timing: as observer.c (doStep(t, h) takes the inputs at t as the sample at t; h a whole
 * number of sample periods, each taking the same held inputs).
 */
#include <math.h>
#include <string.h>

#include "observer_support.h"
#include "kernel_point.h"

static const double kernel_p[] = GT_ENV_KERNEL_P;

/* --- parameters and inputs ------------------------------------------------------------------ */

static PlantStatus check_parameters(const ModelData *m, PlantMessage *msg)
{
    if (plant_check_parameter_values(m->real, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    return gt_check_monitor_parameters(m, msg);
}

/* --- the steps of one sample --------------------------------------------------------------- */

/* x: the steady points of the tangent at discharge q and opening e, each at the opening the
 * generated `openings` gives, by the kernel's C. */
static void tangent(ModelData *m, double q, double e, double *x)
{
    double openings[GT_ENV_N_POINTS];
    int i;
    {
        const double *in[1] = {&e};
        double *out[1] = {openings};
        gt_call(m, gt_env_openings, in, 1, out, 1);
    }
    for (i = 0; i < GT_ENV_N_POINTS; i++) {
        kernel_envelope_point(kernel_p, openings[i], q, &x[2 * i], &x[2 * i + 1]);
    }
}

/* The level horizon_s ahead of state z on the tangent (x, q, e), with e and d held. */
static double forecast(ModelData *m, const double *x, double q, double e, const double *z,
                       double d)
{
    const long n = gt_whole_samples(m->real[VR_HORIZON_S]);
    double a[GT_GEN_NZ], b[GT_GEN_NZ], level;
    long k;
    memcpy(a, z, sizeof a);
    for (k = 0; k < n; k++) {
        const double *in[5] = {x, &q, &e, a, &d};
        double *out[1] = {b};
        gt_call(m, gt_env_advance, in, 5, out, 1);
        memcpy(a, b, sizeof a);
    }
    {
        const double *in[4] = {x, &q, &e, a};
        double *out[1] = {&level};
        gt_call(m, gt_env_level, in, 4, out, 1);
    }
    return level;
}

/* The slow filter's sample and the slow rule on the monitoring filter's `kind`. */
static void slow_sample(ModelData *m, const double *x, double q, double e, double y, double kind)
{
    static const int rule_vr[GT_ENV_N_RULE] = GT_ENV_RULE_VRS;
    double z[GT_GEN_NZ], d, p[GT_GEN_NP], monitor[GT_OBS_N_MONITOR], rule[GT_ENV_N_RULE];
    int i;
    {
        const double *in[12] = {m->x_model, &m->flow_model_m3h, &m->opening_model_mm, x, &q, &e,
                                m->slow_z, &m->slow_d, m->slow_p, &y, m->slow_monitor, &kind};
        double *out[5] = {z, &d, p, monitor, rule};
        gt_call(m, gt_env_slow, in, 12, out, 5);
    }
    memcpy(m->slow_z, z, sizeof z);
    m->slow_d = d;
    memcpy(m->slow_p, p, sizeof p);
    memcpy(m->slow_monitor, monitor, sizeof monitor);
    for (i = 0; i < GT_ENV_N_RULE; i++) {
        m->real[rule_vr[i]] = rule[i];
    }
}

/* One sample: the level y measured now, opening e and discharge q held over the next. */
static void sample(ModelData *m, double y, double e, double q)
{
    static const int estimate_vr[GT_OBS_N_ESTIMATE] = GT_OBS_ESTIMATE_VRS;
    static const int limit_vr[GT_OBS_N_LIMITS] = GT_OBS_LIMIT_VRS;
    double x[GT_ENV_N_X], z[GT_GEN_NZ], d, p[GT_GEN_NP], est[GT_OBS_N_ESTIMATE];
    double limits[GT_OBS_N_LIMITS], monitor[GT_OBS_N_MONITOR], d_now;
    int i;
    tangent(m, q, e, x);
    for (i = 0; i < GT_OBS_N_LIMITS; i++) {
        limits[i] = m->real[limit_vr[i]];
    }
    {
        const double *in[9] = {m->x_model, &m->flow_model_m3h, &m->opening_model_mm, m->z, &m->d,
                               m->p, &y, m->monitor, limits};
        double *out[5] = {z, &d, p, est, monitor};
        gt_call(m, gt_env_correct, in, 9, out, 5);
    }
    for (i = 0; i < GT_OBS_N_ESTIMATE; i++) {
        m->real[estimate_vr[i]] = est[i];
    }
    memcpy(m->monitor, monitor, sizeof monitor);
    slow_sample(m, x, q, e, y, est[GT_ENV_KIND_INDEX]);
    {
        const double *in[9] = {m->x_model, &m->flow_model_m3h, &m->opening_model_mm, x, &q, &e,
                               z, &d, p};
        double *out[4] = {m->z, &m->d, m->p, &d_now};
        gt_call(m, gt_env_predict, in, 9, out, 4);
    }
    m->real[VR_DISTURBANCE_MM] = d_now;
    m->real[VR_PREDICTED_LEVEL_MM] = forecast(m, x, q, e, z, d_now);
    memcpy(m->x_model, x, sizeof x);
    m->flow_model_m3h = q;
    m->opening_model_mm = e;
}

/* --- the glue's entry points ----------------------------------------------------------------- */

void plant_set_defaults(ModelData *m)
{
    component_set_defaults(m);
    m->real[VR_FILTERED_LEVEL_MM] = m->real[VR_LEVEL];
    m->real[VR_PREDICTED_LEVEL_MM] = m->real[VR_LEVEL];
}

/* Both filters' steady prior covariances on the tangent (x, q, e). */
static PlantStatus start_covariances(ModelData *m, const double *x, double q, double e,
                                     PlantMessage *msg)
{
    const double *in[3] = {x, &q, &e};
    if (gt_covariance_fixed_point(m, gt_env_riccati, in, 3, m->p, q, msg) != PLANT_OK ||
        gt_covariance_fixed_point(m, gt_env_slow_riccati, in, 3, m->slow_p, q, msg) !=
            PLANT_OK) {
        return PLANT_ERROR;
    }
    if (!gt_all_finite(m->slow_p, GT_GEN_NP)) {
        plant_message(msg, "the slow filter's covariance is not finite at the start");
        return PLANT_ERROR;
    }
    return PLANT_OK;
}

/* At rest at the opening, level and discharge measured now, as OnlineObserver.reset. */
PlantStatus plant_initialize(ModelData *m, PlantMessage *msg)
{
    double q = m->real[VR_FLOW_M3H], y = m->real[VR_LEVEL], e = m->real[VR_OPENING_MM];
    double level, x[GT_ENV_N_X];
    if (check_parameters(m, msg) != PLANT_OK || gt_check_observer_inputs(m, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    m->parameters_changed = 0;
    tangent(m, q, e, x);
    {
        const double *in[4] = {x, &q, &e, &y};
        double *out[4] = {m->z, &m->d, &level, m->monitor};
        gt_call(m, gt_env_start, in, 4, out, 4);
    }
    if (start_covariances(m, x, q, e, msg) != PLANT_OK ||
        gt_finite_estimate(m, "at the start", "observer", msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    memcpy(m->slow_z, m->z, sizeof m->z);
    m->slow_d = m->d;
    memcpy(m->slow_monitor, m->monitor, sizeof m->monitor);
    memcpy(m->x_model, x, sizeof x);
    m->flow_model_m3h = q;
    m->opening_model_mm = e;
    gt_observer_start_outputs(m, level);
    m->real[VR_SLOW_CUSUM] = 0.0;
    m->real[VR_PREDICTED_LEVEL_MM] = forecast(m, x, q, e, m->z, m->d);
    m->initialized = 1;
    return PLANT_OK;
}

PlantStatus plant_do_step(ModelData *m, double step_s, PlantMessage *msg)
{
    return gt_observer_do_step(m, step_s, sample, msg);
}

/* --- restored states --------------------------------------------------------------------- */

PlantStatus plant_check_state(const ModelData *m, int initialized, PlantMessage *msg)
{
    const int flags[2] = {m->initialized, m->parameters_changed};
    if (gt_check_state_head(m, flags, 2, initialized, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    {
        const double scalars[4] = {m->d, m->slow_d, m->flow_model_m3h, m->opening_model_mm};
        const double runs[2] = {m->monitor[0], m->slow_monitor[0]};
        if (!gt_all_finite(scalars, 4) || !gt_all_finite(m->z, GT_GEN_NZ) ||
            !gt_all_finite(m->p, GT_GEN_NP) || !gt_all_finite(m->slow_z, GT_GEN_NZ) ||
            !gt_all_finite(m->slow_p, GT_GEN_NP) || !gt_all_finite(m->x_model, GT_ENV_N_X) ||
            !gt_all_finite(m->monitor, GT_OBS_N_MONITOR) ||
            !gt_all_finite(m->slow_monitor, GT_OBS_N_MONITOR) ||
            !(runs[0] >= 0.0 && runs[0] == floor(runs[0])) ||
            !(runs[1] >= 0.0 && runs[1] == floor(runs[1]))) {
            plant_message(msg, "state of the observer is not finite or a run is not a count");
            return PLANT_ERROR;
        }
    }
    if (gt_check_drift_state(m, msg) != PLANT_OK ||
        (!m->parameters_changed && check_parameters(m, msg) != PLANT_OK)) {
        return PLANT_ERROR;
    }
    return PLANT_OK;
}
