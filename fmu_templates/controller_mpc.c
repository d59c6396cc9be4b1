/* The MPC controller behind component.h: the single-point MPC of gatetwin.mpc.MpcController
 * (the schedule's FOPDT re-rendered at the measured discharge, disturbance observer, condensed
 * QP) as one FMU component.
 *
 * This file only orders calls: every number is computed by the functions casadi generated from
 * the controller's Python code (mpc_generated.c, gatetwin.mpc.codegen): start, riccati,
 * correct, matrices, vectors, qp, plan, predict. Per sample, as MpcController.step: correct
 * the observer with the measured level (model of the last prediction), form the QP at the
 * measured discharge (its matrices only when the discharge changed), solve it (qrqp, bounded
 * iterations, from the last solution), take the plan's first opening, predict.
 * When the solver does not converge the opening is held and solver_status is 1.
 *
 * Timing: doStep(t, h) reads the inputs at t and sets opening_mm for [t, t + h) (the sample
 * period): a master steps the controller before the plant.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "component.h"

#define GT_VARIABLE_ENTRY(name, kind, start) {name, kind, start},
const PlantVariable plant_variables[GT_N_REAL] = {GT_VARIABLES(GT_VARIABLE_ENTRY)};
#undef GT_VARIABLE_ENTRY

void plant_message(PlantMessage *msg, const char *format, ...)
{
    va_list args;
    va_start(args, format);
    vsnprintf(msg->text, sizeof msg->text, format, args);
    va_end(args);
}

typedef int (*GeneratedFunction)(const casadi_real **arg, casadi_real **res, casadi_int *iw,
                                 casadi_real *w, int mem);

/* One call of a generated function on ModelData's work arrays; returns its flag (0: ok). */
static int call(ModelData *m, GeneratedFunction f, const double *const *in, int n_in,
                double *const *out, int n_out)
{
    const casadi_real *arg[GT_MPC_SZ_ARG];
    casadi_real *res[GT_MPC_SZ_RES];
    int i;
    for (i = 0; i < GT_MPC_SZ_ARG; i++) {
        arg[i] = i < n_in ? in[i] : NULL;
    }
    for (i = 0; i < GT_MPC_SZ_RES; i++) {
        res[i] = i < n_out ? out[i] : NULL;
    }
    return f(arg, res, m->iw, m->w, 0);
}

static const double *theta(const ModelData *m)
{
    return &m->real[VR_THETA];
}

static int all_finite(const double *v, int n)
{
    int i;
    for (i = 0; i < n; i++) {
        if (!isfinite(v[i])) {
            return 0;
        }
    }
    return 1;
}

static double max_abs(const double *v, int n)
{
    double out = 0.0;
    int i;
    for (i = 0; i < n; i++) {
        out = fmax(out, fabs(v[i]));
    }
    return out;
}

/* --- parameters ------------------------------------------------------------------------------ */

static PlantStatus check_parameters(const ModelData *m, PlantMessage *msg)
{
    const double *knots = &m->real[VR_COL_FLOW_M3H];
    const double start = m->real[VR_START_OPENING_MM];
    int vr, k;
    for (vr = 0; vr < GT_N_REAL; vr++) {
        const VariableKind kind = plant_variables[vr].kind;
        if ((kind == GT_KIND_TUNABLE || kind == GT_KIND_FIXED) &&
            !(fabs(m->real[vr]) <= GT_PARAMETER_MAX_ABS)) {
            plant_message(msg, "parameter %s = %.17g must be finite with |value| <= %g",
                          plant_variables[vr].name, m->real[vr], GT_PARAMETER_MAX_ABS);
            return PLANT_ERROR;
        }
    }
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
        if (!(delay >= 0.0 && delay <= GT_MPC_MAX_DEAD_TIME_S)) {
            plant_message(msg,
                          "%s = %.17g must lie in [0, %.17g] s (the register of past openings "
                          "this controller was generated with)",
                          plant_variables[VR_COL_DEAD_TIME_S + k].name, delay,
                          GT_MPC_MAX_DEAD_TIME_S);
            return PLANT_ERROR;
        }
    }
    if (!(GT_MPC_OPENING_MIN_MM <= start && start <= GT_MPC_OPENING_MAX_MM)) {
        plant_message(msg, "start_opening_mm = %.17g is outside the opening range [%g, %g] mm",
                      start, GT_MPC_OPENING_MIN_MM, GT_MPC_OPENING_MAX_MM);
        return PLANT_ERROR;
    }
    return PLANT_OK;
}

