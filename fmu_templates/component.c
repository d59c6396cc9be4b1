/* What every component (component.h) shares: the variable table, generated into
 * model_config.h as GT_VARIABLES, the message formatter and the range check of the
 * parameters. Nothing in it calls back.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>

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
