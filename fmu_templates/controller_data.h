/* ModelData of a controller FMU (the component of component.h): every Real variable and the
 * PI's state. The names are those of gatetwin.mpc.pi.PiController.
 */
#ifndef GATETWIN_CONTROLLER_DATA_H
#define GATETWIN_CONTROLLER_DATA_H

#include "model_config.h"

/* Everything an FMU state holds. Fixed size and pointer-free: copied and serialised as bytes. */
typedef struct {
    double time_s;              /* time of the state, s */
    double real[GT_N_REAL];     /* every Real variable, indexed by value reference */
    double integral_mm;         /* the PI's integral term, mm */
    double previous_opening_mm; /* the opening of the last sample: the output, mm */
    double filtered_mm;         /* the level through the measurement filter, mm */
    int initialized;            /* plant_initialize succeeded */
    int parameters_changed;     /* parameters were set since they were last checked */
} ModelData;

#endif
