/* A portable FMI host that drives one co-simulation FMU binary and prints its output.
 *
 * usage: fmu_trace BINARY GUID VR_OPENING VR_FLOW VR_LEVEL STEP_S < inputs
 *
 * Built for FMI 2.0 by default, for FMI 3.0 with -DTRACE_FMI3 (GUID is then the
 * instantiation token); -I names the FMU's sources/, whose headers are that version's.
 * `inputs` holds one line per communication step, "opening_mm flow_m3h"; the first line sets
 * the initial inputs. Prints the level after initialisation and after every step ("%.17g"),
 * so that runs on different platforms (natively, under wine, under qemu) and of the two FMI
 * versions can be compared to the last bit. Exits 0, or 1 with a line on stderr when a call
 * returns neither OK nor a warning.
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

#ifdef TRACE_FMI3
#include "fmi3Functions.h"
#define STATUS_ACCEPTED(s) ((s) == fmi3OK || (s) == fmi3Warning)
#else
#include "fmi2Functions.h"
#define STATUS_ACCEPTED(s) ((s) == fmi2OK || (s) == fmi2Warning)
#endif

#define LOAD(name) name##TYPE *name = (name##TYPE *)load(lib, #name)
#define CHECK(call)                                                                \
    do {                                                                           \
        int got_ = (int)(call);                                                    \
        if (!STATUS_ACCEPTED(got_)) {                                              \
            fprintf(stderr, "line %d: %s returned %d\n", __LINE__, #call, got_);   \
            return 1;                                                              \
        }                                                                          \
    } while (0)

/* What one run needs: the binary, its token, the three value references and the step. */
typedef struct {
    void *lib;
    const char *token;
    unsigned vr_in[2];
    unsigned vr_out;
    double step_s;
} Run;

static void *load(void *lib, const char *name)
{
    void *f = SYMBOL(lib, name);
    if (!f) {
        fprintf(stderr, "missing symbol %s\n", name);
        exit(1);
    }
    return f;
}

#ifdef TRACE_FMI3

static void logger(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category,
                   fmi3String message)
{
    (void)env, (void)status, (void)category, (void)message;
}

/* Drives the FMU from inputs u (the first line, already read) to the end of stdin. */
static int trace(const Run *run, double u[2])
{
    void *lib = run->lib;
    fmi3ValueReference vr_in[2] = {run->vr_in[0], run->vr_in[1]}, vr_out = run->vr_out;
    fmi3Boolean event, terminate, early;
    double level, t = 0.0, last;
    fmi3Instance c;
    LOAD(fmi3InstantiateCoSimulation);
    LOAD(fmi3FreeInstance);
    LOAD(fmi3EnterInitializationMode);
    LOAD(fmi3ExitInitializationMode);
    LOAD(fmi3SetFloat64);
    LOAD(fmi3GetFloat64);
    LOAD(fmi3DoStep);
    LOAD(fmi3Terminate);
    c = fmi3InstantiateCoSimulation("trace", run->token, NULL, fmi3False, fmi3False, fmi3False,
                                    fmi3False, NULL, 0, NULL, logger, NULL);
    if (!c) {
        fprintf(stderr, "fmi3InstantiateCoSimulation failed\n");
        return 1;
    }
    CHECK(fmi3SetFloat64(c, vr_in, 2, u, 2));
    CHECK(fmi3EnterInitializationMode(c, fmi3False, 0.0, 0.0, fmi3False, 0.0));
    CHECK(fmi3ExitInitializationMode(c));
    CHECK(fmi3GetFloat64(c, &vr_out, 1, &level, 1));
    printf("%.17g\n", level);
    while (scanf("%lf %lf", &u[0], &u[1]) == 2) {
        CHECK(fmi3SetFloat64(c, vr_in, 2, u, 2));
        CHECK(fmi3DoStep(c, t, run->step_s, fmi3True, &event, &terminate, &early, &last));
        t += run->step_s;
        CHECK(fmi3GetFloat64(c, &vr_out, 1, &level, 1));
        printf("%.17g\n", level);
    }
    CHECK(fmi3Terminate(c));
    fmi3FreeInstance(c);
    return 0;
}

#else

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status,
                   fmi2String category, fmi2String message, ...)
{
    (void)env, (void)name, (void)status, (void)category, (void)message;
}

/* Drives the FMU from inputs u (the first line, already read) to the end of stdin. */
static int trace(const Run *run, double u[2])
{
    void *lib = run->lib;
    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    fmi2ValueReference vr_in[2] = {run->vr_in[0], run->vr_in[1]}, vr_out = run->vr_out;
    double level, t = 0.0;
    fmi2Component c;
    LOAD(fmi2Instantiate);
    LOAD(fmi2FreeInstance);
    LOAD(fmi2SetupExperiment);
    LOAD(fmi2EnterInitializationMode);
    LOAD(fmi2ExitInitializationMode);
    LOAD(fmi2SetReal);
    LOAD(fmi2GetReal);
    LOAD(fmi2DoStep);
    LOAD(fmi2Terminate);
    c = fmi2Instantiate("trace", fmi2CoSimulation, run->token, "", &cb, fmi2False, fmi2False);
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
        CHECK(fmi2DoStep(c, t, run->step_s, fmi2True));
        t += run->step_s;
        CHECK(fmi2GetReal(c, &vr_out, 1, &level));
        printf("%.17g\n", level);
    }
    CHECK(fmi2Terminate(c));
    fmi2FreeInstance(c);
    return 0;
}

#endif

int main(int argc, char **argv)
{
    Run run;
    double u[2];
    if (argc != 7) {
        fprintf(stderr, "usage: %s BINARY GUID VR_OPENING VR_FLOW VR_LEVEL STEP_S\n", argv[0]);
        return 2;
    }
    run.lib = OPEN(argv[1]);
    if (!run.lib) {
        fprintf(stderr, "cannot load %s\n", argv[1]);
        return 2;
    }
    run.token = argv[2];
    run.vr_in[0] = (unsigned)atoi(argv[3]);
    run.vr_in[1] = (unsigned)atoi(argv[4]);
    run.vr_out = (unsigned)atoi(argv[5]);
    run.step_s = atof(argv[6]);
    if (scanf("%lf %lf", &u[0], &u[1]) != 2) {
        fprintf(stderr, "no inputs\n");
        return 2;
    }
    return trace(&run, u);
}
