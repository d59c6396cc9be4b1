/* See kernel_point.h. */
#include "kernel_point.h"

#include "physical_kernel.h"

double kernel_steady_depth_m(const double *p, double opening_mm, double flow_m3h)
{
    double tail_m;
    gt_tail_steady_m(flow_m3h, p, &tail_m);
    return kernel_tail_steady_depth_m(p, tail_m, opening_mm, flow_m3h);
}

/* held_steady_depth_m of gatetwin.plant.physical_kernel: Cd's curve at the discharge once,
 * then the halvings */
double kernel_tail_steady_depth_m(const double *p, double tail_m, double opening_mm,
                                  double flow_m3h)
{
    double low = GT_DEPTH_LOW_M, high = p[GT_DEPTH_MAX_INDEX], law[5];
    int i;
    gt_cd_law(flow_m3h, p, &law[0], &law[1], &law[2], &law[3], &law[4]);
    for (i = 0; i < GT_BISECTION_STEPS; i++) {
        gt_law_bisection_step(low, high, tail_m, opening_mm, flow_m3h, law[0], law[1], law[2],
                              law[3], law[4], p, &low, &high);
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
