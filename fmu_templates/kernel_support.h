/* Control flow around the generated physical kernel (physical_kernel.c), shared by the
 * physical family and the envelope FOPDT; mirrors gatetwin.plant.model.steady_depth_m and
 * envelope_point, and PhysicalPlant's parameter checks. */
#ifndef GATETWIN_KERNEL_SUPPORT_H
#define GATETWIN_KERNEL_SUPPORT_H

#include "plant.h"

/* Every parameter that must be positive is (the glue has checked they are finite). */
PlantStatus kernel_check_parameters(const ModelData *m, PlantMessage *msg);
/* The steady depth at the gate (m): the kernel's bisection, its fixed number of steps. */
double kernel_steady_depth_m(const double *p, double opening_mm, double flow_m3h);
/* Steady level at the gauge (mm) and small-signal time constant (s) at (Q, e). */
void kernel_envelope_point(const double *p, double opening_mm, double flow_m3h,
                           double *level_mm, double *time_constant_s);

#endif
