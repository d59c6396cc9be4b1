/* See generated_support.h. Nothing here computes a number of the model: that is the generated
 * code's; this file calls it and checks what goes in and comes out.
 */
#include <math.h>
#include <string.h>

#include "generated_support.h"

int gt_call(ModelData *m, GeneratedFunction f, const double *const *in, int n_in,
            double *const *out, int n_out)
{
    const casadi_real *arg[GT_GEN_SZ_ARG];
    casadi_real *res[GT_GEN_SZ_RES];
    int i;
    for (i = 0; i < GT_GEN_SZ_ARG; i++) {
        arg[i] = i < n_in ? in[i] : NULL;
    }
    for (i = 0; i < GT_GEN_SZ_RES; i++) {
        res[i] = i < n_out ? out[i] : NULL;
    }
    return f(arg, res, m->iw, m->w, 0);
}

#ifdef VR_THETA
const double *gt_theta(const ModelData *m)
{
    return &m->real[VR_THETA];
}
#endif

int gt_all_finite(const double *v, int n)
{
    int i;
    for (i = 0; i < n; i++) {
        if (!isfinite(v[i])) {
            return 0;
        }
    }
    return 1;
}

double gt_max_abs(const double *v, int n)
{
    double out = 0.0;
    int i;
    for (i = 0; i < n; i++) {
        out = fmax(out, fabs(v[i]));
    }
    return out;
}

#ifdef VR_THETA
PlantStatus gt_check_schedule(const ModelData *m, const char *what, PlantMessage *msg)
{
    const double *knots = &m->real[VR_COL_FLOW_M3H];
    int k;
    for (k = 1; k < GT_N_KNOTS; k++) {
        if (!(knots[k] > knots[k - 1])) {
            plant_message(msg, "schedule knots must increase strictly: %s = %.17g <= %.17g",
                          plant_variables[VR_COL_FLOW_M3H + k].name, knots[k], knots[k - 1]);
            return PLANT_ERROR;
        }
    }
    for (k = 0; k < GT_N_KNOTS; k++) {
        const double tau = m->real[VR_COL_TIME_CONSTANT_S + k];
        const double delay = m->real[VR_COL_DEAD_TIME_S + k];
        if (!(tau > 0.0)) {
            plant_message(msg, "%s = %.17g must be > 0",
                          plant_variables[VR_COL_TIME_CONSTANT_S + k].name, tau);
            return PLANT_ERROR;
        }
        if (!(delay >= 0.0 && delay <= GT_GEN_MAX_DEAD_TIME_S)) {
            plant_message(msg,
                          "%s = %.17g must lie in [0, %.17g] s (the register of past openings "
                          "this %s was generated with)",
                          plant_variables[VR_COL_DEAD_TIME_S + k].name, delay,
                          GT_GEN_MAX_DEAD_TIME_S, what);
            return PLANT_ERROR;
        }
    }
    return PLANT_OK;
}

#endif

PlantStatus gt_check_flow(double flow_m3h, PlantMessage *msg)
{
    if (!(GT_GEN_FLOW_MIN_M3H <= flow_m3h && flow_m3h <= GT_GEN_FLOW_MAX_M3H)) {
        plant_message(msg, "flow_m3h = %.17g is outside [%g, %g]", flow_m3h,
                      GT_GEN_FLOW_MIN_M3H, GT_GEN_FLOW_MAX_M3H);
        return PLANT_ERROR;
    }
    return PLANT_OK;
}

/* The observer's correct-and-predict iterated to its fixed point (the Riccati equation's
 * solution, which the Python code takes from scipy's solver). */
PlantStatus gt_covariance_fixed_point(ModelData *m, GeneratedFunction riccati,
                                      const double *const *in, int n_in, double *p, double q,
                                      PlantMessage *msg)
{
    double next[GT_GEN_NP], diff[GT_GEN_NP];
    const double *args[GT_GEN_SZ_ARG];
    int it, i;
    memset(p, 0, sizeof next);
    for (i = 0; i < n_in; i++) {
        args[i] = in[i];
    }
    args[n_in] = p;
    for (it = 0; it < GT_GEN_RICCATI_MAX_ITER; it++) {
        double *out[1] = {next};
        gt_call(m, riccati, args, n_in + 1, out, 1);
        for (i = 0; i < GT_GEN_NP; i++) {
            diff[i] = next[i] - p[i];
        }
        memcpy(p, next, sizeof next);
        if (!gt_all_finite(next, GT_GEN_NP)) {
            break;
        }
        if (gt_max_abs(diff, GT_GEN_NP) <= GT_GEN_RICCATI_RTOL * gt_max_abs(next, GT_GEN_NP)) {
            return PLANT_OK;
        }
    }
    plant_message(msg,
                  "the observer's covariance did not settle in %d iterations at flow_m3h = %g "
                  "(the model at this discharge is not observable or not stable)",
                  GT_GEN_RICCATI_MAX_ITER, q);
    return PLANT_ERROR;
}

#ifdef VR_THETA
PlantStatus gt_steady_covariance(ModelData *m, GeneratedFunction riccati, double q,
                                 PlantMessage *msg)
{
    const double *in[2] = {gt_theta(m), &q};
    return gt_covariance_fixed_point(m, riccati, in, 2, m->p, q, msg);
}
#endif

PlantStatus gt_finite_estimate(const ModelData *m, const char *when, const char *what,
                               PlantMessage *msg)
{
    if (gt_all_finite(m->z, GT_GEN_NZ) && isfinite(m->d) && gt_all_finite(m->p, GT_GEN_NP)) {
        return PLANT_OK;
    }
    plant_message(msg, "the observer's estimate is not finite %s; reset the %s", when, what);
    return PLANT_ERROR;
}

/* A restored state can hold a covariance no run produces (finite, but not positive
 * semi-definite), whose step gives finite estimates and NaN derived outputs. */
PlantStatus gt_finite_outputs(const ModelData *m, const char *what, PlantMessage *msg)
{
    unsigned vr;
    for (vr = 0; vr < GT_N_REAL; vr++) {
        if (plant_variables[vr].kind == GT_KIND_OUTPUT && !isfinite(m->real[vr])) {
            plant_message(msg, "%s is not finite after the step; reset the %s",
                          plant_variables[vr].name, what);
            return PLANT_ERROR;
        }
    }
    return PLANT_OK;
}

PlantStatus gt_check_state_head(const ModelData *m, const int *flags, int n_flags,
                                int initialized, PlantMessage *msg)
{
    if (component_check_flags(flags, n_flags, m->initialized, initialized, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    if (!(fabs(m->time_s) <= GT_MAX_TIME_S) || !gt_all_finite(m->real, GT_N_REAL)) {
        plant_message(msg, "state time %g s or a variable is not finite or beyond %g s",
                      m->time_s, GT_MAX_TIME_S);
        return PLANT_ERROR;
    }
    return PLANT_OK;
}
