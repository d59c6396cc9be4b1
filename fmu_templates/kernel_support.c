/* See kernel_support.h. */
#include "kernel_support.h"

#include "physical_kernel.h"

static const int bounded_parameters[] = {GT_KERNEL_BOUNDED};
static const double lower_bounds[] = {GT_KERNEL_LOWER_BOUNDS};

PlantStatus kernel_check_parameters(const ModelData *m, PlantMessage *msg)
{
    size_t i;
    double room;
    for (i = 0; i < sizeof bounded_parameters / sizeof bounded_parameters[0]; i++) {
        const int vr = bounded_parameters[i];
        if (!(m->real[vr] > lower_bounds[i])) {
            plant_message(msg, "parameter %s = %.17g must be > %.17g", plant_variables[vr].name,
                          m->real[vr], lower_bounds[i]);
            return PLANT_ERROR;
        }
    }
    gt_storage_room_m2(&m->real[VR_KERNEL_FIRST], &room);
    if (!(room > 0.0)) {
        plant_message(msg, "the storage area " GT_KERNEL_STORAGE_RULE);
        return PLANT_ERROR;
    }
    return PLANT_OK;
}
