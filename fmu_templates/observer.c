/* The online observer behind component.h: gatetwin.mpc.online.OnlineObserver (the MPC's
 * disturbance observer on the schedule's FOPDT, re-rendered at the measured discharge) as one
 * FMU component, beside the gate: it takes the measured level, opening and discharge.
 *
 * This file only orders calls: every number is computed by the functions casadi generated from
 * the observer's Python code (observer_generated.c, gatetwin.mpc.observer_codegen): start,
 * riccati, correct, advance, level, predict. Per sample, as OnlineObserver.step: correct with
 * the measured level (model of the last prediction; the innovation, its normalised value,
 * the anomaly rules' outputs and their next state come with it), forecast horizon_s ahead
 * with the inputs held (advance, that many samples, then level), predict with the opening
 * over the next sample.
 *
 * Timing: doStep(t, h) takes the inputs at t as the measurements of the sample at t; after it
 * the outputs are the estimate at t and the forecast from t. h must be a whole number of
 * sample periods; each sample of the step takes the same (held) inputs.
 */
#include <math.h>
#include <string.h>

#include "observer_support.h"

/* --- parameters ------------------------------------------------------------------------------ */

static PlantStatus check_parameters(const ModelData *m, PlantMessage *msg)
{
    if (plant_check_parameter_values(m->real, msg) != PLANT_OK ||
        gt_check_schedule(m, "observer", msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    return gt_check_monitor_parameters(m, msg);
}

/* --- the steps of one sample --------------------------------------------------------------- */

/* The level horizon_s ahead of state z at discharge q, opening e and disturbance d held. */
static double forecast(ModelData *m, double q, const double *z, double d, double e)
{
    const long n = gt_whole_samples(m->real[VR_HORIZON_S]);
    double a[GT_GEN_NZ], b[GT_GEN_NZ], level;
    long k;
    memcpy(a, z, sizeof a);
    for (k = 0; k < n; k++) {
        const double *in[5] = {gt_theta(m), &q, a, &d, &e};
        double *out[1] = {b};
        gt_call(m, gt_obs_advance, in, 5, out, 1);
        memcpy(a, b, sizeof a);
    }
    {
        const double *in[3] = {gt_theta(m), &q, a};
        double *out[1] = {&level};
        gt_call(m, gt_obs_level, in, 3, out, 1);
    }
    return level;
}

/* One sample: correct with the level y, forecast, predict with opening e at discharge q. */
static void sample(ModelData *m, double y, double e, double q)
{
    static const int estimate_vr[GT_OBS_N_ESTIMATE] = GT_OBS_ESTIMATE_VRS;
    static const int limit_vr[GT_OBS_N_LIMITS] = GT_OBS_LIMIT_VRS;
    double z[GT_GEN_NZ], d, p[GT_GEN_NP], est[GT_OBS_N_ESTIMATE], limits[GT_OBS_N_LIMITS];
    double monitor[GT_OBS_N_MONITOR];
    int i;
    for (i = 0; i < GT_OBS_N_LIMITS; i++) {
        limits[i] = m->real[limit_vr[i]];
    }
    {
        const double *in[8] = {gt_theta(m), &m->flow_model_m3h, m->z, &m->d, m->p, &y,
                               m->monitor, limits};
        double *out[5] = {z, &d, p, est, monitor};
        gt_call(m, gt_obs_correct, in, 8, out, 5);
    }
    for (i = 0; i < GT_OBS_N_ESTIMATE; i++) {
        m->real[estimate_vr[i]] = est[i];
    }
    memcpy(m->monitor, monitor, sizeof monitor);
    m->real[VR_PREDICTED_LEVEL_MM] = forecast(m, q, z, d, e);
    {
        const double *in[7] = {gt_theta(m), &m->flow_model_m3h, &q, z, &d, p, &e};
        double *out[3] = {m->z, &m->d, m->p};
        gt_call(m, gt_obs_predict, in, 7, out, 3);
    }
    m->flow_model_m3h = q;
}

/* --- the glue's entry points ----------------------------------------------------------------- */

void plant_set_defaults(ModelData *m)
{
    component_set_defaults(m);
    m->real[VR_FILTERED_LEVEL_MM] = m->real[VR_LEVEL];
    m->real[VR_PREDICTED_LEVEL_MM] = m->real[VR_LEVEL];
}

/* At rest at the opening, level and discharge measured now, as OnlineObserver.reset. */
PlantStatus plant_initialize(ModelData *m, PlantMessage *msg)
{
    double q = m->real[VR_FLOW_M3H], y = m->real[VR_LEVEL], e = m->real[VR_OPENING_MM];
    double level;
    if (check_parameters(m, msg) != PLANT_OK || gt_check_observer_inputs(m, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    m->parameters_changed = 0;
    {
        const double *in[4] = {gt_theta(m), &q, &e, &y};
        double *out[4] = {m->z, &m->d, &level, m->monitor};
        gt_call(m, gt_obs_start, in, 4, out, 4);
    }
    if (gt_steady_covariance(m, gt_obs_riccati, q, msg) != PLANT_OK ||
        gt_finite_estimate(m, "at the start", "observer", msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    m->flow_model_m3h = q;
    gt_observer_start_outputs(m, level);
    m->real[VR_PREDICTED_LEVEL_MM] = forecast(m, q, m->z, m->d, e);
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
        const double scalars[2] = {m->d, m->flow_model_m3h};
        const double run = m->monitor[0];
        if (!gt_all_finite(scalars, 2) || !gt_all_finite(m->z, GT_GEN_NZ) ||
            !gt_all_finite(m->p, GT_GEN_NP) || !gt_all_finite(m->monitor, GT_OBS_N_MONITOR) ||
            !(run >= 0.0 && run == floor(run))) {
            plant_message(msg, "state of the observer is not finite or its run is not a count");
            return PLANT_ERROR;
        }
    }
    if (gt_check_drift_state(m, msg) != PLANT_OK ||
        (!m->parameters_changed && check_parameters(m, msg) != PLANT_OK)) {
        return PLANT_ERROR;
    }
    return PLANT_OK;
}
