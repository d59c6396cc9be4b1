/* The steady point of the generated physical kernel (physical_kernel.c): the control flow of
 * gatetwin.plant.model.steady_depth_m and envelope_point around the kernel's Newton step,
 * level and time constant. Needs nothing but the kernel, so every component that renders an
 * envelope (the plants, the envelope observer) compiles it as it is. */
#ifndef GATETWIN_KERNEL_POINT_H
#define GATETWIN_KERNEL_POINT_H

/* The steady depth at the gate (m): held_steady_depth_m's loop on the kernel's Newton step. */
double kernel_steady_depth_m(const double *p, double opening_mm, double flow_m3h);
/* The same with the pool below the gate held at tail_m (m). */
double kernel_tail_steady_depth_m(const double *p, double tail_m, double opening_mm,
                                  double flow_m3h);
/* Steady level at the gauge (mm) and small-signal time constant (s) at (Q, e). */
void kernel_envelope_point(const double *p, double opening_mm, double flow_m3h,
                           double *level_mm, double *time_constant_s);
/* The same and the steady depth at the gate (m), which the secant time constant needs. */
void kernel_envelope_steady(const double *p, double opening_mm, double flow_m3h,
                            double *level_mm, double *time_constant_s, double *depth_m);

#endif
