/* A portable FMI 2.0 host that drives one co-simulation FMU binary and prints its output.
 *
 * usage: fmu_trace BINARY GUID VR_OPENING VR_FLOW VR_LEVEL STEP_S < inputs
 *
 * `inputs` holds one line per communication step, "opening_mm flow_m3h"; the first line sets
 * the initial inputs. Prints the level after initialisation and after every step ("%.17g"),
 * so that runs on different platforms (natively, under wine, under qemu) can be compared to
 * the last bit. Exits 0, or 1 with a line on stderr when a call does not return fmi2OK (a
 * warning is accepted).
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef _WIN32
#include <windows.h>
#define OPEN(path) ((void *)LoadLibraryA(path))
#define SYMBOL(lib, name) ((void *)GetProcAddress((HMODULE)(lib), name))
#else
#include <dlfcn.h>
#define OPEN(path) dlopen(path, RTLD_NOW | RTLD_LOCAL)
#define SYMBOL(lib, name) dlsym(lib, name)
#endif

#include "fmi2Functions.h"

#define LOAD(name) name##TYPE *name = (name##TYPE *)load(lib, #name)
#define CHECK(call)                                                                \
    do {                                                                           \
        fmi2Status got_ = (call);                                                  \
        if (got_ != fmi2OK && got_ != fmi2Warning) {                               \
            fprintf(stderr, "line %d: %s returned %d\n", __LINE__, #call, got_);   \
            return 1;                                                              \
        }                                                                          \
    } while (0)

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status,
                   fmi2String category, fmi2String message, ...)
{
    (void)env, (void)name, (void)status, (void)category, (void)message;
}

static void *load(void *lib, const char *name)
{
    void *f = SYMBOL(lib, name);
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
    fmi2ValueReference vr_in[2], vr_out;
    double u[2], level, t = 0.0, step_s;
    fmi2Component c;
    if (argc != 7) {
        fprintf(stderr, "usage: %s BINARY GUID VR_OPENING VR_FLOW VR_LEVEL STEP_S\n", argv[0]);
        return 2;
    }
    lib = OPEN(argv[1]);
    if (!lib) {
        fprintf(stderr, "cannot load %s\n", argv[1]);
        return 2;
    }
    vr_in[0] = (fmi2ValueReference)atoi(argv[3]);
    vr_in[1] = (fmi2ValueReference)atoi(argv[4]);
    vr_out = (fmi2ValueReference)atoi(argv[5]);
    step_s = atof(argv[6]);
    if (scanf("%lf %lf", &u[0], &u[1]) != 2) {
        fprintf(stderr, "no inputs\n");
        return 2;
    }
    {
        LOAD(fmi2Instantiate);
        LOAD(fmi2FreeInstance);
        LOAD(fmi2SetupExperiment);
        LOAD(fmi2EnterInitializationMode);
        LOAD(fmi2ExitInitializationMode);
        LOAD(fmi2SetReal);
        LOAD(fmi2GetReal);
        LOAD(fmi2DoStep);
        LOAD(fmi2Terminate);
        c = fmi2Instantiate("trace", fmi2CoSimulation, argv[2], "", &cb, fmi2False, fmi2False);
        if (!c) {
            fprintf(stderr, "fmi2Instantiate failed\n");
            return 1;
        }
        CHECK(fmi2SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0));
        CHECK(fmi2SetReal(c, vr_in, 2, u));
        CHECK(fmi2EnterInitializationMode(c));
        CHECK(fmi2ExitInitializationMode(c));
        CHECK(fmi2GetReal(c, &vr_out, 1, &level));
        printf("%.17g\n", level);
        while (scanf("%lf %lf", &u[0], &u[1]) == 2) {
            CHECK(fmi2SetReal(c, vr_in, 2, u));
            CHECK(fmi2DoStep(c, t, step_s, fmi2True));
            t += step_s;
            CHECK(fmi2GetReal(c, &vr_out, 1, &level));
            printf("%.17g\n", level);
        }
        CHECK(fmi2Terminate(c));
        fmi2FreeInstance(c);
    }
    return 0;
}
