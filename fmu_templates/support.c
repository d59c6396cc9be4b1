/* What every part of the plant uses and nothing in it calls back: the schedule lookup
 * (mirrors gatetwin.plant.model.interp_clamped operation by operation);
 * the variable table and the message formatter are in component.c. plant.c orchestrates; the
 * families (model_*.c), the effect blocks (effects.c) and the kernel support call only down
 * into this file, component.c and the generated code, so the translation units form no call
 * circle.
 */
#include "plant.h"

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

PlantStatus plant_check_flag(int flag, const char *what, PlantMessage *msg)
{
    if (flag != 0 && flag != 1) {
        plant_message(msg, "state's %s flag is %d, not 0 or 1", what, flag);
        return PLANT_ERROR;
    }
    return PLANT_OK;
}