static PlantStatus check_flow(double flow_m3h, PlantMessage *msg)
{
    if (!(GT_MPC_FLOW_MIN_M3H <= flow_m3h && flow_m3h <= GT_MPC_FLOW_MAX_M3H)) {
        plant_message(msg, "flow_m3h = %.17g is outside [%g, %g]", flow_m3h,
                      GT_MPC_FLOW_MIN_M3H, GT_MPC_FLOW_MAX_M3H);
        return PLANT_ERROR;
    }
    return PLANT_OK;
}

/* --- the steps of one sample --------------------------------------------------------------- */

/* The steady prior covariance at discharge q: the observer's correct-and-predict iterated to
 * its fixed point (the Riccati equation's solution, which the Python controller takes from
 * scipy's solver). */
static PlantStatus steady_covariance(ModelData *m, double q, PlantMessage *msg)
{
    double next[GT_MPC_NP], diff[GT_MPC_NP];
    int it, i;
    memset(m->p, 0, sizeof m->p);
    for (it = 0; it < GT_MPC_RICCATI_MAX_ITER; it++) {
        const double *in[3] = {theta(m), &q, m->p};
        double *out[1] = {next};
        call(m, gt_mpc_riccati, in, 3, out, 1);
        for (i = 0; i < GT_MPC_NP; i++) {
            diff[i] = next[i] - m->p[i];
        }
        memcpy(m->p, next, sizeof next);
        if (!all_finite(next, GT_MPC_NP)) {
            break;
        }
        if (max_abs(diff, GT_MPC_NP) <= GT_MPC_RICCATI_RTOL * max_abs(next, GT_MPC_NP)) {
            return PLANT_OK;
        }
    }
    plant_message(msg,
                  "the observer's covariance did not settle in %d iterations at flow_m3h = %g "
                  "(the model at this discharge is not observable or not stable)",
                  GT_MPC_RICCATI_MAX_ITER, q);
    return PLANT_ERROR;
}

static void form_matrices(ModelData *m, double q)
{
    if (m->have_matrices && m->flow_matrices_m3h == q) {
        return;
    }
    const double *in[2] = {theta(m), &q};
    double *out[2] = {m->h, m->a};
    call(m, gt_mpc_matrices, in, 2, out, 2);
    m->flow_matrices_m3h = q;
    m->have_matrices = 1;
}

/* Solve this sample's QP from the observer's estimate; returns 1 when qrqp converged, else 0.
 * A finite solution is the next call's initial guess (as the Python controller's backend
 * keeps it); the multipliers start at zero, as there (warm-started multipliers made qrqp
 * cycle to its iteration limit on the demo's transients). */
static int solve(ModelData *m, double q, double setpoint_mm, double *x, double *iterations,
                 double *active)
{
    double lam_x[GT_MPC_NV], lam_a[GT_MPC_NC], cost[2] = {0.0, 0.0};
    int flag, i, count = 0;
    form_matrices(m, q);
    {
        const double *in[6] = {theta(m), &q, m->z, &m->d, &m->opening_mm, &setpoint_mm};
        double *out[5] = {m->g, m->lba, m->uba, m->lbx, m->ubx};
        call(m, gt_mpc_vectors, in, 6, out, 5);
    }
    {
        const double *in[8] = {m->h, m->g, m->a, m->lba, m->uba, m->lbx, m->ubx, m->x};
        double *out[4] = {x, cost, lam_a, lam_x};
        flag = call(m, gt_mpc_qp, in, 8, out, 4);
    }
    *iterations = cost[1];
    for (i = 0; i < GT_MPC_NV; i++) {
        count += lam_x[i] != 0.0;
    }
    for (i = 0; i < GT_MPC_NC; i++) {
        count += lam_a[i] != 0.0;
    }
    *active = count;
    if (!all_finite(x, GT_MPC_NV)) {
        return 0;
    }
    memcpy(m->x, x, sizeof m->x);
    return flag == 0;
}

