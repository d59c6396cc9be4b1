/* What the two observer components share; see observer_support.h. */
#include <math.h>
#include <string.h>

#include "observer_support.h"

long gt_whole_samples(double span_s)
{
    const double n = floor(span_s / GT_GEN_SAMPLE_PERIOD_S + 0.5);
    if (!(n >= 0.0 && n <= 1e9) ||
        !(fabs(n * GT_GEN_SAMPLE_PERIOD_S - span_s) <=
          GT_COMMUNICATION_POINT_RTOL * fmax(span_s, GT_GEN_SAMPLE_PERIOD_S))) {
        return -1;
    }
    return (long)n;
}

PlantStatus gt_check_monitor_parameters(const ModelData *m, PlantMessage *msg)
{
    const double horizon = m->real[VR_HORIZON_S], band = m->real[VR_ANOMALY_BAND_SIGMA];
    const double run = m->real[VR_ANOMALY_RUN_SAMPLES];
    const double slack = m->real[VR_ANOMALY_CUSUM_SLACK_SIGMA];
    const double threshold = m->real[VR_ANOMALY_CUSUM_THRESHOLD];
    if (!(horizon >= 0.0 && horizon <= GT_OBS_MAX_HORIZON_S) || gt_whole_samples(horizon) < 0) {
        plant_message(msg, "horizon_s = %.17g must be a whole multiple of the sample period "
                           "%g s in [0, %g] s", horizon, GT_GEN_SAMPLE_PERIOD_S,
                      GT_OBS_MAX_HORIZON_S);
        return PLANT_ERROR;
    }
    if (!(band > 0.0)) {
        plant_message(msg, "anomaly_band_sigma = %.17g must be > 0", band);
        return PLANT_ERROR;
    }
    if (!(run >= 1.0 && run <= 1e6 && run == floor(run))) {
        plant_message(msg, "anomaly_run_samples = %.17g must be a whole number in [1, 1e6]", run);
        return PLANT_ERROR;
    }
    if (!(slack >= 0.0) || !(threshold > 0.0)) {
        plant_message(msg, "anomaly_cusum_slack_sigma = %.17g must be >= 0 and "
                           "anomaly_cusum_threshold = %.17g > 0", slack, threshold);
        return PLANT_ERROR;
    }
#if GT_DRIFT_N_REFS > 0
    if (!(m->real[VR_GAUGE_DRIFT_THRESHOLD_MM_PER_S] > 0.0 &&
          m->real[VR_GAUGE_DRIFT_THRESHOLD_MM_PER_S] <= 1e6)) {
        plant_message(msg, "gauge_drift_threshold_mm_per_s = %.17g must be in (0, 1e6]",
                      m->real[VR_GAUGE_DRIFT_THRESHOLD_MM_PER_S]);
        return PLANT_ERROR;
    }
#endif
    return PLANT_OK;
}

PlantStatus gt_check_observer_inputs(const ModelData *m, PlantMessage *msg)
{
    if (!isfinite(m->real[VR_LEVEL]) || !isfinite(m->real[VR_OPENING_MM])) {
        plant_message(msg, "%s = %.17g and opening_mm = %.17g must be finite",
                      plant_variables[VR_LEVEL].name, m->real[VR_LEVEL], m->real[VR_OPENING_MM]);
        return PLANT_ERROR;
    }
#if GT_DRIFT_N_REFS > 0
    {
        static const int ref_vr[GT_DRIFT_N_REFS] = GT_DRIFT_REF_VRS;
        int i;
        for (i = 0; i < GT_DRIFT_N_REFS; i++) {
            if (!isfinite(m->real[ref_vr[i]])) {
                plant_message(msg, "%s = %.17g must be finite", plant_variables[ref_vr[i]].name,
                              m->real[ref_vr[i]]);
                return PLANT_ERROR;
            }
        }
    }
#endif
    return gt_check_flow(m->real[VR_FLOW_M3H], msg);
}

PlantStatus gt_observer_samples(const ModelData *m, double step_s, long *n, PlantMessage *msg)
{
    *n = step_s > 0.0 ? gt_whole_samples(step_s) : -1;
    if (*n < 1) {
        plant_message(msg, "communication step %.17g s must be a whole multiple of the "
                           "observer's sample period %.17g s", step_s, GT_GEN_SAMPLE_PERIOD_S);
        return PLANT_ERROR;
    }
    if (*n > GT_OBS_MAX_SAMPLES_PER_STEP) {
        plant_message(msg, "communication step %.17g s spans %ld samples; at most %d per step",
                      step_s, *n, GT_OBS_MAX_SAMPLES_PER_STEP);
        return PLANT_ERROR;
    }
    if (!(fabs(m->time_s + step_s) <= GT_MAX_TIME_S)) {
        plant_message(msg, "communication step to t = %.17g s passes the time limit %g s",
                      m->time_s + step_s, GT_MAX_TIME_S);
        return PLANT_ERROR;
    }
    return gt_check_observer_inputs(m, msg);
}

