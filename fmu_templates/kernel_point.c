/* See kernel_point.h. */
#include "kernel_point.h"

#include "physical_kernel.h"

double kernel_steady_depth_m(const double *p, double opening_mm, double flow_m3h)
{
    double low = GT_DEPTH_LOW_M, high = p[GT_DEPTH_MAX_INDEX];
    int i;
    for (i = 0; i < GT_BISECTION_STEPS; i++) {
        gt_bisection_step(low, high, opening_mm, flow_m3h, p, &low, &high);
    }
    return 0.5 * (low + high);
}

double kernel_tail_steady_depth_m(const double *p, double tail_m, double opening_mm,
                                  double flow_m3h)
{
    double low = GT_DEPTH_LOW_M, high = p[GT_DEPTH_MAX_INDEX];
    int i;
    for (i = 0; i < GT_BISECTION_STEPS; i++) {
        gt_tail_bisection_step(low, high, tail_m, opening_mm, flow_m3h, p, &low, &high);
    }
    return 0.5 * (low + high);
}

void kernel_envelope_steady(const double *p, double opening_mm, double flow_m3h,
                            double *level_mm, double *time_constant_s, double *depth_m)
{
    const double depth = kernel_steady_depth_m(p, opening_mm, flow_m3h);
    gt_level_mm(depth, opening_mm, flow_m3h, p, level_mm);
    gt_time_constant_s(depth, opening_mm, flow_m3h, p, time_constant_s);
    *depth_m = depth;
}

void kernel_envelope_point(const double *p, double opening_mm, double flow_m3h,
                           double *level_mm, double *time_constant_s)
{
    double depth;
    kernel_envelope_steady(p, opening_mm, flow_m3h, level_mm, time_constant_s, &depth);
}
