/* ModelData of a plant FMU (the component of component.h): every Real variable, the
 * family's dynamics state and the effect blocks' state.
 */
#ifndef GATETWIN_PLANT_DATA_H
#define GATETWIN_PLANT_DATA_H

#include "model_config.h"
#include GT_DYNAMICS_HEADER /* DynamicsState of the family: model_fopdt.h or model_arx.h */
#include "effects.h"        /* EffectState */

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
    DynamicsState dyn;        /* the family's state; dyn.x is the deviation from level_ref, mm */
    EffectState fx;           /* the effect blocks' state */
} ModelData;

#endif
