/* The plant pipeline shared by every family: input checks, schedule lookup, parameter checks,
 * and command -> input blocks -> dynamics -> output blocks (effects.h; the family runs the
 * input blocks over its pieces of a step, model_fopdt.c / model_arx.c).
 *
 * Mirrors gatetwin.plant.simulate.PlantSimulator (initialize, do_step, level_mm) and
 * gatetwin.plant.model.interp_clamped operation by operation, so that results agree to the bit.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "effects.h"
#include "plant.h"

static PlantStatus level_output(const ModelData *m, double *level_mm, PlantMessage *msg);
static double level_at(const ModelData *m, const KnotPosition *at);

static PlantStatus check_inputs(double opening_mm, double flow_m3h, PlantMessage *msg)
{
    if (!(GT_OPENING_MIN_MM <= opening_mm && opening_mm <= GT_OPENING_MAX_MM)) {
        plant_message(msg, "opening_mm = %.17g is outside [%.17g, %.17g]", opening_mm,
                      GT_OPENING_MIN_MM, GT_OPENING_MAX_MM);
        return PLANT_ERROR;
    }
    if (!(GT_FLOW_MIN_M3H <= flow_m3h && flow_m3h <= GT_FLOW_MAX_M3H)) {
        plant_message(msg, "flow_m3h = %.17g is outside [%.17g, %.17g]", flow_m3h,
                      GT_FLOW_MIN_M3H, GT_FLOW_MAX_M3H);
        return PLANT_ERROR;
    }
    return PLANT_OK;
}

/* Every parameter finite and within GT_PARAMETER_MAX_ABS, knots strictly increasing, then the
 * family's own rules. */
