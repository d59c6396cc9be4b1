/* See kernel_support.h. */
#include "kernel_support.h"

static const int positive_parameters[] = {GT_KERNEL_POSITIVE};

PlantStatus kernel_check_parameters(const ModelData *m, PlantMessage *msg)
{
    size_t i;
    for (i = 0; i < sizeof positive_parameters / sizeof positive_parameters[0]; i++) {
        const int vr = positive_parameters[i];
        if (!(m->real[vr] > 0.0)) {
            plant_message(msg, "parameter %s = %.17g must be > 0", plant_variables[vr].name,
                          m->real[vr]);
            return PLANT_ERROR;
        }
    }
    return PLANT_OK;
}
