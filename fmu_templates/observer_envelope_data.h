/* ModelData of the envelope observer FMU (the component of component.h): every Real variable,
 * the two filters' estimates (the monitoring one and the slow rule's), the tangent model of the
 * last prediction and the generated code's work arrays. Fixed size and pointer-free (copied and
 * serialised as bytes by the FMU-state functions); the sizes come from the generated
 * model_config.h.
 */
#ifndef GATETWIN_OBSERVER_ENVELOPE_DATA_H
#define GATETWIN_OBSERVER_ENVELOPE_DATA_H

#include "model_config.h"
#include "observer_envelope_generated.h" /* casadi_int, casadi_real, the generated functions */

typedef struct {
    double time_s;          /* time of the state, s */
    double real[GT_N_REAL]; /* every Real variable, indexed by value reference */
    int initialized;        /* plant_initialize succeeded */
    int parameters_changed; /* parameters were set since they were last checked */
    /* the monitoring filter: state, input disturbance (mm of opening), prior covariance */
    double z[GT_GEN_NZ];
    double d;
    double p[GT_GEN_NP];
    double monitor[GT_OBS_N_MONITOR]; /* its anomaly rules' state (gatetwin.mpc.online.MONITOR) */
    /* the slow rule's filter, the same */
    double slow_z[GT_GEN_NZ];
    double slow_d;
    double slow_p[GT_GEN_NP];
    double slow_monitor[GT_OBS_N_MONITOR];
    /* the last prediction's tangent: its steady points, discharge (m3/h) and opening (mm) */
    double x_model[GT_ENV_N_X];
    double flow_model_m3h;
    double opening_model_mm;
#if GT_DRIFT_N_REFS > 0
    /* the gauge-drift rule: the last differences to the reference gauges' mean, oldest first,
     * and the samples seen (at most the window) */
    double drift_window[GT_DRIFT_WINDOW];
    double drift_count;
#endif
    /* scratch of one call: the generated code's work arrays */
    casadi_int iw[GT_GEN_SZ_IW];
    casadi_real w[GT_GEN_SZ_W];
} ModelData;

#endif
