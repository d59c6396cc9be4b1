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
    if (GT_VALIDITY_LEVEL && GT_VALIDITY_FLOW) {
        const double levels[2] = {GT_VALIDITY_LEVEL_MIN, GT_VALIDITY_LEVEL_MAX};
        const double flows[2] = {GT_VALIDITY_FLOW_MIN, GT_VALIDITY_FLOW_MAX};
        for (i = 0; i < 4; i++) {
            gt_operating_room_m2(levels[i / 2], flows[i % 2], &m->real[VR_KERNEL_FIRST], &room);
            if (!(room > 0.0)) {
                plant_message(msg, "the storage area at level %.17g mm and %.17g m3/h: "
                              GT_KERNEL_OPERATING_STORAGE_RULE, levels[i / 2], flows[i % 2]);
                return PLANT_ERROR;
            }
        }
    }
    return PLANT_OK;
}
