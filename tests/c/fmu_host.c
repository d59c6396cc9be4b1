/* A small FMI 2.0 host for the C FMU's lifecycle tests (run under valgrind / AddressSanitizer).
 *
 * usage: fmu_host BINARY GUID VR_OPENING VR_FLOW VR_LEVEL STEP_S CYCLES
 *
 * Each cycle instantiates, initialises, steps with changing inputs (also outside the schedule's
 * knots), takes, serialises, restores and frees FMU states, makes calls the FMU must refuse
 * (NULL arrays, unknown value references, NaN input, a call in the wrong state) and frees the
 * instance. Exits 0 when every call returned what it should, 1 otherwise.
 */
#include <dlfcn.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

#define LOAD(name) name##TYPE *name = (name##TYPE *)load(lib, #name)
#define EXPECT(call, status)                                                                 \
    do {                                                                                     \
        fmi2Status got_ = (call);                                                            \
        if (got_ != (status)) {                                                              \
            fprintf(stderr, "line %d: %s returned %d, expected %d\n", __LINE__, #call, got_, \
                    status);                                                                 \
            return 1;                                                                        \
        }                                                                                    \
    } while (0)

static int messages;

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status,
                   fmi2String category, fmi2String message, ...)
{
    (void)env, (void)name, (void)status, (void)category, (void)message;
    messages++;
}

static void *load(void *lib, const char *name)
{
    void *f = dlsym(lib, name);
    if (!f) {
        fprintf(stderr, "missing symbol %s\n", name);
        exit(1);
    }
    return f;
}

