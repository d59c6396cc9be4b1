/* Where a gatetwin C FMU's component keeps its ints: the SPEC lines of tests/fmu_fuzz.c that
 * the modelDescription cannot give.
 *
 * Compiled against an FMU's sources/ (-I): component.h brings the generated model_config.h
 * and the component's ModelData, whatever the component. Prints `data_size` (sizeof
 * ModelData) and one `int_field NAME OFFSET` per int the component's state checks must guard:
 * `parameters_changed` (every component, component.h), and the fields of the components this
 * file knows (a plant, the PI and MPC controllers, the observer); another component gets
 * parameters_changed only.
 */
#include <stddef.h>
#include <stdio.h>

#include "component.h"

#define INT_FIELD(field) \
    printf("int_field %s %lu\n", #field, (unsigned long)offsetof(ModelData, field))

int main(void)
{
    printf("data_size %lu\n", (unsigned long)sizeof(ModelData));
    INT_FIELD(parameters_changed);
#if defined(GATETWIN_PLANT_DATA_H) || defined(GATETWIN_CONTROLLER_DATA_H) || \
    defined(GATETWIN_MPC_DATA_H) || defined(GATETWIN_OBSERVER_DATA_H)
    INT_FIELD(initialized);
#endif
#ifdef GATETWIN_MPC_DATA_H
    INT_FIELD(have_matrices);
#endif
#ifdef GATETWIN_PLANT_DATA_H
    INT_FIELD(warned_validity);
#endif
#ifdef GATETWIN_MODEL_FOPDT_H
    INT_FIELD(dyn.head);
    INT_FIELD(dyn.count);
#endif
    return 0;
}
