/* ModelData of a plant FMU (the component of component.h): every Real variable, the
 * family's dynamics state, the effect blocks' state and the step cache.
 */
#ifndef GATETWIN_PLANT_DATA_H
#define GATETWIN_PLANT_DATA_H

#include "model_config.h"
#include GT_DYNAMICS_HEADER /* DynamicsState and DynamicsCache of the family (model_*.h) */
#include "effects.h"        /* EffectState */

/* Where a discharge falls among the schedule knots (shared by every column). */
typedef struct {
    int index;     /* left knot of the segment, or the clamped end knot */
    double weight; /* position inside the segment, 0..1 */
    int clamped;   /* 1: at or beyond an end knot (or a single knot), use column[index] */
} KnotPosition;

/* What a step derives from its discharge and the parameters alone (the knot position, the
 * family's scheduled parameters, an envelope's steady point), kept for the steps after it:
 * derived anew when the discharge differs, bit for bit, from the one it holds for, and dropped
 * whenever a parameter changes (plant.c). Every value in it is what a recomputation gives, so
 * the outputs are the same bits as without it; a restored state's cache is recomputed and
 * compared (plant_check_state). */
typedef struct {
    int valid;         /* 1: the fields below hold for flow_m3h and the parameters in force */
    double flow_m3h;   /* the discharge they were derived at, m3/h */
    KnotPosition at;   /* where flow_m3h falls among the knots */
    DynamicsCache dyn; /* the family's share (model_*.h) */
} StepCache;

/* Everything an FMU state holds. Fixed size and pointer-free: copied and serialised as bytes. */
typedef struct {
    double time_s;            /* time of the state, s */
    double real[GT_N_REAL];   /* every Real variable, indexed by value reference */
    double flow_in_force_m3h; /* discharge of the last step: selects level_ref for the output */
    double output_mm;         /* the output after initialisation or the last step, served
                                 by getReal until a parameter changes */
    int initialized;          /* plant_initialize succeeded */
    int warned_validity;      /* the validity warning (envelope or schedule range) was given */
    int parameters_changed;   /* parameters were set since they were last checked */
    StepCache cache;          /* derived from the inputs and parameters alone (plant.c) */
    DynamicsState dyn;        /* the family's state; dyn.x is the deviation from level_ref, mm */
    EffectState fx;           /* the effect blocks' state */
} ModelData;

#endif
