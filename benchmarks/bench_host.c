/* Tiny FMI 2.0 host that times doStep calls of one FMU binary (used by bench_fmu.py).
 *
 * usage: bench_host BINARY GUID RESOURCE_URI VR_OPENING VR_FLOW VR_LEVEL STEP_S N [LIBPYTHON]
 *
 * LIBPYTHON (for pythonfmu FMUs) is loaded first with RTLD_GLOBAL: pythonfmu's binary takes
 * the Python C API from the process instead of linking libpython itself.
 * Prints four lines: doStep alone with held inputs; setReal + doStep + getReal per step with
 * the opening changed every 7 steps; the same with the opening changed at every step between
 * 18 and 23 mm; the same with the opening moving by 0.1 mm at every step (a controller's
 * output: 18.0, 18.1, ... 22.9 mm, then back to 18 mm).
 */
#define _POSIX_C_SOURCE 199309L
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "fmi2Functions.h"

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status,
                   fmi2String category, fmi2String message, ...)
{
    (void)env, (void)category;
    if (status > fmi2Warning) {
        fprintf(stderr, "[%s] %s\n", name, message);
    }
}

static double now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1e9 + ts.tv_nsec;
}

static void *load(void *lib, const char *name)
{
    void *f = dlsym(lib, name);
    if (!f) {
        fprintf(stderr, "missing symbol %s\n", name);
        exit(2);
    }
    return f;
}

#define LOAD(name) name##TYPE *name = (name##TYPE *)load(lib, #name)

int main(int argc, char **argv)
{
    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    fmi2ValueReference inputs[2], output;
    double step_s, t = 0.0, start, level = 0.0;
    long n, k;
    void *lib;
    if (argc < 9) {
        fprintf(stderr, "usage: %s BINARY GUID RESOURCE_URI VR_OPENING VR_FLOW VR_LEVEL STEP_S N "
                        "[LIBPYTHON]\n", argv[0]);
        return 2;
    }
    if (argc > 9 && !dlopen(argv[9], RTLD_NOW | RTLD_GLOBAL)) {
        fprintf(stderr, "dlopen libpython: %s\n", dlerror());
        return 2;
    }
    lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        fprintf(stderr, "dlopen: %s\n", dlerror());
        return 2;
    }
    inputs[0] = (fmi2ValueReference)atoi(argv[4]);
    inputs[1] = (fmi2ValueReference)atoi(argv[5]);
    output = (fmi2ValueReference)atoi(argv[6]);
    step_s = atof(argv[7]);
    n = atol(argv[8]);
    {
        LOAD(fmi2Instantiate);
        LOAD(fmi2FreeInstance);
        LOAD(fmi2SetupExperiment);
        LOAD(fmi2EnterInitializationMode);
        LOAD(fmi2ExitInitializationMode);
        LOAD(fmi2SetReal);
        LOAD(fmi2GetReal);
        LOAD(fmi2DoStep);
        fmi2Real values[2] = {20.0, 47.0}; /* between two knots: interpolation is exercised */
        fmi2Component c = fmi2Instantiate("bench", fmi2CoSimulation, argv[2], argv[3], &cb, 0, 0);
        if (!c || fmi2SetupExperiment(c, 0, 0.0, 0.0, 0, 0.0) != fmi2OK ||
            fmi2EnterInitializationMode(c) != fmi2OK || fmi2SetReal(c, inputs, 2, values) ||
            fmi2ExitInitializationMode(c) != fmi2OK) {
            fprintf(stderr, "initialisation failed\n");
            return 1;
        }
        values[0] = 24.0;
        fmi2SetReal(c, inputs, 2, values);
        for (k = 0; k < n / 10 + 1; k++) { /* warm up, and let the step response settle */
            if (fmi2DoStep(c, t, step_s, fmi2True) != fmi2OK) {
                return 1;
            }
            t += step_s;
        }
        start = now_ns();
        for (k = 0; k < n; k++) {
            fmi2DoStep(c, t, step_s, fmi2True);
            t += step_s;
        }
        printf("doStep_ns %.2f\n", (now_ns() - start) / n);
        start = now_ns();
        for (k = 0; k < n; k++) {
            values[0] = (k / 7) % 2 ? 18.0 : 23.0; /* PRBS-like opening changes */
            fmi2SetReal(c, inputs, 2, values);
            if (fmi2DoStep(c, t, step_s, fmi2True) != fmi2OK) {
                return 1;
            }
            fmi2GetReal(c, &output, 1, &level);
            t += step_s;
        }
        printf("set_doStep_get_ns %.2f\n", (now_ns() - start) / n);
        start = now_ns();
        for (k = 0; k < n; k++) {
            values[0] = k % 2 ? 18.0 : 23.0; /* a new opening at every step */
            fmi2SetReal(c, inputs, 2, values);
            if (fmi2DoStep(c, t, step_s, fmi2True) != fmi2OK) {
                return 1;
            }
            fmi2GetReal(c, &output, 1, &level);
            t += step_s;
        }
        printf("set_every_step_ns %.2f\n", (now_ns() - start) / n);
        start = now_ns();
        for (k = 0; k < n; k++) {
            values[0] = 18.0 + 0.1 * (double)(k % 50); /* 0.1 mm per step */
            fmi2SetReal(c, inputs, 2, values);
            if (fmi2DoStep(c, t, step_s, fmi2True) != fmi2OK) {
                return 1;
            }
            fmi2GetReal(c, &output, 1, &level);
            t += step_s;
        }
        printf("moving_ns %.2f\n", (now_ns() - start) / n);
        printf("level %.6f\n", level);
        fmi2FreeInstance(c);
    }
    return 0;
}