static PlantStatus check_parameters(const ModelData *m, PlantMessage *msg)
{
    int vr;
    if (plant_check_parameter_values(m->real, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    for (vr = VR_COL_FLOW_M3H + 1; vr < VR_COL_FLOW_M3H + GT_N_KNOTS; vr++) {
        if (!(m->real[vr] > m->real[vr - 1])) {
            plant_message(msg, "schedule knots must increase strictly: %s = %.17g <= %s = %.17g",
                          plant_variables[vr].name, m->real[vr], plant_variables[vr - 1].name,
                          m->real[vr - 1]);
            return PLANT_ERROR;
        }
    }
    if (dynamics_check_parameters(m, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    return effects_check_parameters(m, msg);
}

static PlantStatus check_parameters_if_changed(ModelData *m, PlantMessage *msg)
{
    if (m->parameters_changed) {
        m->cache.valid = 0; /* derived from the parameters that were in force */
        if (check_parameters(m, msg) != PLANT_OK) {
            return PLANT_ERROR;
        }
        m->parameters_changed = 0;
    }
    return PLANT_OK;
}

/* Warn with `text` when value lies outside [lo, hi]. */
static int outside(PlantMessage *msg, const char *name, double value, double lo, double hi,
                   const char *unit)
{
    if (lo <= value && value <= hi) {
        return 0;
    }
    plant_message(msg, "%s %g outside the model's validity %g..%g %s; results are extrapolated",
                  name, value, lo, hi, unit);
    return 1;
}

/* Warn once per instance, the first time the opening, the discharge or the level leaves the
 * model's validity envelope (model_config.h). Without a stated discharge range the schedule's
 * knots are the discharge's range (outside them the parameters clamp). */
static PlantStatus check_validity(ModelData *m, double opening_mm, double flow_m3h,
                                  double level_mm, PlantMessage *msg)
{
    const double knot_lo = m->real[VR_COL_FLOW_M3H];
    const double knot_hi = m->real[VR_COL_FLOW_M3H + GT_N_KNOTS - 1];
    int left;
    if (m->warned_validity) {
        return PLANT_OK;
    }
    left = GT_VALIDITY_OPENING &&
           outside(msg, "opening_mm", opening_mm, GT_VALIDITY_OPENING_MIN,
                   GT_VALIDITY_OPENING_MAX, GT_VALIDITY_OPENING_UNIT);
    left = left || (GT_VALIDITY_FLOW &&
                    outside(msg, "flow_m3h", flow_m3h, GT_VALIDITY_FLOW_MIN,
                            GT_VALIDITY_FLOW_MAX, GT_VALIDITY_FLOW_UNIT));
    if (!left && !GT_VALIDITY_FLOW && !(knot_lo <= flow_m3h && flow_m3h <= knot_hi)) {
        plant_message(msg,
                      "flow_m3h = %.17g outside the schedule's validity range [%.17g, %.17g]; "
                      "parameters clamped (warned once per instance)",
                      flow_m3h, knot_lo, knot_hi);
        left = 1;
    }
    left = left || (GT_VALIDITY_LEVEL &&
                    outside(msg, plant_variables[VR_OUTPUT].name, level_mm,
                            GT_VALIDITY_LEVEL_MIN, GT_VALIDITY_LEVEL_MAX,
                            GT_VALIDITY_LEVEL_UNIT));
    if (left) {
        m->warned_validity = 1;
        return PLANT_WARNING;
    }
    return PLANT_OK;
}

/* The output after initialisation or a step (`at`: the discharge in force), kept in
 * m->output_mm: finite, or an error saying when. */
static PlantStatus finite_output(ModelData *m, const KnotPosition *at, const char *when,
                                 double *level_mm, PlantMessage *msg)
{
    *level_mm = level_at(m, at);
    m->output_mm = *level_mm;
    if (!isfinite(*level_mm)) {
        plant_message(msg,
                      "%s = %g %s is not finite: the parameters (or an unstable model) drive "
                      "the level beyond any number; restore a state or reset",
                      plant_variables[VR_OUTPUT].name, *level_mm, when);
        return PLANT_ERROR;
    }
    return PLANT_OK;
}

/* What the output adds to the family's state: level_ref_mm(Q), or 0 for an envelope FOPDT
 * (its state is the level itself). */
static double level_offset(const ModelData *m, const KnotPosition *at)
{
#if GT_ENVELOPE
    (void)m;
    (void)at;
    return 0.0;
#else
    return plant_interp(at, &m->real[VR_COL_LEVEL_REF_MM]);
#endif
}

/* The step cache for the discharge flow_m3h (checked parameters): kept if it holds for it,
 * else derived anew. */
static const StepCache *step_cache(ModelData *m, double flow_m3h)
{
    StepCache *c = &m->cache;
    if (!c->valid || !plant_same_bits(c->flow_m3h, flow_m3h)) {
        c->flow_m3h = flow_m3h;
        c->at = plant_locate(m, flow_m3h);
        dynamics_derive(m, flow_m3h, &c->at, &c->dyn);
        c->valid = 1;
    }
    return c;
}

/* --- the glue's entry points ----------------------------------------------------------------- */

void plant_set_defaults(ModelData *m)
{
    component_set_defaults(m);
}

/* Checked inputs and parameters, and the equilibrium they define (u, knot position, x0). */
static PlantStatus equilibrium(const ModelData *m, double *u, KnotPosition *at, double *x0,
                               PlantMessage *msg)
{
    const double opening_mm = m->real[VR_OPENING_MM];
    const double flow_m3h = m->real[VR_FLOW_M3H];
    if (check_inputs(opening_mm, flow_m3h, msg) != PLANT_OK ||
        check_parameters(m, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    *u = effects_input(m, opening_mm); /* at rest the gate is where it is commanded */
    *at = plant_locate(m, flow_m3h);
    return dynamics_equilibrium(m, *u, at, x0, msg);
}

PlantStatus plant_initialize(ModelData *m, PlantMessage *msg)
{
    KnotPosition at;
    double u, x0, level;
    if (equilibrium(m, &u, &at, &x0, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    dynamics_initialize(m, u, x0);
    m->cache.valid = 0; /* a restored state's cache may hold other parameters */
    effects_initialize(m, m->real[VR_OPENING_MM], m->real[VR_FLOW_M3H],
                       level_offset(m, &at) + x0);
    m->flow_in_force_m3h = m->real[VR_FLOW_M3H];
    m->parameters_changed = 0;
    m->initialized = 1;
    if (finite_output(m, &at, "at initialisation", &level, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    return check_validity(m, m->real[VR_OPENING_MM], m->flow_in_force_m3h, level, msg);
}

PlantStatus plant_do_step(ModelData *m, double step_s, PlantMessage *msg)
{
    const double opening_mm = m->real[VR_OPENING_MM];
    const double flow_m3h = m->real[VR_FLOW_M3H];
    if (check_inputs(opening_mm, flow_m3h, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    if (component_check_step(m, step_s, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    if (check_parameters_if_changed(m, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    /* ---- pipeline: input blocks and dynamics over the family's pieces, then output blocks ---- */
    if (dynamics_check_step(m, step_s, opening_mm, msg) != PLANT_OK) {
        return PLANT_ERROR; /* nothing has changed: a refused step leaves the state as it was */
    }
    const StepCache *cache = step_cache(m, flow_m3h);
    dynamics_step(m, step_s, opening_mm);
    effects_step_end(m, step_s, flow_m3h);
    m->flow_in_force_m3h = flow_m3h;
    m->time_s += step_s;
    double level_mm;
    if (finite_output(m, &cache->at, "after the step", &level_mm, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    return check_validity(m, opening_mm, flow_m3h, level_mm, msg);
}

/* The output of an initialised instance; `at` locates the discharge in force. */
static double level_at(const ModelData *m, const KnotPosition *at)
{
    return effects_output(m, level_offset(m, at) + m->dyn.x);
}

static PlantStatus level_output(const ModelData *m, double *level_mm, PlantMessage *msg)
{
    KnotPosition at;
    double u, x;
    if (m->initialized) {
        at = plant_locate(m, m->flow_in_force_m3h);
        *level_mm = level_at(m, &at);
        return PLANT_OK;
    }
    if (equilibrium(m, &u, &at, &x, msg) != PLANT_OK) {
        return PLANT_ERROR; /* before initialisation the output is the equilibrium level */
    }
    *level_mm = effects_output_at_rest(m, level_offset(m, &at) + x, m->real[VR_FLOW_M3H]);
    return PLANT_OK;
}

PlantStatus plant_output(const ModelData *m, unsigned vr, double *value, PlantMessage *msg)
{
    if (vr != VR_OUTPUT) {
        plant_message(msg, "%s is not an output", plant_variables[vr].name);
        return PLANT_ERROR;
    }
    if (m->initialized && !m->parameters_changed) {
        *value = m->output_mm; /* what the last step computed; nothing it depends on changed */
        return PLANT_OK;
    }
    return level_output(m, value, msg);
}

/* A restored state's kept output must be the one its state gives (bit for bit). */
static PlantStatus check_kept_output(const ModelData *m, PlantMessage *msg)
{
    double level_mm;
    if (!m->initialized || m->parameters_changed) {
        return PLANT_OK;
    }
    if (level_output(m, &level_mm, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    if (memcmp(&level_mm, &m->output_mm, sizeof level_mm) != 0) {
        plant_message(msg, "state's output %.17g mm is not the %.17g mm its state gives",
                      m->output_mm, level_mm);
        return PLANT_ERROR;
    }
    return PLANT_OK;
}

/* A restored state's step cache must be what its discharge and parameters give (bit for bit),
 * unless it is dropped before any use: before initialisation (plant_initialize drops it) and
 * after a parameter change (the next step drops it). */
static PlantStatus check_cache(const ModelData *m, PlantMessage *msg)
{
    const StepCache *c = &m->cache;
    KnotPosition at;
    if (plant_check_flag(c->valid, "step cache", msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    if (!c->valid || !m->initialized || m->parameters_changed) {
        return PLANT_OK;
    }
    at = plant_locate(m, c->flow_m3h);
    if (!isfinite(c->flow_m3h) || at.index != c->at.index || at.clamped != c->at.clamped ||
        !plant_same_bits(at.weight, c->at.weight)) {
        plant_message(msg,
                      "state's step cache (knot %d, weight %.17g, clamped %d) is not what its "
                      "discharge %.17g m3/h gives",
                      c->at.index, c->at.weight, c->at.clamped, c->flow_m3h);
        return PLANT_ERROR;
    }
    return dynamics_check_cache(m, msg);
}

/* --- restored states --------------------------------------------------------------------- */

static PlantStatus check_flags(const ModelData *m, int initialized, PlantMessage *msg)
{
    const int flags[3] = {m->initialized, m->warned_validity, m->parameters_changed};
    return component_check_flags(flags, 3, m->initialized, initialized, msg);
}

PlantStatus plant_check_state(const ModelData *m, int initialized, PlantMessage *msg)
{
    if (check_flags(m, initialized, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    if (!(fabs(m->time_s) <= GT_MAX_TIME_S) || !isfinite(m->flow_in_force_m3h)) {
        plant_message(msg, "state time %g s or discharge %g m3/h is not finite or beyond %g s",
                      m->time_s, m->flow_in_force_m3h, GT_MAX_TIME_S);
        return PLANT_ERROR;
    }
    if (component_check_reals(m->real, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    /* parameters the state says were checked must pass the checks */
    if (!m->parameters_changed && check_parameters(m, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    if (dynamics_check_state(m, msg) != PLANT_OK || effects_check_state(m, msg) != PLANT_OK ||
        check_cache(m, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    return check_kept_output(m, msg);
}
