/* What the components whose arithmetic casadi generated share (controller_mpc.c, observer.c):
 * the call of a generated function on ModelData's work arrays, vector checks, the checks of the
 * schedule and the discharge, and the observer's steady covariance as a fixed point.
 *
 * Compiled with the component's own model_config.h: its ModelData (component.h) holds `real`,
 * the observer's `z`, `d` and `p`, and the generated code's work arrays `iw` and `w` (its
 * header includes the generated header, which brings casadi_int and casadi_real). Sizes and
 * limits are model_config.h's GT_GEN_* macros. The schedule's helpers exist where
 * model_config.h names a schedule (VR_THETA); the envelope observer has none.
 */
#ifndef GATETWIN_GENERATED_SUPPORT_H
#define GATETWIN_GENERATED_SUPPORT_H

#include "component.h"

/* The signature of every casadi-generated function. */
typedef int (*GeneratedFunction)(const casadi_real **arg, casadi_real **res, casadi_int *iw,
                                 casadi_real *w, int mem);

/* One call of generated function f on ModelData's work arrays; returns its flag (0: ok). */
int gt_call(ModelData *m, GeneratedFunction f, const double *const *in, int n_in,
            double *const *out, int n_out);
#ifdef VR_THETA
/* The schedule and opening_ref_mm as the generated functions take them. */
const double *gt_theta(const ModelData *m);
#endif
int gt_all_finite(const double *v, int n);
double gt_max_abs(const double *v, int n);
#ifdef VR_THETA
/* Knots increasing, time constants > 0, dead times within the register `what` (the
 * controller, the observer) was generated with. */
PlantStatus gt_check_schedule(const ModelData *m, const char *what, PlantMessage *msg);
#endif
PlantStatus gt_check_flow(double flow_m3h, PlantMessage *msg);
/* p: the steady prior covariance, the fixed point of `riccati` (one correct-and-predict of
 * the covariance; its inputs are the n_in of `in`, then the covariance) from zero; q, the
 * discharge, names the point in the message. */
PlantStatus gt_covariance_fixed_point(ModelData *m, GeneratedFunction riccati,
                                      const double *const *in, int n_in, double *p, double q,
                                      PlantMessage *msg);
#ifdef VR_THETA
/* m->p: the steady prior covariance at discharge q of `riccati(theta, q, P)`. */
PlantStatus gt_steady_covariance(ModelData *m, GeneratedFunction riccati, double q,
                                 PlantMessage *msg);
#endif
/* The observer's estimate (z, d, p) finite; `when` and `what` name the moment and the
 * component in the message. */
PlantStatus gt_finite_estimate(const ModelData *m, const char *when, const char *what,
                               PlantMessage *msg);
/* What a restored state must hold first: each of `flags` 0 or 1, `initialized` as its mode
 * needs, time and every variable finite. */
PlantStatus gt_check_state_head(const ModelData *m, const int *flags, int n_flags,
                                int initialized, PlantMessage *msg);
/* Every output finite after a step. */
PlantStatus gt_finite_outputs(const ModelData *m, const char *what, PlantMessage *msg);

#endif
