/* What every component (component.h) shares: the variable table, generated into
 * model_config.h as GT_VARIABLES, the message formatter, the range check of the
 * parameters and the first checks of a restored state. Nothing in it calls back.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "component.h"

#define GT_VARIABLE_ENTRY(name, kind, start) {name, kind, start},
const PlantVariable plant_variables[GT_N_REAL] = {GT_VARIABLES(GT_VARIABLE_ENTRY)};
#undef GT_VARIABLE_ENTRY

void component_set_defaults(ModelData *m)
{
    int vr;
    memset(m, 0, sizeof *m);
    for (vr = 0; vr < GT_N_REAL; vr++) {
        m->real[vr] = plant_variables[vr].start;
    }
    m->parameters_changed = 1;
}

PlantStatus component_check_step(const ModelData *m, double step_s, PlantMessage *msg)
{
    if (!(step_s > 0.0 && step_s <= GT_MAX_COMMUNICATION_STEP_S)) {
        plant_message(msg, "communication step %.17g s must be > 0 and at most %g s (the limit)",
                      step_s, GT_MAX_COMMUNICATION_STEP_S);
        return PLANT_ERROR;
    }
    if (!(fabs(m->time_s + step_s) <= GT_MAX_TIME_S)) {
        plant_message(msg, "communication step to t = %.17g s passes the time limit %g s",
                      m->time_s + step_s, GT_MAX_TIME_S);
        return PLANT_ERROR;
    }
    return PLANT_OK;
}

void plant_message(PlantMessage *msg, const char *format, ...)
{
    va_list args;
    va_start(args, format);
    vsnprintf(msg->text, sizeof msg->text, format, args);
    va_end(args);
}

PlantStatus plant_check_parameter_values(const double *real, PlantMessage *msg)
{
    int vr;
    for (vr = 0; vr < GT_N_REAL; vr++) {
        const VariableKind kind = plant_variables[vr].kind;
        if ((kind == GT_KIND_TUNABLE || kind == GT_KIND_FIXED) &&
            !(fabs(real[vr]) <= GT_PARAMETER_MAX_ABS)) {
            plant_message(msg, "parameter %s = %.17g must be finite with |value| <= %g",
                          plant_variables[vr].name, real[vr], GT_PARAMETER_MAX_ABS);
            return PLANT_ERROR;
        }
    }
    return PLANT_OK;
}

PlantStatus component_check_reals(const double *real, PlantMessage *msg)
{
    int vr;
    for (vr = 0; vr < GT_N_REAL; vr++) {
        if (!isfinite(real[vr])) {
            plant_message(msg, "state value of %s = %g is not finite", plant_variables[vr].name,
                          real[vr]);
            return PLANT_ERROR;
        }
    }
    return PLANT_OK;
}

PlantStatus component_check_flags(const int *flags, int n_flags, int state_initialized,
                                  int initialized, PlantMessage *msg)
{
    int i;
    for (i = 0; i < n_flags; i++) {
        if (flags[i] != 0 && flags[i] != 1) {
            plant_message(msg, "state flag %d is %d, not 0 or 1", i, flags[i]);
            return PLANT_ERROR;
        }
    }
    if (state_initialized != initialized) {
        plant_message(msg, "state says initialised = %d, its mode needs %d", state_initialized,
                      initialized);
        return PLANT_ERROR;
    }
    return PLANT_OK;
}
