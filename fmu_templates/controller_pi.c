/* The PI controller behind component.h: checks, state and the sampling of the inputs; the
 * arithmetic of one sample is gt_pi_step, generated from gatetwin.mpc.pi_law (pi_law.c).
 *
 * Mirrors gatetwin.mpc.pi.PiController: plant_initialize is its reset (bumpless: the integral
 * and the output start at start_opening_mm), each sample of a doStep is one call of its step.
 *
 * Sampling: a communication step must be a whole multiple n of sample_period_s. The inputs are
 * sampled at the step's start and held over it (they are piecewise constant, FMI 2.0); the PI
 * runs n samples on them and the output after the step is the opening of the last sample. With
 * n = 1 the output after the step from t is the opening computed from the inputs at t: a master
 * that steps the controller before the plant applies it over [t, t + Ts], as the Python loop
 * (gatetwin.mpc.loop.run_closed_loop) does; one that steps them together applies it a sample
 * later. Before the first step the output is start_opening_mm.
 */
#include <math.h>

#include "component.h"
#include "pi_law.h"

/* Every parameter finite and within GT_PARAMETER_MAX_ABS, then the PI's rules (those of
 * gatetwin.mpc.pi.PiSettings). */
static PlantStatus check_parameters(const ModelData *m, PlantMessage *msg)
{
    const double *r = m->real;
    if (plant_check_parameter_values(r, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    if (!(r[VR_FILTER_TIME_S] >= 0.0)) {
        plant_message(msg, "filter_time_s = %.17g must be >= 0", r[VR_FILTER_TIME_S]);
        return PLANT_ERROR;
    }
    if (!(r[VR_INTEGRAL_TIME_S] > 0.0 && r[VR_TRACKING_TIME_S] > 0.0 &&
          r[VR_SAMPLE_PERIOD_S] > 0.0 && r[VR_OPENING_RATE_MM_S] > 0.0)) {
        plant_message(msg,
                      "integral_time_s = %.17g, tracking_time_s = %.17g, sample_period_s = %.17g "
                      "and opening_rate_mm_s = %.17g must all be > 0",
                      r[VR_INTEGRAL_TIME_S], r[VR_TRACKING_TIME_S], r[VR_SAMPLE_PERIOD_S],
                      r[VR_OPENING_RATE_MM_S]);
        return PLANT_ERROR;
    }
    if (!(0.0 <= r[VR_OPENING_MIN_MM] && r[VR_OPENING_MIN_MM] < r[VR_OPENING_MAX_MM])) {
        plant_message(msg, "need 0 <= opening_min_mm = %.17g < opening_max_mm = %.17g",
                      r[VR_OPENING_MIN_MM], r[VR_OPENING_MAX_MM]);
        return PLANT_ERROR;
    }
    return PLANT_OK;
}

static PlantStatus check_parameters_if_changed(ModelData *m, PlantMessage *msg)
{
    if (m->parameters_changed) {
        if (check_parameters(m, msg) != PLANT_OK) {
            return PLANT_ERROR;
        }
        m->parameters_changed = 0;
    }
    return PLANT_OK;
}

/* The glue refuses a non-finite value; a restored state is checked too: this is the last
 * guard before the arithmetic. */
static PlantStatus check_inputs(const ModelData *m, PlantMessage *msg)
{
    const int inputs[3] = {VR_LEVEL_MM, VR_FLOW_M3H, VR_SETPOINT_MM};
    int i;
    for (i = 0; i < 3; i++) {
        if (!isfinite(m->real[inputs[i]])) {
            plant_message(msg, "input %s = %g is not finite", plant_variables[inputs[i]].name,
                          m->real[inputs[i]]);
            return PLANT_ERROR;
        }
    }
    return PLANT_OK;
}

/* Samples in a communication step of step_s, or -1 with a message (the rule of the ARX). */
static double samples_in(const ModelData *m, double step_s, PlantMessage *msg)
{
    const double period_s = m->real[VR_SAMPLE_PERIOD_S];
    const double n_float = step_s / period_s;
    double n;
    if (!(n_float <= GT_MAX_SAMPLES_PER_STEP)) {
        plant_message(msg,
                      "communication step %.17g s spans %.17g controller samples; the limit is "
                      "%.0e samples per step",
                      step_s, n_float, GT_MAX_SAMPLES_PER_STEP);
        return -1.0;
    }
    n = nearbyint(n_float); /* round half to even, as Python's round() */
    if (n < 1.0 || fabs(n_float - n) > GT_STEP_RTOL * fmax(1.0, n_float)) {
        plant_message(msg,
                      "communication step %.17g s is not a whole multiple of the controller's "
                      "sample period %.17g s",
                      step_s, period_s);
        return -1.0;
    }
    return n;
}

/* --- the glue's entry points ----------------------------------------------------------------- */

void plant_set_defaults(ModelData *m)
{
    component_set_defaults(m);
}

PlantStatus plant_initialize(ModelData *m, PlantMessage *msg)
{
    const double start_mm = m->real[VR_START_OPENING_MM];
    if (check_parameters(m, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    if (!(m->real[VR_OPENING_MIN_MM] <= start_mm && start_mm <= m->real[VR_OPENING_MAX_MM])) {
        plant_message(msg, "start_opening_mm = %.17g is outside [%.17g, %.17g]", start_mm,
                      m->real[VR_OPENING_MIN_MM], m->real[VR_OPENING_MAX_MM]);
        return PLANT_ERROR;
    }
    if (check_inputs(m, msg) != PLANT_OK) { /* the filter starts at the level input */
        return PLANT_ERROR;
    }
    m->integral_mm = start_mm; /* bumpless: at rest the integral holds the opening, */
    m->previous_opening_mm = start_mm;
    m->filtered_mm = m->real[VR_LEVEL_MM]; /* and the filter the level */
    m->parameters_changed = 0;
    m->initialized = 1;
    return PLANT_OK;
}

PlantStatus plant_do_step(ModelData *m, double step_s, PlantMessage *msg)
{
    const double *r = m->real;
    double n, k, opening_mm, integral_mm, filtered_mm;
    if (component_check_step(m, step_s, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    if (check_parameters_if_changed(m, msg) != PLANT_OK || check_inputs(m, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    n = samples_in(m, step_s, msg);
    if (n < 0.0) {
        return PLANT_ERROR; /* nothing has changed: a refused step leaves the state as it was */
    }
    opening_mm = m->previous_opening_mm;
    integral_mm = m->integral_mm;
    filtered_mm = m->filtered_mm;
    for (k = 0.0; k < n; k += 1.0) {
        gt_pi_step(r[VR_LEVEL_MM], r[VR_SETPOINT_MM], integral_mm, opening_mm, filtered_mm,
                   r[VR_GAIN_MM_PER_MM], r[VR_INTEGRAL_TIME_S], r[VR_TRACKING_TIME_S],
                   r[VR_OPENING_MIN_MM], r[VR_OPENING_MAX_MM], r[VR_OPENING_RATE_MM_S],
                   r[VR_SAMPLE_PERIOD_S], r[VR_FILTER_TIME_S], &opening_mm, &integral_mm,
                   &filtered_mm);
        /* finite inputs and parameters can still overflow (a huge error times the gain, a
         * tiny Ti); the range limits would hide it in the opening but not in the integral */
        if (!isfinite(opening_mm) || !isfinite(integral_mm) || !isfinite(filtered_mm)) {
            plant_message(msg,
                          "sample %.0f of the step overflows: level %.17g mm, set-point %.17g mm "
                          "give filtered level %g mm, integral %g mm and opening %g mm with these "
                          "parameters",
                          k + 1.0, r[VR_LEVEL_MM], r[VR_SETPOINT_MM], filtered_mm, integral_mm,
                          opening_mm);
            return PLANT_ERROR; /* the state stays as it was before the step */
        }
    }
    m->previous_opening_mm = opening_mm;
    m->integral_mm = integral_mm;
    m->filtered_mm = filtered_mm;
    m->time_s += step_s;
    return PLANT_OK;
}

PlantStatus plant_output(const ModelData *m, unsigned vr, double *value, PlantMessage *msg)
{
    if (vr != VR_OUTPUT) {
        plant_message(msg, "%s is not an output", plant_variables[vr].name);
        return PLANT_ERROR;
    }
    *value = m->initialized ? m->previous_opening_mm : m->real[VR_START_OPENING_MM];
    return PLANT_OK;
}

/* --- restored states --------------------------------------------------------------------- */

PlantStatus plant_check_state(const ModelData *m, int initialized, PlantMessage *msg)
{
    if ((m->initialized != 0 && m->initialized != 1) ||
        (m->parameters_changed != 0 && m->parameters_changed != 1)) {
        plant_message(msg, "state flags %d, %d are not 0 or 1", m->initialized,
                      m->parameters_changed);
        return PLANT_ERROR;
    }
    if (m->initialized != initialized) {
        plant_message(msg, "state says initialised = %d, its mode needs %d", m->initialized,
                      initialized);
        return PLANT_ERROR;
    }
    if (!(fabs(m->time_s) <= GT_MAX_TIME_S) || !isfinite(m->integral_mm) ||
        !isfinite(m->previous_opening_mm) || !isfinite(m->filtered_mm)) {
        plant_message(msg, "state time %g s, integral %g mm, opening %g mm or filtered level "
                      "%g mm is not finite or beyond %g s", m->time_s, m->integral_mm,
                      m->previous_opening_mm, m->filtered_mm, GT_MAX_TIME_S);
        return PLANT_ERROR;
    }
    if (component_check_reals(m->real, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    /* parameters the state says were checked must pass the checks */
    if (!m->parameters_changed && check_parameters(m, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    return PLANT_OK;
}