/* The opening to hold and the level it predicts one sample ahead; x = 0 holds the opening. */
static void plan(ModelData *m, double q, const double *x, double *opening, double *level)
{
    const double *in[6] = {theta(m), &q, m->z, &m->d, &m->opening_mm, x};
    double *out[2] = {opening, level};
    call(m, gt_mpc_plan, in, 6, out, 2);
}

static void observer_step(ModelData *m, GeneratedFunction f, const double *const *in, int n_in)
{
    double z[GT_MPC_NZ], d, p[GT_MPC_NP];
    double *out[3] = {z, &d, p};
    call(m, f, in, n_in, out, 3);
    memcpy(m->z, z, sizeof z);
    m->d = d;
    memcpy(m->p, p, sizeof p);
}

static PlantStatus finite_estimate(const ModelData *m, const char *when, PlantMessage *msg)
{
    if (all_finite(m->z, GT_MPC_NZ) && isfinite(m->d) && all_finite(m->p, GT_MPC_NP)) {
        return PLANT_OK;
    }
    plant_message(msg, "the observer's estimate is not finite %s; reset the controller", when);
    return PLANT_ERROR;
}

/* Every output finite: a restored state can hold a covariance no run produces (finite, but not
 * positive semi-definite), whose step gives finite estimates and NaN derived outputs. */
static PlantStatus finite_outputs(const ModelData *m, PlantMessage *msg)
{
    unsigned vr;
    for (vr = 0; vr < GT_N_REAL; vr++) {
        if (plant_variables[vr].kind == GT_KIND_OUTPUT && !isfinite(m->real[vr])) {
            plant_message(msg, "%s is not finite after the step; reset the %s",
                          plant_variables[vr].name, "controller");
            return PLANT_ERROR;
        }
    }
    return PLANT_OK;
}

static void set_outputs(ModelData *m, double opening, double level, double active, int status,
                        double iterations)
{
    m->real[VR_OPENING_MM] = opening;
    m->real[VR_PREDICTED_LEVEL_MM] = level;
    m->real[VR_ACTIVE_CONSTRAINTS] = active;
    m->real[VR_SOLVER_STATUS] = status;
    m->real[VR_SOLVER_ITERATIONS] = iterations;
}

/* --- the glue's entry points ----------------------------------------------------------------- */

void plant_set_defaults(ModelData *m)
{
    int vr;
    memset(m, 0, sizeof *m);
    for (vr = 0; vr < GT_N_REAL; vr++) {
        m->real[vr] = plant_variables[vr].start;
    }
    m->real[VR_OPENING_MM] = m->real[VR_START_OPENING_MM];
    m->parameters_changed = 1;
}

/* At rest at start_opening_mm with the level and discharge measured now, as
 * MpcController.reset: the observer's steady estimate and covariance, then one solve at rest
 * (its solution is the first warm start). */
