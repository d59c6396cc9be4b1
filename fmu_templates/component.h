/* What the FMI glue (fmi2_glue.c, fmi3_glue.c) sees of the component an FMU carries: a
 * table of Real variables, one fixed-size pointer-free ModelData (copied and serialised as
 * bytes by the FMU-state functions) and five verbs. The component is a plant (plant.h,
 * plant.c) or a controller (controller_data.h, controller_pi.c); the generated model_config.h
 * names the header that defines its ModelData (GT_COMPONENT_HEADER), which holds at least
 * `time_s`, `real[GT_N_REAL]` and `parameters_changed`. component.c holds the variable table
 * and the message formatter every component shares.
 */
#ifndef GATETWIN_COMPONENT_H
#define GATETWIN_COMPONENT_H

#include <stddef.h>

#include "model_config.h"

typedef enum { PLANT_OK = 0, PLANT_WARNING = 1, PLANT_ERROR = 2 } PlantStatus;

/* Why a call returned PLANT_WARNING or PLANT_ERROR; the glue logs it. */
typedef struct {
    char text[512];
} PlantMessage;

typedef enum { GT_KIND_INPUT, GT_KIND_OUTPUT, GT_KIND_TUNABLE, GT_KIND_FIXED } VariableKind;

/* One Real variable of the model description (the table is generated, see component.c). */
typedef struct {
    const char *name;
    VariableKind kind;
    double start;
} PlantVariable;

extern const PlantVariable plant_variables[GT_N_REAL];

void plant_message(PlantMessage *msg, const char *format, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

/* Every tunable and fixed parameter in `real` (indexed by value reference) finite and within
 * GT_PARAMETER_MAX_ABS; else PLANT_ERROR naming the first that is not. */
PlantStatus plant_check_parameter_values(const double *real, PlantMessage *msg);
/* A restored state's first checks: each of its n_flags flags is 0 or 1, and the state's
 * `initialized` flag (state_initialized) is the one the instance's mode needs. */
PlantStatus component_check_flags(const int *flags, int n_flags, int state_initialized,
                                  int initialized, PlantMessage *msg);
/* A restored state's Real variables: every value in `real` (indexed by value reference)
 * finite; else PLANT_ERROR naming the first that is not. */
PlantStatus component_check_reals(const double *real, PlantMessage *msg);

#include GT_COMPONENT_HEADER /* ModelData */

/* ModelData zeroed, every Real variable at its start value, the parameters to be checked:
 * what each component's plant_set_defaults starts from. */
void component_set_defaults(ModelData *m);
/* A communication step of step_s from m->time_s: > 0, at most GT_MAX_COMMUNICATION_STEP_S and
 * ending within GT_MAX_TIME_S; else PLANT_ERROR saying which. */
PlantStatus component_check_step(const ModelData *m, double step_s, PlantMessage *msg);

/* Called by the glue. */
void plant_set_defaults(ModelData *m);
PlantStatus plant_initialize(ModelData *m, PlantMessage *msg);
PlantStatus plant_do_step(ModelData *m, double step_s, PlantMessage *msg);
/* The value of output variable `vr` (before initialisation: the value at rest). */
PlantStatus plant_output(const ModelData *m, unsigned vr, double *value, PlantMessage *msg);
/* Whether m can be restored: every double finite, every index and count in range, flags 0 or
 * 1, initialised exactly when `initialized` says, checked parameters still valid. */
PlantStatus plant_check_state(const ModelData *m, int initialized, PlantMessage *msg);

#endif
