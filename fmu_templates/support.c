/* What every part of the C FMU uses and nothing in it calls back: the variable table, the
 * message formatter and the schedule lookup (mirrors gatetwin.plant.model.interp_clamped
 * operation by operation). plant.c orchestrates; the families (model_*.c), the effect blocks
 * (effects.c) and the kernel support call only down into this file and the generated code, so
 * the translation units form no call circle.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "plant.h"

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

/* --- schedule: piecewise-linear in the discharge, clamped outside the knots ---------------- */

KnotPosition plant_locate(const ModelData *m, double flow_m3h)
{
    const double *knots = &m->real[VR_COL_FLOW_M3H];
    KnotPosition at = {0, 0.0, 1};
    if (GT_N_KNOTS == 1 || flow_m3h <= knots[0]) {
        return at;
    }
    if (flow_m3h >= knots[GT_N_KNOTS - 1]) {
        at.index = GT_N_KNOTS - 1;
        return at;
    }
    while (flow_m3h > knots[at.index + 1]) {
        at.index++;
    }
    at.weight = (flow_m3h - knots[at.index]) / (knots[at.index + 1] - knots[at.index]);
    at.clamped = 0;
    return at;
}

double plant_interp(const KnotPosition *at, const double *column)
{
    if (at->clamped) {
        return column[at->index];
    }
    return column[at->index] + at->weight * (column[at->index + 1] - column[at->index]);
}

/* --- checks ---------------------------------------------------------------------------------- */
