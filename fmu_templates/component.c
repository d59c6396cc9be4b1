/* What every component (component.h) shares: the variable table, generated into
 * model_config.h as GT_VARIABLES, and the message formatter. Nothing in it calls back.
 */
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
