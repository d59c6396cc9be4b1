/* Tiny FMI 2.0 host that times doStep calls of the MPC controller FMU (bench_controller_fmu.py).
 *
 * Compiled against the FMU's own sources folder (-I sources): model_config.h gives the value
 * references and component.h the controller's ModelData, whose size is printed.
 *
 * usage: bench_controller_host BINARY RESOURCE_URI N
 *
 * The loop closes on a first-order pool in the host (gain -13.6 mm/mm, 62 s, at 40 m3/h:
 * the demo plant's numbers, no dead time) and steps the set-point every 100 samples through
 * 190, 210, 190 and 340 mm (+-20 mm steps, and a 150 mm one that keeps the rate limit active
 * for most of the horizon), so the rate limit is active through each transient. Prints one
 * "key value" per line: doStep percentiles (ns), the share of samples with active constraints besides the band slack's
 * bound s >= 0 (active at every sample: the slack is zero), fallbacks, iterations, the
 * size of ModelData and what the FMU allocated through the callbacks (at instantiation, and
 * during the steps).
 */
#define _POSIX_C_SOURCE 199309L
#include <dlfcn.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "fmi2Functions.h"
#include "component.h" /* model_config.h (value references) and ModelData */

static size_t allocations, allocated_bytes;

static void *counting_calloc(size_t n, size_t size)
{
    allocations++;
    allocated_bytes += n * size;
    return calloc(n, size);
}

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

static int by_value(const void *a, const void *b)
{
    const double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* "<prefix>p50_ns", "p99_ns" and "max_ns" of the n times in t (sorted here) */
static void percentiles(const char *prefix, double *t, long n)
{
    if (n < 1) {
        return;
    }
    qsort(t, (size_t)n, sizeof *t, by_value);
    printf("%sp50_ns %.0f\n%sp99_ns %.0f\n%smax_ns %.0f\n", prefix, t[n / 2], prefix,
           t[(long)(0.99 * (double)(n - 1))], prefix, t[n - 1]);
}

int main(int argc, char **argv)
{
    const fmi2CallbackFunctions cb = {logger, counting_calloc, free, NULL, NULL};
    const fmi2ValueReference inputs[3] = {VR_LEVEL, VR_FLOW_M3H, VR_SETPOINT_MM};
    const fmi2ValueReference outputs[4] = {VR_OPENING_MM, VR_ACTIVE_CONSTRAINTS,
                                           VR_SOLVER_STATUS, VR_SOLVER_ITERATIONS};
    const fmi2ValueReference start_vr = VR_START_OPENING_MM;
    const double ts = GT_GEN_SAMPLE_PERIOD_S, keep = exp(-GT_GEN_SAMPLE_PERIOD_S / 62.0);
    static const double setpoints[4] = {190.0, 210.0, 190.0, 340.0};
    double level = 190.0, opening = 25.0, t = 0.0, *step_ns, *phase_ns, out[4], in[3];
    double most = 0.0;
    long n, k, active = 0, fallbacks = 0, n_small = 0, n_large = 0;
    double iterations = 0.0;
    size_t at_instantiation;
    void *lib;
    fmi2Component c;
    if (argc != 4) {
        fprintf(stderr, "usage: %s BINARY RESOURCE_URI N\n", argv[0]);
        return 2;
    }
    n = atol(argv[3]);
    step_ns = malloc(sizeof *step_ns * (size_t)n);
    phase_ns = malloc(sizeof *phase_ns * (size_t)n); /* small steps first, the large last */
    lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    if (!lib || !step_ns || !phase_ns) {
        fprintf(stderr, "cannot load %s: %s\n", argv[1], dlerror());
        return 2;
    }
    fmi2InstantiateTYPE *instantiate = (fmi2InstantiateTYPE *)load(lib, "fmi2Instantiate");
    fmi2SetupExperimentTYPE *setup = (fmi2SetupExperimentTYPE *)load(lib, "fmi2SetupExperiment");
    fmi2EnterInitializationModeTYPE *enter =
        (fmi2EnterInitializationModeTYPE *)load(lib, "fmi2EnterInitializationMode");
    fmi2ExitInitializationModeTYPE *leave =
        (fmi2ExitInitializationModeTYPE *)load(lib, "fmi2ExitInitializationMode");
    fmi2SetRealTYPE *set_real = (fmi2SetRealTYPE *)load(lib, "fmi2SetReal");
    fmi2GetRealTYPE *get_real = (fmi2GetRealTYPE *)load(lib, "fmi2GetReal");
    fmi2DoStepTYPE *do_step = (fmi2DoStepTYPE *)load(lib, "fmi2DoStep");
    fmi2FreeInstanceTYPE *free_instance = (fmi2FreeInstanceTYPE *)load(lib, "fmi2FreeInstance");

    c = instantiate("bench", fmi2CoSimulation, GT_GUID, argv[2], &cb, fmi2False, fmi2False);
    if (!c) {
        return 3;
    }
    at_instantiation = allocated_bytes;
    in[0] = level, in[1] = 40.0, in[2] = level;
    if (setup(c, fmi2False, 0.0, 0.0, fmi2False, 0.0) != fmi2OK || enter(c) != fmi2OK ||
        set_real(c, &start_vr, 1, &opening) != fmi2OK || set_real(c, inputs, 3, in) != fmi2OK ||
        leave(c) != fmi2OK) {
        return 4;
    }
    for (k = 0; k < n; k++) {
        double t0;
        in[0] = level;
        in[2] = setpoints[(k / 100) % 4];
        t0 = now_ns();
        if (set_real(c, inputs, 3, in) != fmi2OK || do_step(c, t, ts, fmi2True) != fmi2OK ||
            get_real(c, outputs, 4, out) != fmi2OK) {
            return 5;
        }
        step_ns[k] = now_ns() - t0;
        if ((k / 100) % 4 == 3) {
            phase_ns[n - 1 - n_large++] = step_ns[k];
        } else {
            phase_ns[n_small++] = step_ns[k];
        }
        opening = out[0];
        active += out[1] > 1.0; /* more than the slack's s >= 0, active throughout */
        fallbacks += out[2] != 0.0;
        iterations += out[3];
        most = out[3] > most ? out[3] : most;
        level = keep * level + (1.0 - keep) * (190.0 - 13.6 * (opening - 25.0));
        t += ts;
    }
    percentiles("", step_ns, n);
    percentiles("small_steps_", phase_ns, n_small);
    percentiles("large_step_", phase_ns + n_small, n_large);
    printf("active_share %.4f\nfallbacks %ld\nmean_iterations %.3f\nmax_iterations %.0f\n",
           (double)active / n, fallbacks, iterations / n, most);
    printf("sizeof_modeldata %lu\n", (unsigned long)sizeof(ModelData));
    printf("heap_at_instantiation_bytes %lu\nheap_during_steps_bytes %lu\n",
           (unsigned long)at_instantiation, (unsigned long)(allocated_bytes - at_instantiation));
    free_instance(c);
    free(step_ns);
    free(phase_ns);
    return 0;
}
