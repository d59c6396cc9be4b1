/* See kernel_point.h. */
#include "kernel_point.h"

#include <math.h>

#include "physical_kernel.h"

double kernel_steady_depth_m(const double *p, double opening_mm, double flow_m3h)
{
    double tail_m;
    gt_tail_steady_m(flow_m3h, p, &tail_m);
    return kernel_tail_steady_depth_m(p, tail_m, opening_mm, flow_m3h);
}

/* held_steady_depth_m of gatetwin.plant.physical_kernel: Cd's curve at the discharge once,
 * then its steps from its start until a step is within the tolerance (or NaN) */
double kernel_tail_steady_depth_m(const double *p, double tail_m, double opening_mm,
                                  double flow_m3h)
{
    double low = GT_DEPTH_LOW_M, high = p[GT_DEPTH_MAX_INDEX], law[5], depth, step, tolerance;
    int i;
    gt_cd_law(flow_m3h, p, &law[0], &law[1], &law[2], &law[3], &law[4]);
    tolerance = (high - low) * ldexp(1.0, -GT_BISECTION_STEPS);
    step = high - low;
    gt_steady_depth_start_m(tail_m, opening_mm, flow_m3h, law[0], p, &depth);
    for (i = 0; i < GT_STEADY_MAX_STEPS; i++) {
        gt_law_newton_step(low, high, depth, step, tail_m, opening_mm, flow_m3h, law[0], law[1],
                           law[2], law[3], law[4], p, &low, &high, &depth, &step);
        if (!(step > tolerance || -step > tolerance)) {
            break;
        }
    }
    return depth;
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
