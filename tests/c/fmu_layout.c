/* Where a gatetwin C FMU's component keeps its ints: the SPEC lines of tests/c/fmu_fuzz.c that
 * the modelDescription cannot give.
 *
 * Compiled against an FMU's sources/ (-I): component.h brings the generated model_config.h
 * and the component's ModelData, whatever the component. Prints `data_size` (sizeof
 * ModelData) and one `int_field NAME OFFSET` per int the component's state checks must guard:
 * `parameters_changed` (every component, component.h), and the fields of the components this
 * file knows (a plant, the PI and MPC controllers, the observers, the scenario); another component gets
 * parameters_changed only.
 *
 * With the argument `cache` (a plant only) it prints `NAME OFFSET` for the fields of the step
 * cache (plant_data.h) that tests/fmu/test_fmu_cache.py tampers with instead.
 */
#include <stddef.h>
#include <stdio.h>
#include <string.h>

#include "component.h"

#define INT_FIELD(field) \
    printf("int_field %s %lu\n", #field, (unsigned long)offsetof(ModelData, field))
#define FIELD(field) printf("%s %lu\n", #field, (unsigned long)offsetof(ModelData, field))

#if defined(GATETWIN_PLANT_DATA_H) && GT_ENVELOPE
#define ENVELOPE_CACHE 1 /* an envelope FOPDT or ARX: its cache holds a steady point */
#else
#define ENVELOPE_CACHE 0
#endif

static int cache_fields(void)
{
#ifdef GATETWIN_PLANT_DATA_H
    FIELD(cache.valid);
    FIELD(cache.flow_m3h);
    FIELD(cache.at.index);
    FIELD(cache.at.weight);
#if ENVELOPE_CACHE
    FIELD(cache.dyn.point_valid);
    FIELD(cache.dyn.point_u_mm);
    FIELD(cache.dyn.point_level_mm);
#endif
#ifdef GATETWIN_MODEL_FOPDT_H
    FIELD(cache.dyn.decay_filled);
    FIELD(cache.dyn.decay_next);
    FIELD(cache.dyn.decay);
#endif
    FIELD(cache.dyn);
    return 0;
#else
    fprintf(stderr, "not a plant: no step cache\n");
    return 1;
#endif
}

int main(int argc, char **argv)
{
    if (argc > 1 && strcmp(argv[1], "cache") == 0) {
        return cache_fields();
    }
    printf("data_size %lu\n", (unsigned long)sizeof(ModelData));
    INT_FIELD(parameters_changed);
#if defined(GATETWIN_PLANT_DATA_H) || defined(GATETWIN_CONTROLLER_DATA_H) || \
    defined(GATETWIN_MPC_DATA_H) || defined(GATETWIN_OBSERVER_DATA_H) || \
    defined(GATETWIN_OBSERVER_ENVELOPE_DATA_H) || defined(GATETWIN_SIGNAL_DATA_H)
    INT_FIELD(initialized);
#endif
#ifdef GATETWIN_MPC_DATA_H
    INT_FIELD(have_matrices);
    INT_FIELD(n_expected);
#endif
#ifdef GATETWIN_PLANT_DATA_H
    INT_FIELD(warned_validity);
    INT_FIELD(cache.valid);
    INT_FIELD(cache.at.index);
    INT_FIELD(cache.at.clamped);
#endif
#if ENVELOPE_CACHE
    INT_FIELD(cache.dyn.point_valid);
#endif
#ifdef GATETWIN_MODEL_FOPDT_H
    INT_FIELD(cache.dyn.decay_filled);
    INT_FIELD(cache.dyn.decay_next);
    INT_FIELD(dyn.head);
    INT_FIELD(dyn.count);
#endif
    return 0;
}
