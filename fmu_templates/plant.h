/* The plant seen by the FMI glue: one scheduled FOPDT or ARX gauge model.
 *
 * The glue (fmi2_glue.c) knows only its component.h part. Everything that differs per model comes
 * from the generated model_config.h (value references, sizes, start values, the family's
 * dynamics header) and from the family file (model_fopdt.c or model_arx.c).
 *
 * Semantics follow gatetwin.plant.simulate.PlantSimulator operation by operation.
 */
#ifndef GATETWIN_PLANT_H
#define GATETWIN_PLANT_H

#include <string.h>

#include "component.h" /* the glue-facing part, and ModelData (plant_data.h) */

/* KnotPosition and StepCache are in plant_data.h (ModelData holds them). */
KnotPosition plant_locate(const ModelData *m, double flow_m3h);
double plant_interp(const KnotPosition *at, const double *column);

/* Whether two doubles are the same bits: how a cache's key is matched (0.0 and -0.0 differ). */
static inline int plant_same_bits(double a, double b)
{
    return memcmp(&a, &b, sizeof a) == 0;
}

/* PLANT_OK when a restored state's cache flag `what` is 0 or 1; otherwise an error naming it. */
PlantStatus plant_check_flag(int flag, const char *what, PlantMessage *msg);

/* Implemented once per family (model_fopdt.c, model_arx.c, model_physical.c); called by
 * plant.c only. dynamics_check_step and dynamics_step get the commanded opening: the family
 * runs the input blocks over its own pieces of the step (see effects.c); dynamics_step takes
 * its scheduled parameters from m->cache, which plant.c has derived for the step's discharge. */
PlantStatus dynamics_check_parameters(const ModelData *m, PlantMessage *msg);
PlantStatus dynamics_equilibrium(const ModelData *m, double u_mm, const KnotPosition *at,
                                 double *x0_mm, PlantMessage *msg);
void dynamics_initialize(ModelData *m, double u_mm, double x0_mm);
PlantStatus dynamics_check_step(const ModelData *m, double step_s, double command_mm,
                                PlantMessage *msg);
void dynamics_step(ModelData *m, double step_s, double command_mm);
/* The family's share of the step cache at the discharge flow_m3h, which `at` locates (an
 * envelope's steady point is dropped: it is derived when a step first needs it). */
void dynamics_derive(const ModelData *m, double flow_m3h, const KnotPosition *at,
                     DynamicsCache *c);
/* The family's state of a restored FMU state: finite, indices and counts in range. */
PlantStatus dynamics_check_state(const ModelData *m, PlantMessage *msg);
/* A restored cache's family share (m->cache.dyn, its discharge and knot position already
 * checked) is what dynamics_derive and the steady point give, bit for bit. */
PlantStatus dynamics_check_cache(const ModelData *m, PlantMessage *msg);

/* Implemented in effects.c (identity or no-op for the blocks a model does not carry). */
PlantStatus effects_check_parameters(const ModelData *m, PlantMessage *msg);
PlantStatus effects_check_state(const ModelData *m, PlantMessage *msg);
double effects_input(const ModelData *m, double gate_mm);
void effects_actuate(const ModelData *m, EffectState *fx, double command_mm, double duration_s);
void effects_fopdt_parameters(const ModelData *m, double flow_m3h, double *gain,
                              double *time_constant_s);
void effects_initialize(ModelData *m, double opening_mm, double flow_m3h, double level_mm);
void effects_seiche_piece(ModelData *m, double duration_s, double gate_mm);
void effects_lag_interval(ModelData *m, double level_target_mm, double level_excess_mm,
                          double duration_s, double level_time_constant_s);
void effects_lag_sample(ModelData *m, double level_mm, double duration_s);
void effects_step_end(ModelData *m, double step_s, double flow_m3h);
double effects_output(const ModelData *m, double level_mm);
double effects_output_at_rest(const ModelData *m, double level_mm, double flow_m3h);

#endif
