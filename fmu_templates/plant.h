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

#include "component.h" /* the glue-facing part, and ModelData (plant_data.h) */

/* Where a discharge falls among the schedule knots (shared by every column). */
typedef struct {
    int index;     /* left knot of the segment, or the clamped end knot */
    double weight; /* position inside the segment, 0..1 */
    int clamped;   /* 1: at or beyond an end knot (or a single knot), use column[index] */
} KnotPosition;

KnotPosition plant_locate(const ModelData *m, double flow_m3h);
double plant_interp(const KnotPosition *at, const double *column);

/* Implemented once per family (model_fopdt.c, model_arx.c); called by plant.c only.
 * dynamics_check_step and dynamics_step get the commanded opening: the family runs the input
 * blocks over its own pieces of the step (see effects.c). */
PlantStatus dynamics_check_parameters(const ModelData *m, PlantMessage *msg);
PlantStatus dynamics_equilibrium(const ModelData *m, double u_mm, const KnotPosition *at,
                                 double *x0_mm, PlantMessage *msg);
void dynamics_initialize(ModelData *m, double u_mm, double x0_mm);
PlantStatus dynamics_check_step(const ModelData *m, double step_s, double command_mm,
                                PlantMessage *msg);
void dynamics_step(ModelData *m, double step_s, double command_mm, const KnotPosition *at);
/* The family's state of a restored FMU state: finite, indices and counts in range. */
PlantStatus dynamics_check_state(const ModelData *m, PlantMessage *msg);

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
