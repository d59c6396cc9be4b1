/* What the two observer components share (observer.c, the schedule's; observer_envelope.c,
 * the envelope's): sample counts, the checks of the horizon and the anomaly rules' limits, of
 * the measured inputs and of a communication step, and the outputs' getter.
 *
 * Compiled with the component's own model_config.h (its ModelData, VR_* and GT_GEN_* /
 * GT_OBS_* / GT_DRIFT_* macros): both components name their parameters and inputs alike.
 * With reference gauges (GT_DRIFT_N_REFS > 0) each sample ends with the gauge-drift rule
 * (gatetwin.mpc.gauge_drift, generated as GT_DRIFT_FUNCTION): the slope of the observed
 * level's difference to the reference gauges' mean over the last GT_DRIFT_WINDOW samples,
 * its flag, and anomaly_kind 4 where the rule alone holds.
 */
#ifndef GATETWIN_OBSERVER_SUPPORT_H
#define GATETWIN_OBSERVER_SUPPORT_H

#include "generated_support.h"

/* A whole number of sample periods in `span_s`, or -1 when it is not one. */
long gt_whole_samples(double span_s);
/* horizon_s a whole number of samples within its limit; the anomaly rules' band, run length,
 * CUSUM slack and threshold in their ranges. */
PlantStatus gt_check_monitor_parameters(const ModelData *m, PlantMessage *msg);
/* The measured level and opening finite, the discharge within the meter's range. */
PlantStatus gt_check_observer_inputs(const ModelData *m, PlantMessage *msg);
/* The samples a communication step of step_s spans (*n), after checking the step (a whole
 * number of samples, at most GT_OBS_MAX_SAMPLES_PER_STEP, within the time limit) and the
 * inputs it holds. */
PlantStatus gt_observer_samples(const ModelData *m, double step_s, long *n, PlantMessage *msg);
/* One observer sample: the component's own, on the measured level y, opening e, discharge q. */
typedef void (*ObserverSample)(ModelData *m, double y, double e, double q);
/* A communication step: its samples (gt_observer_samples), each by `sample` on the held
 * inputs, then the estimate and the outputs checked finite. */
PlantStatus gt_observer_do_step(ModelData *m, double step_s, ObserverSample sample,
                                PlantMessage *msg);
/* The outputs at the start, before any sample: every estimate 0 but the filtered level (the
 * measured one), the disturbance (the start's) and the innovation scale (1); the gauge-drift
 * rule's window empty. */
void gt_observer_start_outputs(ModelData *m, double level_mm);
/* A restored state's gauge-drift window finite and its count a whole number within the
 * window (always PLANT_OK without reference gauges). */
PlantStatus gt_check_drift_state(const ModelData *m, PlantMessage *msg);

#endif