PlantStatus plant_initialize(ModelData *m, PlantMessage *msg)
{
    double q = m->real[VR_FLOW_M3H], y = m->real[VR_LEVEL], e = m->real[VR_START_OPENING_MM];
    double x[GT_MPC_NV], zero[GT_MPC_NV], opening, level, iterations, active;
    if (check_parameters(m, msg) != PLANT_OK || check_flow(q, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    m->parameters_changed = 0;
    {
        const double *in[4] = {theta(m), &q, &e, &y};
        double *out[2] = {m->z, &m->d};
        call(m, gt_mpc_start, in, 4, out, 2);
    }
    if (steady_covariance(m, q, msg) != PLANT_OK ||
        finite_estimate(m, "at the start", msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    m->opening_mm = e;
    m->flow_model_m3h = q;
    m->have_matrices = 0;
    memset(m->x, 0, sizeof m->x);
    solve(m, q, y, x, &iterations, &active);
    memset(zero, 0, sizeof zero);
    plan(m, q, zero, &opening, &level);
    set_outputs(m, e, level, 0.0, 0, 0.0);
    m->initialized = 1;
    return PLANT_OK;
}

PlantStatus plant_do_step(ModelData *m, double step_s, PlantMessage *msg)
{
    double q = m->real[VR_FLOW_M3H], y = m->real[VR_LEVEL], r = m->real[VR_SETPOINT_MM];
    double x[GT_MPC_NV], opening, level, iterations, active;
    int ok;
    if (!(fabs(step_s - GT_MPC_SAMPLE_PERIOD_S) <=
          GT_COMMUNICATION_POINT_RTOL * GT_MPC_SAMPLE_PERIOD_S)) {
        plant_message(msg, "communication step %.17g s must be the controller's sample period "
                           "%.17g s", step_s, GT_MPC_SAMPLE_PERIOD_S);
        return PLANT_ERROR;
    }
    if (!(fabs(m->time_s + step_s) <= GT_MAX_TIME_S)) {
        plant_message(msg, "communication step to t = %.17g s passes the time limit %g s",
                      m->time_s + step_s, GT_MAX_TIME_S);
        return PLANT_ERROR;
    }
    if (check_flow(q, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    {
        const double *in[6] = {theta(m), &m->flow_model_m3h, m->z, &m->d, m->p, &y};
        observer_step(m, gt_mpc_correct, in, 6);
    }
    ok = solve(m, q, r, x, &iterations, &active);
    if (!ok) {
        memset(x, 0, sizeof x); /* no move: the opening is held */
    }
    plan(m, q, x, &opening, &level);
    {
        const double *in[7] = {theta(m), &m->flow_model_m3h, &q, m->z, &m->d, m->p, &opening};
        observer_step(m, gt_mpc_predict, in, 7);
    }
    m->flow_model_m3h = q;
    m->opening_mm = opening;
    m->time_s += step_s;
    set_outputs(m, opening, level, active, ok ? 0 : 1, iterations);
    if (finite_estimate(m, "after the step", msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    return finite_outputs(m, msg);
}

PlantStatus plant_output(const ModelData *m, unsigned vr, double *value, PlantMessage *msg)
{
    if (plant_variables[vr].kind != GT_KIND_OUTPUT) {
        plant_message(msg, "%s is not an output", plant_variables[vr].name);
        return PLANT_ERROR;
    }
    /* before initialisation the opening is the one held at rest: start_opening_mm as set now
     * (a master propagating initial values reads it, as the PI's) */
    if (!m->initialized && vr == VR_OPENING_MM) {
        *value = m->real[VR_START_OPENING_MM];
        return PLANT_OK;
    }
    *value = m->real[vr];
    return PLANT_OK;
}

/* --- restored states --------------------------------------------------------------------- */

PlantStatus plant_check_state(const ModelData *m, int initialized, PlantMessage *msg)
{
    const int flags[3] = {m->initialized, m->parameters_changed, m->have_matrices};
    int i;
    for (i = 0; i < 3; i++) {
        if (flags[i] != 0 && flags[i] != 1) {
            plant_message(msg, "state flag %d is %d, not 0 or 1", i, flags[i]);
            return PLANT_ERROR;
        }
    }
    if (m->initialized != initialized) {
        plant_message(msg, "state says initialised = %d, its mode needs %d", m->initialized,
                      initialized);
        return PLANT_ERROR;
    }
    if (!(fabs(m->time_s) <= GT_MAX_TIME_S) || !all_finite(m->real, GT_N_REAL)) {
        plant_message(msg, "state time %g s or a variable is not finite or beyond %g s",
                      m->time_s, GT_MAX_TIME_S);
        return PLANT_ERROR;
    }
    {
        const double scalars[4] = {m->d, m->opening_mm, m->flow_model_m3h,
                                   m->flow_matrices_m3h};
        if (!all_finite(scalars, 4) || !all_finite(m->z, GT_MPC_NZ) ||
            !all_finite(m->p, GT_MPC_NP) || !all_finite(m->x, GT_MPC_NV) ||
            !all_finite(m->h, GT_MPC_NV * GT_MPC_NV) ||
            !all_finite(m->a, GT_MPC_NC * GT_MPC_NV)) {
            plant_message(msg, "state of the observer or of the QP is not finite");
            return PLANT_ERROR;
        }
    }
    if (!m->parameters_changed && check_parameters(m, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    return PLANT_OK;
}
