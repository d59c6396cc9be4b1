/* See kernel_support.h. */
#include "kernel_support.h"

#include "physical_kernel.h"

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

double kernel_steady_depth_m(const double *p, double opening_mm, double flow_m3h)
{
    double low = GT_DEPTH_LOW_M, high = GT_DEPTH_HIGH_M;
    int i;
    for (i = 0; i < GT_BISECTION_STEPS; i++) {
        gt_bisection_step(low, high, opening_mm, flow_m3h, p, &low, &high);
    }
    return 0.5 * (low + high);
}

void kernel_envelope_point(const double *p, double opening_mm, double flow_m3h,
                           double *level_mm, double *time_constant_s)
{
    const double depth = kernel_steady_depth_m(p, opening_mm, flow_m3h);
    gt_level_mm(depth, opening_mm, flow_m3h, p, level_mm);
    gt_time_constant_s(depth, opening_mm, flow_m3h, p, time_constant_s);
}
