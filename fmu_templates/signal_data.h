/* ModelData of a scenario FMU (the component of component.h, signal_source.c): every Real
 * variable and the time. The signals' layout is model_config.h's GT_SIGNALS table.
 */
#ifndef GATETWIN_SIGNAL_DATA_H
#define GATETWIN_SIGNAL_DATA_H

#include "model_config.h"

/* Everything an FMU state holds. Fixed size and pointer-free: copied and serialised as bytes. */
typedef struct {
    double time_s;          /* time of the state, s */
    double real[GT_N_REAL]; /* every Real variable, indexed by value reference */
    int initialized;        /* plant_initialize succeeded */
    int parameters_changed; /* parameters were set since they were last checked */
} ModelData;

#endif