#if GT_DRIFT_N_REFS > 0
/* The gauge-drift rule after the observer's sample of the level y (generated from
 * gatetwin.mpc.gauge_drift.drift_sample and with_drift_rule): the window moves on, the slope
 * and flag are new, and anomaly_kind and anomaly become 4 and 1 where the rule alone holds. */
static void drift_sample(ModelData *m, double y)
{
    static const int ref_vr[GT_DRIFT_N_REFS] = GT_DRIFT_REF_VRS;
    static const int rule_vr[GT_DRIFT_N_RULE] = GT_DRIFT_RULE_VRS;
    double others[GT_DRIFT_N_REFS], window[GT_DRIFT_WINDOW], count, rule[GT_DRIFT_N_RULE];
    int i;
    for (i = 0; i < GT_DRIFT_N_REFS; i++) {
        others[i] = m->real[ref_vr[i]];
    }
    {
        const double *in[6] = {m->drift_window, &m->drift_count, &y, others,
                               &m->real[VR_GAUGE_DRIFT_THRESHOLD_MM_PER_S],
                               &m->real[VR_ANOMALY_KIND]};
        double *out[3] = {window, &count, rule};
        gt_call(m, GT_DRIFT_FUNCTION, in, 6, out, 3);
    }
    memcpy(m->drift_window, window, sizeof window);
    m->drift_count = count;
    for (i = 0; i < GT_DRIFT_N_RULE; i++) {
        m->real[rule_vr[i]] = rule[i];
    }
}
#endif

PlantStatus gt_check_drift_state(const ModelData *m, PlantMessage *msg)
{
#if GT_DRIFT_N_REFS > 0
    const double count = m->drift_count;
    if (!gt_all_finite(m->drift_window, GT_DRIFT_WINDOW) ||
        !(count >= 0.0 && count <= GT_DRIFT_WINDOW && count == floor(count))) {
        plant_message(msg, "state of the gauge-drift rule is not finite or its count is not a "
                           "whole number in [0, %d]", GT_DRIFT_WINDOW);
        return PLANT_ERROR;
    }
#else
    (void)m;
    (void)msg;
#endif
    return PLANT_OK;
}

PlantStatus gt_observer_do_step(ModelData *m, double step_s, ObserverSample sample,
                                PlantMessage *msg)
{
    long n, k;
    if (gt_observer_samples(m, step_s, &n, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    for (k = 0; k < n; k++) {
        sample(m, m->real[VR_LEVEL], m->real[VR_OPENING_MM], m->real[VR_FLOW_M3H]);
#if GT_DRIFT_N_REFS > 0
        drift_sample(m, m->real[VR_LEVEL]);
#endif
    }
    m->time_s += step_s;
    if (gt_finite_estimate(m, "after the step", "observer", msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    return gt_finite_outputs(m, "observer", msg);
}

void gt_observer_start_outputs(ModelData *m, double level_mm)
{
    static const int estimate_vr[GT_OBS_N_ESTIMATE] = GT_OBS_ESTIMATE_VRS;
    int i;
    for (i = 0; i < GT_OBS_N_ESTIMATE; i++) {
        m->real[estimate_vr[i]] = 0.0;
    }
    m->real[VR_FILTERED_LEVEL_MM] = level_mm;
    m->real[VR_DISTURBANCE_MM] = m->d;
    m->real[VR_INNOVATION_SCALE] = 1.0;
#if GT_DRIFT_N_REFS > 0
    memset(m->drift_window, 0, sizeof m->drift_window);
    m->drift_count = 0.0;
    m->real[VR_GAUGE_SLOPE_MM_PER_S] = 0.0;
    m->real[VR_GAUGE_DRIFT] = 0.0;
#endif
}

PlantStatus plant_output(const ModelData *m, unsigned vr, double *value, PlantMessage *msg)
{
    if (plant_variables[vr].kind != GT_KIND_OUTPUT) {
        plant_message(msg, "%s is not an output", plant_variables[vr].name);
        return PLANT_ERROR;
    }
    *value = m->real[vr];
    return PLANT_OK;
}
