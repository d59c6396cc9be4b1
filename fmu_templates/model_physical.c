/* Physical dynamics: the steps of gatetwin.plant.physical.PhysicalSimulator around the kernel
 * generated into physical_kernel.c (gatetwin.plant.physical_kernel): the steady depth by the
 * kernel's solve (kernel_point.c), then equal sub-steps of at most max_substep_s per communication
 * step. The parameters are the Real variables from VR_KERNEL_FIRST on, in kernel order. A seiche
 * block (effects.c) is driven over each sub-step by the gate position at its start.
 */
#include <math.h>

#include "kernel_support.h"
#include "physical_kernel.h"
#include "plant.h"

#define PHYSICAL(m) (&(m)->real[VR_KERNEL_FIRST])

PlantStatus dynamics_check_parameters(const ModelData *m, PlantMessage *msg)
{
    return kernel_check_parameters(m, msg);
}

static double steady_depth_m(const ModelData *m, double gate_mm, double flow_m3h)
{
    return kernel_steady_depth_m(PHYSICAL(m), gate_mm, flow_m3h);
}

static double actuator_target(const ModelData *m, double command_mm)
{
    double target;
    gt_actuator_target_mm(command_mm, PHYSICAL(m), &target);
    return target;
}

PlantStatus dynamics_equilibrium(const ModelData *m, double u_mm, const KnotPosition *at,
                                 double *x0_mm, PlantMessage *msg)
{
    const double flow_m3h = m->real[VR_FLOW_M3H];
    const double gate = actuator_target(m, u_mm);
    (void)at;
    (void)msg;
    gt_level_mm(steady_depth_m(m, gate, flow_m3h), gate, flow_m3h, PHYSICAL(m), x0_mm);
    return PLANT_OK;
}

void dynamics_initialize(ModelData *m, double u_mm, double x0_mm)
{
    m->dyn.gate_mm = actuator_target(m, u_mm);
    m->dyn.depth_m = steady_depth_m(m, m->dyn.gate_mm, m->real[VR_FLOW_M3H]);
    gt_tail_steady_m(m->real[VR_FLOW_M3H], PHYSICAL(m), &m->dyn.tail_m);
    m->dyn.x = x0_mm;
}

PlantStatus dynamics_check_step(const ModelData *m, double step_s, double command_mm,
                                PlantMessage *msg)
{
    double n;
    (void)command_mm;
    gt_substep_count(step_s, PHYSICAL(m), &n);
    if (!(n <= GT_PHYSICAL_MAX_SUBSTEPS)) {
        plant_message(msg,
                      "communication step %.17g s needs %.0f sub-steps of at most %.17g s; "
                      "the limit is %d",
                      step_s, n, m->real[VR_KERNEL_FIRST + GT_PHYSICAL_MAX_SUBSTEP_INDEX],
                      GT_PHYSICAL_MAX_SUBSTEPS);
        return PLANT_ERROR;
    }
    return PLANT_OK;
}

void dynamics_derive(const ModelData *m, double flow_m3h, const KnotPosition *at,
                     DynamicsCache *c)
{
    (void)m;
    (void)flow_m3h;
    (void)at;
    c->none = 0;
}

void dynamics_step(ModelData *m, double step_s, double command_mm)
{
    const double flow_m3h = m->real[VR_FLOW_M3H];
    const double target = actuator_target(m, command_mm);
    double n, dt;
    long i;
    gt_substep_count(step_s, PHYSICAL(m), &n);
    dt = step_s / n;
    for (i = 0; i < (long)n; i++) {
        const double gate_mm = m->dyn.gate_mm; /* drives the seiche over the sub-step */
        gt_substep(m->dyn.depth_m, m->dyn.tail_m, m->dyn.gate_mm, target, flow_m3h, dt,
                   PHYSICAL(m), &m->dyn.depth_m, &m->dyn.tail_m, &m->dyn.gate_mm);
        effects_seiche_piece(m, dt, gate_mm);
    }
    gt_level_mm(m->dyn.depth_m, m->dyn.gate_mm, flow_m3h, PHYSICAL(m), &m->dyn.x);
}

/* A restored state: every value finite. */
PlantStatus dynamics_check_state(const ModelData *m, PlantMessage *msg)
{
    const DynamicsState *d = &m->dyn;
    if (!(isfinite(d->x) && isfinite(d->depth_m) && isfinite(d->tail_m) &&
          isfinite(d->gate_mm))) {
        plant_message(msg,
                      "physical state (level %g mm, depth %g m, tail %g m, gate %g mm) is not "
                      "finite",
                      d->x, d->depth_m, d->tail_m, d->gate_mm);
        return PLANT_ERROR;
    }
    return PLANT_OK;
}

/* A restored cache: nothing derived, so nothing but its placeholder to check. */
PlantStatus dynamics_check_cache(const ModelData *m, PlantMessage *msg)
{
    if (m->cache.dyn.none != 0) {
        plant_message(msg, "state's step cache placeholder is %d, not 0", m->cache.dyn.none);
        return PLANT_ERROR;
    }
    return PLANT_OK;
}
