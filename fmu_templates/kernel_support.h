/* Control flow around the generated physical kernel (physical_kernel.c), shared by the
 * physical family and the envelope FOPDT: the steady point (kernel_point.h) and
 * PhysicalPlant's parameter checks. */
#ifndef GATETWIN_KERNEL_SUPPORT_H
#define GATETWIN_KERNEL_SUPPORT_H

#include "kernel_point.h"
#include "plant.h"

/* Every parameter that must be positive is (the glue has checked they are finite). */
PlantStatus kernel_check_parameters(const ModelData *m, PlantMessage *msg);

#endif
