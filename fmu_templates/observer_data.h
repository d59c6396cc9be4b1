/* ModelData of the observer FMU (the component of component.h): every Real variable, the
 * observer's estimate and the generated code's work arrays. Fixed size and pointer-free
 * (copied and serialised as bytes by the FMU-state functions); the sizes come from the
 * generated model_config.h.
 */
#ifndef GATETWIN_OBSERVER_DATA_H
#define GATETWIN_OBSERVER_DATA_H

#include "model_config.h"
#include "observer_generated.h" /* casadi_int, casadi_real and the generated functions */

typedef struct {
    double time_s;          /* time of the state, s */
    double real[GT_N_REAL]; /* every Real variable, indexed by value reference */
    int initialized;        /* plant_initialize succeeded */
    int parameters_changed; /* parameters were set since they were last checked */
    /* the observer: state, input disturbance (mm of opening), prior covariance of [z, d] */
    double z[GT_GEN_NZ];
    double d;
    double p[GT_GEN_NP];
    double flow_model_m3h; /* discharge of the observer's model (the last prediction's) */
    double monitor[GT_OBS_N_MONITOR]; /* anomaly rules' state (gatetwin.mpc.online.MONITOR) */
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
