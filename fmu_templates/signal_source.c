/* A scenario as an FMU (component.h): no inputs, one output per tabulated signal. Each
 * signal's knots are fixed parameters (<name>_table.time_s[k], <name>_table.value[k], k from
 * 1) and <name>_table.linear says how its value runs between them (0: held from each knot on;
 * 1: linear); the output at time t is gt_signal_value, generated from
 * gatetwin.mpc.signal_law (signal_law.c). model_config.h lists the signals in GT_SIGNALS(X) as
 * X(output vr, linear vr, vr of the first time, vr of the first value, number of knots).
 *
 * The outputs hold the value at the instance's time: at the start time after initialisation,
 * at t + h after a step from t. A master that reads them before stepping the components that
 * read them gives each the signal at the communication point its step starts from.
 */
#include <math.h>

#include "component.h"
#include "signal_law.h"

typedef struct {
    unsigned output, linear, first_time, first_value;
    int count;
} Signal;

#define GT_SIGNAL_ROW(out, lin, t0, v0, n) {(out), (lin), (t0), (v0), (n)},
static const Signal signals[GT_N_SIGNALS] = {GT_SIGNALS(GT_SIGNAL_ROW)};

/* Every parameter finite and within GT_PARAMETER_MAX_ABS, each signal's linear 0 or 1 and its
 * times increasing strictly. */
static PlantStatus check_parameters(const ModelData *m, PlantMessage *msg)
{
    const double *r = m->real;
    int s, k;
    if (plant_check_parameter_values(r, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    for (s = 0; s < GT_N_SIGNALS; s++) {
        const Signal *sig = &signals[s];
        if (!(r[sig->linear] == 0.0 || r[sig->linear] == 1.0)) {
            plant_message(msg, "%s = %.17g must be 0 (held) or 1 (linear)",
                          plant_variables[sig->linear].name, r[sig->linear]);
            return PLANT_ERROR;
        }
        for (k = 1; k < sig->count; k++) {
            if (!(r[sig->first_time + k] > r[sig->first_time + k - 1])) {
                plant_message(msg, "%s = %.17g s must lie after %s = %.17g s",
                              plant_variables[sig->first_time + k].name, r[sig->first_time + k],
                              plant_variables[sig->first_time + k - 1].name,
                              r[sig->first_time + k - 1]);
                return PLANT_ERROR;
            }
        }
    }
    return PLANT_OK;
}

/* --- the glue's entry points ----------------------------------------------------------------- */

void plant_set_defaults(ModelData *m)
{
    component_set_defaults(m);
}

PlantStatus plant_initialize(ModelData *m, PlantMessage *msg)
{
    if (check_parameters(m, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    m->parameters_changed = 0;
    m->initialized = 1;
    return PLANT_OK;
}

PlantStatus plant_do_step(ModelData *m, double step_s, PlantMessage *msg)
{
    if (component_check_step(m, step_s, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    if (m->parameters_changed) { /* the knots are fixed: set before initialisation only */
        if (check_parameters(m, msg) != PLANT_OK) {
            return PLANT_ERROR;
        }
        m->parameters_changed = 0;
    }
    m->time_s += step_s;
    return PLANT_OK;
}

PlantStatus plant_output(const ModelData *m, unsigned vr, double *value, PlantMessage *msg)
{
    int s;
    for (s = 0; s < GT_N_SIGNALS; s++) {
        const Signal *sig = &signals[s];
        if (sig->output == vr) {
            *value = gt_signal_value(m->time_s, &m->real[sig->first_time],
                                     &m->real[sig->first_value], sig->count, m->real[sig->linear],
                                     GT_SIGNAL_TIME_TOL_S);
            return PLANT_OK;
        }
    }
    plant_message(msg, "%s is not an output", plant_variables[vr].name);
    return PLANT_ERROR;
}

/* --- restored states --------------------------------------------------------------------- */

PlantStatus plant_check_state(const ModelData *m, int initialized, PlantMessage *msg)
{
    const int flags[2] = {m->initialized, m->parameters_changed};
    if (component_check_flags(flags, 2, m->initialized, initialized, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    if (!(fabs(m->time_s) <= GT_MAX_TIME_S)) {
        plant_message(msg, "state time %g s is not finite or beyond %g s", m->time_s,
                      GT_MAX_TIME_S);
        return PLANT_ERROR;
    }
    if (component_check_reals(m->real, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    if (m->initialized && m->parameters_changed) {
        /* the knots are fixed: nothing sets them once initialisation has ended */
        plant_message(msg, "state says its fixed parameters changed after initialisation");
        return PLANT_ERROR;
    }
    if (!m->parameters_changed && check_parameters(m, msg) != PLANT_OK) {
        return PLANT_ERROR;
    }
    return PLANT_OK;
}