int main(int argc, char **argv)
{
    void *lib;
    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    fmi2ValueReference vr_in[2], vr_out, vr_bad = 100000;
    double step_s;
    long cycles, cycle;
    int k;
    if (argc != 8) {
        fprintf(stderr, "usage: %s BINARY GUID VR_OPENING VR_FLOW VR_LEVEL STEP_S CYCLES\n", argv[0]);
        return 2;
    }
    lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        fprintf(stderr, "dlopen: %s\n", dlerror());
        return 2;
    }
    vr_in[0] = (fmi2ValueReference)atoi(argv[3]);
    vr_in[1] = (fmi2ValueReference)atoi(argv[4]);
    vr_out = (fmi2ValueReference)atoi(argv[5]);
    step_s = atof(argv[6]);
    cycles = atol(argv[7]);
    {
        LOAD(fmi2Instantiate);
        LOAD(fmi2FreeInstance);
        LOAD(fmi2SetupExperiment);
        LOAD(fmi2EnterInitializationMode);
        LOAD(fmi2ExitInitializationMode);
        LOAD(fmi2Terminate);
        LOAD(fmi2Reset);
        LOAD(fmi2SetReal);
        LOAD(fmi2GetReal);
        LOAD(fmi2GetInteger);
        LOAD(fmi2DoStep);
        LOAD(fmi2GetFMUstate);
        LOAD(fmi2SetFMUstate);
        LOAD(fmi2FreeFMUstate);
        LOAD(fmi2SerializedFMUstateSize);
        LOAD(fmi2SerializeFMUstate);
        LOAD(fmi2DeSerializeFMUstate);
        const char *guid = argv[2];
        if (fmi2Instantiate("bad", fmi2CoSimulation, "{not-the-guid}", "", &cb, 0, 0) != NULL ||
            fmi2Instantiate("bad", fmi2ModelExchange, guid, "", &cb, 0, 0) != NULL) {
            fprintf(stderr, "instantiate accepted a wrong GUID or FMU type\n");
            return 1;
        }
        EXPECT(fmi2DoStep(NULL, 0.0, 1.0, fmi2True), fmi2Error);
        for (cycle = 0; cycle < cycles; cycle++) {
            fmi2Component c = fmi2Instantiate("host", fmi2CoSimulation, guid, "", &cb, 0, 0);
            fmi2FMUstate saved = NULL, restored = NULL;
            fmi2Real inputs[2] = {20.0, 57.0}, level, level_again, t = 0.0;
            size_t size;
            fmi2Byte *bytes;
            if (!c) {
                fprintf(stderr, "instantiate failed\n");
                return 1;
            }
            EXPECT(fmi2DoStep(c, 0.0, step_s, fmi2True), fmi2Error); /* before initialisation */
            EXPECT(fmi2Reset(c), fmi2OK);
            EXPECT(fmi2SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0), fmi2OK);
            EXPECT(fmi2EnterInitializationMode(c), fmi2OK);
            EXPECT(fmi2SetReal(c, vr_in, 2, inputs), fmi2OK);
            EXPECT(fmi2ExitInitializationMode(c), fmi2OK);
            for (k = 0; k < 40; k++) {
                inputs[0] = 20.0 + (k % 3) * 4.0;
                inputs[1] = 10.0 + k * 3.0; /* crosses and leaves the knots' range */
                EXPECT(fmi2SetReal(c, vr_in, 2, inputs), fmi2OK);
                if (fmi2DoStep(c, t, step_s, fmi2True) > fmi2Warning) {
                    fprintf(stderr, "doStep failed at step %d\n", k);
                    return 1;
                }
                t += step_s;
                if (k == 20) {
                    EXPECT(fmi2GetFMUstate(c, &saved), fmi2OK);
                    EXPECT(fmi2GetFMUstate(c, &saved), fmi2OK); /* reuse the same state */
                }
            }
            EXPECT(fmi2GetReal(c, &vr_out, 1, &level), fmi2OK);
            EXPECT(fmi2SerializedFMUstateSize(c, saved, &size), fmi2OK);
            bytes = (fmi2Byte *)malloc(size);
            EXPECT(fmi2SerializeFMUstate(c, saved, bytes, size), fmi2OK);
            EXPECT(fmi2DeSerializeFMUstate(c, bytes, size - 1, &restored), fmi2Error);
            EXPECT(fmi2SetFMUstate(c, saved), fmi2OK);
            EXPECT(fmi2DeSerializeFMUstate(c, bytes, size, &restored), fmi2OK);
            free(bytes);
            EXPECT(fmi2SetFMUstate(c, restored), fmi2OK);
            t = 21.0 * step_s;
            for (k = 21; k < 40; k++) {
                inputs[0] = 20.0 + (k % 3) * 4.0;
                inputs[1] = 10.0 + k * 3.0;
                EXPECT(fmi2SetReal(c, vr_in, 2, inputs), fmi2OK);
                if (fmi2DoStep(c, t, step_s, fmi2True) > fmi2Warning) {
                    return 1;
                }
                t += step_s;
            }
            EXPECT(fmi2GetReal(c, &vr_out, 1, &level_again), fmi2OK);
            if (level_again != level) {
                fprintf(stderr, "restored run differs: %.17g vs %.17g\n", level_again, level);
                return 1;
            }
            /* calls the FMU must refuse without crashing */
            EXPECT(fmi2GetReal(c, NULL, 1, &level), fmi2Error);
            EXPECT(fmi2SetFMUstate(c, saved), fmi2OK);
            EXPECT(fmi2GetReal(c, &vr_bad, 1, &level), fmi2Error);
            EXPECT(fmi2SetFMUstate(c, saved), fmi2OK);
            EXPECT(fmi2GetInteger(c, &vr_out, 1, NULL), fmi2Error);
            EXPECT(fmi2SetFMUstate(c, saved), fmi2OK);
            inputs[0] = NAN;
            EXPECT(fmi2SetReal(c, vr_in, 2, inputs), fmi2Error);
            EXPECT(fmi2DoStep(c, t, step_s, fmi2True), fmi2Error); /* error state sticks */
            EXPECT(fmi2SetFMUstate(c, saved), fmi2OK);
            EXPECT(fmi2Terminate(c), fmi2OK);
            EXPECT(fmi2FreeFMUstate(c, &saved), fmi2OK);
            EXPECT(fmi2FreeFMUstate(c, &restored), fmi2OK);
            EXPECT(fmi2FreeFMUstate(c, &restored), fmi2OK); /* already NULL */
            fmi2FreeInstance(c);
        }
    }
    printf("%ld cycles ok, %d log messages\n", cycles, messages);
    dlclose(lib);
    return 0;
}
