/* The plant seen by the FMI glue: one scheduled FOPDT or ARX gauge model.
 *
 * The glue (fmi2_glue.c) knows only this interface. Everything that differs per model comes
 * from the generated model_config.h (value references, sizes, start values, the family's
 * dynamics header) and from the family file (model_fopdt.c or model_arx.c).
 *
 * Semantics follow gatetwin.plant.simulate.PlantSimulator operation by operation.
 */
#ifndef GATETWIN_PLANT_H
#define GATETWIN_PLANT_H

#include <stddef.h>

#include "model_config.h"
#include GT_DYNAMICS_HEADER /* DynamicsState of the family: model_fopdt.h or model_arx.h */
#include "effects.h"        /* EffectState */

typedef enum { PLANT_OK = 0, PLANT_WARNING = 1, PLANT_ERROR = 2 } PlantStatus;

/* Why a call returned PLANT_WARNING or PLANT_ERROR; the glue logs it. */
typedef struct {
    char text[512];
} PlantMessage;

typedef enum { GT_KIND_INPUT, GT_KIND_OUTPUT, GT_KIND_TUNABLE, GT_KIND_FIXED } VariableKind;

/* One Real variable of the model description (the table is generated, see plant.c). */
typedef struct {
    const char *name;
    VariableKind kind;
    double start;
} PlantVariable;

extern const PlantVariable plant_variables[GT_N_REAL];

/* Everything an FMU state holds. Fixed size and pointer-free: copied and serialised as bytes. */
typedef struct {
    double time_s;            /* time of the state, s */
    double real[GT_N_REAL];   /* every Real variable, indexed by value reference */
    double flow_in_force_m3h; /* discharge of the last step: selects level_ref for the output */
    int initialized;          /* plant_initialize succeeded */
    int warned_flow_range;    /* the out-of-range discharge warning was given */
    int parameters_changed;   /* parameters were set since they were last checked */
    DynamicsState dyn;        /* the family's state; dyn.x is the deviation from level_ref, mm */
    EffectState fx;           /* the effect blocks' state */
} ModelData;

/* Where a discharge falls among the schedule knots (shared by every column). */
typedef struct {
    int index;     /* left knot of the segment, or the clamped end knot */
    double weight; /* position inside the segment, 0..1 */
    int clamped;   /* 1: at or beyond an end knot (or a single knot), use column[index] */
} KnotPosition;

KnotPosition plant_locate(const ModelData *m, double flow_m3h);
double plant_interp(const KnotPosition *at, const double *column);
void plant_message(PlantMessage *msg, const char *format, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

/* Called by the glue. */
void plant_set_defaults(ModelData *m);
PlantStatus plant_initialize(ModelData *m, PlantMessage *msg);
PlantStatus plant_do_step(ModelData *m, double step_s, PlantMessage *msg);
PlantStatus plant_output(const ModelData *m, double *level_mm, PlantMessage *msg);

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

/* Implemented in effects.c (identity or no-op for the blocks a model does not carry). */
PlantStatus effects_check_parameters(const ModelData *m, PlantMessage *msg);
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
