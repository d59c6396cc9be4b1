/* The MPC controller behind component.h: the single-point MPC of gatetwin.mpc.MpcController
 * (the schedule's FOPDT re-rendered at the measured discharge, disturbance observer, condensed
 * QP) as one FMU component.
 *
 * This file only orders calls: every number of the controller is computed by the functions
 * casadi generated from the controller's Python code (mpc_generated.c, gatetwin.mpc.codegen):
 * start, riccati, correct, matrices, vectors, plan, predict; the QP they form is solved by
 * qp_dense.c. Per sample, as MpcController.step: correct the observer with the measured level
 * (model of the last prediction), form the QP at the measured discharge (its matrices and the
 * Hessian's factor only when the discharge changed), solve it (bounded iterations), take the
 * plan's first opening, predict.
 * When the solver does not converge the opening is held and solver_status is 1.
 *
 * Timing: doStep(t, h) reads the inputs at t and sets opening_mm for [t, t + h) (the sample
 * period): a master steps the controller before the plant.
 */
#include <math.h>
#include <string.h>

#include "generated_support.h"

/* --- parameters ------------------------------------------------------------------------------ */

static PlantStatus check_parameters(const ModelData *m, PlantMessage *msg)
{
    const double start = m->real[VR_START_OPENING_MM];
    if (plant_check_parameter_values(m->real, msg) != PLANT_OK ||
        gt_check_schedule(m, "controller", msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    if (!(GT_MPC_OPENING_MIN_MM <= start && start <= GT_MPC_OPENING_MAX_MM)) {
        plant_message(msg, "start_opening_mm = %.17g is outside the opening range [%g, %g] mm",
                      start, GT_MPC_OPENING_MIN_MM, GT_MPC_OPENING_MAX_MM);
        return PLANT_ERROR;
    }
    return PLANT_OK;
}

/* --- the steps of one sample --------------------------------------------------------------- */

/* A set-point outside the level band is followed only as far as the band's soft bound lets
 * the plan go; the first sample with such a set-point (and each change of it) says so. */
static PlantStatus check_setpoint(ModelData *m, double r, PlantMessage *msg)
{
    if (GT_MPC_BAND_LO_MM <= r && r <= GT_MPC_BAND_HI_MM) {
        m->warned_setpoint = 0;
        return PLANT_OK;
    }
    if (m->warned_setpoint && m->warned_setpoint_mm == r) {
        return PLANT_OK;
    }
    m->warned_setpoint = 1;
    m->warned_setpoint_mm = r;
    plant_message(msg, "setpoint_mm = %.17g lies outside the level band [%g, %g] mm: the band's "
                       "soft bound holds the level near its edge", r, GT_MPC_BAND_LO_MM,
                  GT_MPC_BAND_HI_MM);
    return PLANT_WARNING;
}

/* The QP's matrices at discharge q and the Hessian's factor (the Hessian is formed in the
 * solver's scratch); 0 when the Hessian is not positive definite. */
static int form_matrices(ModelData *m, double q)
{
    const int n = GT_MPC_NV;
    if (m->have_matrices && m->flow_matrices_m3h == q) {
        return 1;
    }
    {
        const double *in[2] = {gt_theta(m), &q};
        double *out[2] = {m->qp_work, m->a};
        gt_call(m, gt_mpc_matrices, in, 2, out, 2);
    }
    m->have_matrices = 0;
    if (qp_dense_factor(n, m->qp_work, m->factor, m->qp_work + n * n) != 0) {
        return 0;
    }
    m->flow_matrices_m3h = q;
    m->have_matrices = 1;
    return 1;
}

/* The QP's layout (gatetwin.mpc.qp): the moves of the horizon's N samples, then the band's
 * slack; rows of N each, the opening's range, the band's lower and upper bound. */
#define GT_MPC_N (GT_MPC_NV - 1)
typedef char gt_mpc_layout_is_n_moves_and_3n_rows[(GT_MPC_NC == 3 * GT_MPC_N) ? 1 : -1];

/* The active set of this sample's QP as the next sample's guess: a constraint on move j, or
 * on the opening or level j samples ahead, becomes the one on j - 1 (those on j = 0 are
 * this sample's own); the slack's bound stays. */
static void expect_shifted(ModelData *m, const int *active, int count)
{
    int i, kept = 0;
    for (i = 0; i < count && kept < GT_MPC_NV; i++) {
        const int k = active[i], item = k >> 1, side = k & 1;
        const int row = item - GT_MPC_NV;
        const int base = item < GT_MPC_NV ? 0 : GT_MPC_NV + (row / GT_MPC_N) * GT_MPC_N;
        const int j = item < GT_MPC_NV ? item : row % GT_MPC_N;
        if (item == GT_MPC_N) {
            m->expected[kept++] = k;
        } else if (j > 0) {
            m->expected[kept++] = 2 * (base + j - 1) + side;
        }
    }
    m->n_expected = kept;
}

/* Solve this sample's QP from the observer's estimate; returns 1 when it solved, else 0. */
static int solve(ModelData *m, double q, double setpoint_mm, double *x, double *iterations,
                 double *active)
{
    int status, count = 0, taken = 0;
    *iterations = 0.0;
    *active = 0.0;
    if (!form_matrices(m, q)) {
        m->n_expected = 0;
        return 0;
    }
    {
        const double *in[6] = {gt_theta(m), &q, m->z, &m->d, &m->opening_mm, &setpoint_mm};
        double *out[5] = {m->g, m->lba, m->uba, m->lbx, m->ubx};
        gt_call(m, gt_mpc_vectors, in, 6, out, 5);
    }
    status = qp_dense_solve(GT_MPC_NV, GT_MPC_NC, m->factor, m->g, m->a, m->lba, m->uba,
                            m->lbx, m->ubx, m->expected, m->n_expected, GT_MPC_MAX_ITER, x,
                            &taken, &count, m->qp_work, m->qp_iwork);
    *iterations = taken;
    *active = count;
    if (status != QP_DENSE_SOLVED || !gt_all_finite(x, GT_MPC_NV)) {
        m->n_expected = 0;
        return 0;
    }
    expect_shifted(m, m->qp_iwork, count);
    return 1;
}

/* The opening to hold and the level it predicts one sample ahead; x = 0 holds the opening. */
static void plan(ModelData *m, double q, const double *x, double *opening, double *level)
{
    const double *in[6] = {gt_theta(m), &q, m->z, &m->d, &m->opening_mm, x};
    double *out[2] = {opening, level};
    gt_call(m, gt_mpc_plan, in, 6, out, 2);
}

static void observer_step(ModelData *m, GeneratedFunction f, const double *const *in, int n_in)
{
    double z[GT_GEN_NZ], d, p[GT_GEN_NP];
    double *out[3] = {z, &d, p};
    gt_call(m, f, in, n_in, out, 3);
    memcpy(m->z, z, sizeof z);
    m->d = d;
    memcpy(m->p, p, sizeof p);
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
    component_set_defaults(m);
    m->real[VR_OPENING_MM] = m->real[VR_START_OPENING_MM];
}

/* At rest at start_opening_mm with the level and discharge measured now, as
 * MpcController.reset: the observer's steady estimate and covariance; the QP's matrices at
 * this discharge are formed now, so that the first step pays no more than the others. */
PlantStatus plant_initialize(ModelData *m, PlantMessage *msg)
{
    double q = m->real[VR_FLOW_M3H], y = m->real[VR_LEVEL], e = m->real[VR_START_OPENING_MM];
    double zero[GT_MPC_NV], opening, level;
    if (check_parameters(m, msg) != PLANT_OK || gt_check_flow(q, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    m->parameters_changed = 0;
    {
        const double *in[4] = {gt_theta(m), &q, &e, &y};
        double *out[2] = {m->z, &m->d};
        gt_call(m, gt_mpc_start, in, 4, out, 2);
    }
    if (gt_steady_covariance(m, gt_mpc_riccati, q, msg) != PLANT_OK ||
        gt_finite_estimate(m, "at the start", "controller", msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    m->opening_mm = e;
    m->flow_model_m3h = q;
    m->have_matrices = 0;
    m->n_expected = 0;
    if (!form_matrices(m, q)) {
        plant_message(msg, "the QP's Hessian at flow_m3h = %.17g is not positive definite", q);
        return PLANT_ERROR;
    }
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
    PlantStatus band;
    int ok;
    if (!(fabs(step_s - GT_GEN_SAMPLE_PERIOD_S) <=
          GT_COMMUNICATION_POINT_RTOL * GT_GEN_SAMPLE_PERIOD_S)) {
        plant_message(msg, "communication step %.17g s must be the controller's sample period "
                           "%.17g s", step_s, GT_GEN_SAMPLE_PERIOD_S);
        return PLANT_ERROR;
    }
    if (!(fabs(m->time_s + step_s) <= GT_MAX_TIME_S)) {
        plant_message(msg, "communication step to t = %.17g s passes the time limit %g s",
                      m->time_s + step_s, GT_MAX_TIME_S);
        return PLANT_ERROR;
    }
    if (gt_check_flow(q, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    {
        const double *in[6] = {gt_theta(m), &m->flow_model_m3h, m->z, &m->d, m->p, &y};
        observer_step(m, gt_mpc_correct, in, 6);
    }
    band = check_setpoint(m, r, msg);
    ok = solve(m, q, r, x, &iterations, &active);
    if (!ok) {
        memset(x, 0, sizeof x); /* no move: the opening is held */
    }
    plan(m, q, x, &opening, &level);
    {
        const double *in[7] = {gt_theta(m), &m->flow_model_m3h, &q, m->z, &m->d, m->p, &opening};
        observer_step(m, gt_mpc_predict, in, 7);
    }
    m->flow_model_m3h = q;
    m->opening_mm = opening;
    m->time_s += step_s;
    set_outputs(m, opening, level, active, ok ? 0 : 1, iterations);
    if (gt_finite_estimate(m, "after the step", "controller", msg) != PLANT_OK ||
        gt_finite_outputs(m, "controller", msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    return band;
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
    if (gt_check_state_head(m, flags, 3, initialized, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    {
        const double scalars[4] = {m->d, m->opening_mm, m->flow_model_m3h,
                                   m->flow_matrices_m3h};
        if (!gt_all_finite(scalars, 4) || !gt_all_finite(m->z, GT_GEN_NZ) ||
            !gt_all_finite(m->p, GT_GEN_NP) ||
            !gt_all_finite(m->factor, GT_MPC_NV * GT_MPC_NV) ||
            !gt_all_finite(m->a, GT_MPC_NC * GT_MPC_NV)) {
            plant_message(msg, "state of the observer or of the QP is not finite");
            return PLANT_ERROR;
        }
    }
    if (!(0 <= m->n_expected && m->n_expected <= GT_MPC_NV)) {
        plant_message(msg, "state of the QP's warm start is out of range");
        return PLANT_ERROR;
    }
    if (!m->parameters_changed && check_parameters(m, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    return PLANT_OK;
}
