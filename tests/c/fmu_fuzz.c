/* An FMI 2.0 fuzzer for gatetwin's C FMUs (plants and controllers): random call sequences
 * from a seed.
 *
 * usage: fmu_fuzz BINARY SPEC SEED SEQUENCES [OTHER_BINARY OTHER_GUID]
 *
 * SPEC is a small text file that describes the FMU, one item per line (tests/fmu/test_fmu_fuzz.py
 * writes it from the FMU's modelDescription.xml and tests/c/fmu_layout.c):
 *
 *   guid GUID
 *   var VR KIND START          every Real variable, KIND input|output|tunable|fixed
 *   range VR LO HI             optional, after its var: an input's plausible values
 *                              (default START +- max(|START|, 1))
 *   sample_period VR           optional: communication steps are whole multiples of it
 *   sample_period_s SECONDS    optional, instead: a fixed sample period no variable holds
 *   warns_on_change VR         optional: each setting of this input may bring one more
 *                              fmi2Warning (a controller warns of each set-point outside
 *                              its band)
 *   data_size BYTES            sizeof(ModelData): a serialised state ends with it
 *   int_field NAME OFFSET      optional, repeated: an int of ModelData (flag, index, count)
 *
 * The fuzzer needs only the FMI 2.0 headers (-I fmu_templates/) and is built, like the FMU
 * binary, with -fsanitize=address,undefined. Each sequence instantiates the FMU and makes
 * 1..80 calls drawn at random: calls in and out of order, NaN / inf / huge / negative inputs
 * and parameters, communication steps that are negative, zero, tiny or huge or start at the
 * wrong time, get/set of unknown value references and of every type, FMU state get/set/free
 * and serialise/deserialise round trips, tampered serialised states (flipped bytes, header,
 * mode and the component's int fields overwritten, doubles made NaN/inf, truncated or
 * extended buffers), states of another FMU (OTHER_BINARY), free/instantiate cycles.
 *
 * Besides the sanitizers (any report aborts the run), each call is checked:
 *  - the status is one of fmi2OK..fmi2Pending;
 *  - a call on an instance that returns fmi2Error logs at least one error line;
 *  - after fmi2DoStep returns fmi2OK or fmi2Warning every output is finite;
 *  - a state the FMU serialised is accepted back; an accepted serialised state has a finite
 *    time and finite variables;
 *  - a refused fmi2SetFMUstate leaves the instance as it was, a refused
 *    fmi2DeSerializeFMUstate leaves the state it was to overwrite as it was (both compared as
 *    serialised bytes);
 *  - an instance gives at most one fmi2Warning between (re)starts, plus one for each setting
 *    of the input named by warns_on_change.
 * A sequence taking longer than HANG_S seconds counts as a hang. Exits 0 and prints the
 * counts when nothing was found, 1 with the seed and sequence of the first finding otherwise,
 * 2 on bad arguments or a bad SPEC.
 */
#define _POSIX_C_SOURCE 200809L
#include <dlfcn.h>
#include <limits.h>
#include <math.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "fmi2Functions.h"

#define HANG_S 20
#define N_SLOTS 4
#define MAX_CALLS 80
#define MAX_INT_FIELDS 16

/* --- what the fuzzer knows of the FMU (SPEC) ---------------------------------------------- */

typedef enum { KIND_INPUT, KIND_OUTPUT, KIND_TUNABLE, KIND_FIXED } Kind;

typedef struct {
    char guid[128];
    unsigned n_real;          /* Real variables: value references 0..n_real-1 */
    Kind *kind;               /* by value reference */
    double *start;            /* by value reference (0 where the description has none) */
    double *lo, *hi;          /* an input's plausible values, by value reference */
    unsigned *inputs, n_inputs;
    unsigned *outputs, n_outputs;
    long period_vr;           /* sample period's value reference, -1: none */
    long warn_vr;             /* warns_on_change's value reference, -1: none */
    double period_s;          /* a fixed sample period, s; 0: none */
    size_t data_size;         /* sizeof(ModelData) */
    size_t int_fields[MAX_INT_FIELDS]; /* offsets of ints in ModelData */
    unsigned n_int_fields;
} Spec;

static Spec spec;

/* One line naming the SPEC file (and the line, when one is to blame), exit 2. */
static void bad_spec(const char *path, unsigned line, const char *why)
{
    if (line) {
        fprintf(stderr, "%s:%u: %s\n", path, line, why);
    } else {
        fprintf(stderr, "%s: %s\n", path, why);
    }
    exit(2);
}

static Kind kind_named(const char *name, const char *path, unsigned line)
{
    static const char *const names[] = {"input", "output", "tunable", "fixed"};
    unsigned k;
    for (k = 0; k < 4; k++) {
        if (strcmp(name, names[k]) == 0) {
            return (Kind)k;
        }
    }
    bad_spec(path, line, "variable kind must be input, output, tunable or fixed");
    return KIND_INPUT;
}

/* One "var VR KIND START" line: the variables come in value-reference order. */
static void spec_variable(const char *rest, const char *path, unsigned line)
{
    unsigned vr;
    char kind[16];
    double start;
    if (sscanf(rest, "%u %15s %lf", &vr, kind, &start) != 3 || vr != spec.n_real ||
        vr >= 100000) {
        bad_spec(path, line, "expected 'var VR KIND START', value references 0, 1, 2, ...");
    }
    spec.kind = (Kind *)realloc(spec.kind, (vr + 1) * sizeof *spec.kind);
    spec.start = (double *)realloc(spec.start, (vr + 1) * sizeof *spec.start);
    spec.lo = (double *)realloc(spec.lo, (vr + 1) * sizeof *spec.lo);
    spec.hi = (double *)realloc(spec.hi, (vr + 1) * sizeof *spec.hi);
    spec.inputs = (unsigned *)realloc(spec.inputs, (vr + 1) * sizeof *spec.inputs);
    spec.outputs = (unsigned *)realloc(spec.outputs, (vr + 1) * sizeof *spec.outputs);
    if (!spec.kind || !spec.start || !spec.lo || !spec.hi || !spec.inputs || !spec.outputs) {
        bad_spec(path, line, "out of memory");
    }
    if (!isfinite(start)) {
        bad_spec(path, line, "a start value must be finite");
    }
    spec.kind[vr] = kind_named(kind, path, line);
    spec.start[vr] = start;
    spec.lo[vr] = start - (fabs(start) > 1.0 ? fabs(start) : 1.0);
    spec.hi[vr] = start + (fabs(start) > 1.0 ? fabs(start) : 1.0);
    if (spec.kind[vr] == KIND_INPUT) {
        spec.inputs[spec.n_inputs++] = vr;
    } else if (spec.kind[vr] == KIND_OUTPUT) {
        spec.outputs[spec.n_outputs++] = vr;
    }
    spec.n_real = vr + 1;
}

/* One "range VR LO HI" line, after the variable's. */
static void spec_range(const char *rest, const char *path, unsigned line)
{
    unsigned vr;
    double lo, hi;
    if (sscanf(rest, "%u %lf %lf", &vr, &lo, &hi) != 3 || vr >= spec.n_real ||
        spec.kind[vr] != KIND_INPUT || !(lo < hi) || !isfinite(hi - lo)) {
        bad_spec(path, line, "expected 'range VR LO HI' of an input declared above, LO < HI");
    }
    spec.lo[vr] = lo;
    spec.hi[vr] = hi;
}

static void spec_line(const char *text, const char *path, unsigned line)
{
    char key[32], name[64];
    unsigned long value;
    int used = 0;
    if (sscanf(text, "%31s %n", key, &used) != 1) {
        return; /* blank */
    }
    if (strcmp(key, "guid") == 0) {
        if (sscanf(text + used, "%127s", spec.guid) != 1) {
            bad_spec(path, line, "expected 'guid GUID'");
        }
    } else if (strcmp(key, "var") == 0) {
        spec_variable(text + used, path, line);
    } else if (strcmp(key, "range") == 0) {
        spec_range(text + used, path, line);
    } else if (strcmp(key, "sample_period") == 0) {
        if (sscanf(text + used, "%lu", &value) != 1) {
            bad_spec(path, line, "expected 'sample_period VR'");
        }
        spec.period_vr = (long)value;
    } else if (strcmp(key, "warns_on_change") == 0) {
        if (sscanf(text + used, "%lu", &value) != 1 || value >= spec.n_real ||
            spec.kind[value] != KIND_INPUT) {
            bad_spec(path, line, "expected 'warns_on_change VR' of an input declared above");
        }
        spec.warn_vr = (long)value;
    } else if (strcmp(key, "sample_period_s") == 0) {
        if (sscanf(text + used, "%lf", &spec.period_s) != 1 || !(spec.period_s > 0.0) ||
            !isfinite(spec.period_s)) {
            bad_spec(path, line, "expected 'sample_period_s SECONDS', a positive number");
        }
    } else if (strcmp(key, "data_size") == 0) {
        if (sscanf(text + used, "%lu", &value) != 1 || value < 8) {
            bad_spec(path, line, "expected 'data_size BYTES'");
        }
        spec.data_size = (size_t)value;
    } else if (strcmp(key, "int_field") == 0) {
        if (sscanf(text + used, "%63s %lu", name, &value) != 2 ||
            spec.n_int_fields == MAX_INT_FIELDS) {
            bad_spec(path, line, "expected 'int_field NAME OFFSET' (at most 16)");
        }
        spec.int_fields[spec.n_int_fields++] = (size_t)value;
    } else {
        bad_spec(path, line, "unknown item (guid, var, range, sample_period, sample_period_s, "
                             "warns_on_change, data_size, int_field)");
    }
}

static void read_spec(const char *path)
{
    char text[512];
    unsigned line = 0, k;
    FILE *file = fopen(path, "r");
    if (!file) {
        fprintf(stderr, "%s: cannot open the FMU spec\n", path);
        exit(2);
    }
    spec.period_vr = -1;
    spec.warn_vr = -1;
    while (fgets(text, sizeof text, file)) {
        spec_line(text, path, ++line);
    }
    fclose(file);
    if (!spec.guid[0] || spec.n_real == 0 || spec.n_outputs == 0 ||
        spec.data_size < 8 * (1 + (size_t)spec.n_real) || spec.period_vr >= (long)spec.n_real) {
        bad_spec(path, 0, "needs a guid, outputs, a data_size holding time and every "
                          "variable, a sample_period among the variables");
    }
    for (k = 0; k < spec.n_int_fields; k++) {
        if (spec.int_fields[k] + sizeof(int) > spec.data_size) {
            bad_spec(path, 0, "an int_field lies outside data_size");
        }
    }
}

typedef struct {
    fmi2InstantiateTYPE *instantiate;
    fmi2FreeInstanceTYPE *free_instance;
    fmi2SetDebugLoggingTYPE *set_debug_logging;
    fmi2SetupExperimentTYPE *setup_experiment;
    fmi2EnterInitializationModeTYPE *enter_initialization;
    fmi2ExitInitializationModeTYPE *exit_initialization;
    fmi2TerminateTYPE *terminate;
    fmi2ResetTYPE *reset;
    fmi2GetRealTYPE *get_real;
    fmi2SetRealTYPE *set_real;
    fmi2GetIntegerTYPE *get_integer;
    fmi2SetIntegerTYPE *set_integer;
    fmi2GetBooleanTYPE *get_boolean;
    fmi2SetBooleanTYPE *set_boolean;
    fmi2GetStringTYPE *get_string;
    fmi2SetStringTYPE *set_string;
    fmi2GetFMUstateTYPE *get_state;
    fmi2SetFMUstateTYPE *set_state;
    fmi2FreeFMUstateTYPE *free_state;
    fmi2SerializedFMUstateSizeTYPE *state_size;
    fmi2SerializeFMUstateTYPE *serialize;
    fmi2DeSerializeFMUstateTYPE *deserialize;
    fmi2GetDirectionalDerivativeTYPE *directional_derivative;
    fmi2SetRealInputDerivativesTYPE *set_input_derivatives;
    fmi2GetRealOutputDerivativesTYPE *get_output_derivatives;
    fmi2DoStepTYPE *do_step;
    fmi2CancelStepTYPE *cancel_step;
    fmi2GetStatusTYPE *get_status;
    fmi2GetRealStatusTYPE *get_real_status;
    fmi2GetIntegerStatusTYPE *get_integer_status;
    fmi2GetBooleanStatusTYPE *get_boolean_status;
    fmi2GetStringStatusTYPE *get_string_status;
} Api;

/* --- findings, counts, logging ----------------------------------------------------------- */

static unsigned long long seed_arg;
static volatile long current_sequence;
static long long calls, error_returns, warning_returns, steps_taken;
static long long error_logs;

static void finding(const char *format, ...)
{
    va_list args;
    fprintf(stderr, "FINDING (seed %llu, sequence %ld): ", seed_arg, (long)current_sequence);
    va_start(args, format);
    vfprintf(stderr, format, args);
    va_end(args);
    fputc('\n', stderr);
    exit(1);
}

static void on_alarm(int sig)
{
    static const char text[] = "FINDING: a sequence did not finish within HANG_S seconds\n";
    (void)sig;
    if (write(2, text, sizeof text - 1) < 0) {
        _exit(4);
    }
    _exit(3);
}

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status,
                   fmi2String category, fmi2String message, ...)
{
    (void)env;
    if (!name || !category || !message || strlen(message) == 0) {
        finding("logger called with a NULL or empty name, category or message");
    }
    if (status == fmi2Error || status == fmi2Fatal) {
        error_logs++;
    }
    if (getenv("FMU_FUZZ_LOG")) { /* set it to see what the FMU says */
        fprintf(stderr, "  [%d] %s\n", (int)status, message);
    }
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

static void load_api(Api *api, const char *path)
{
    void *lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        fprintf(stderr, "dlopen: %s\n", dlerror());
        exit(2);
    }
#define LOAD(field, name) api->field = (name##TYPE *)load(lib, #name)
    LOAD(instantiate, fmi2Instantiate);
    LOAD(free_instance, fmi2FreeInstance);
    LOAD(set_debug_logging, fmi2SetDebugLogging);
    LOAD(setup_experiment, fmi2SetupExperiment);
    LOAD(enter_initialization, fmi2EnterInitializationMode);
    LOAD(exit_initialization, fmi2ExitInitializationMode);
    LOAD(terminate, fmi2Terminate);
    LOAD(reset, fmi2Reset);
    LOAD(get_real, fmi2GetReal);
    LOAD(set_real, fmi2SetReal);
    LOAD(get_integer, fmi2GetInteger);
    LOAD(set_integer, fmi2SetInteger);
    LOAD(get_boolean, fmi2GetBoolean);
    LOAD(set_boolean, fmi2SetBoolean);
    LOAD(get_string, fmi2GetString);
    LOAD(set_string, fmi2SetString);
    LOAD(get_state, fmi2GetFMUstate);
    LOAD(set_state, fmi2SetFMUstate);
    LOAD(free_state, fmi2FreeFMUstate);
    LOAD(state_size, fmi2SerializedFMUstateSize);
    LOAD(serialize, fmi2SerializeFMUstate);
    LOAD(deserialize, fmi2DeSerializeFMUstate);
    LOAD(directional_derivative, fmi2GetDirectionalDerivative);
    LOAD(set_input_derivatives, fmi2SetRealInputDerivatives);
    LOAD(get_output_derivatives, fmi2GetRealOutputDerivatives);
    LOAD(do_step, fmi2DoStep);
    LOAD(cancel_step, fmi2CancelStep);
    LOAD(get_status, fmi2GetStatus);
    LOAD(get_real_status, fmi2GetRealStatus);
    LOAD(get_integer_status, fmi2GetIntegerStatus);
    LOAD(get_boolean_status, fmi2GetBooleanStatus);
    LOAD(get_string_status, fmi2GetStringStatus);
#undef LOAD
}

/* --- random numbers (splitmix64) --------------------------------------------------------- */

static uint64_t rng_state;

static uint64_t next_u64(void)
{
    uint64_t z = (rng_state += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}

static unsigned below(unsigned n)
{
    return (unsigned)(next_u64() % n);
}

static double uniform(double lo, double hi)
{
    return lo + (hi - lo) * ((double)(next_u64() >> 11) / 9007199254740992.0);
}

/* A double from everywhere: ordinary, boundary, huge, tiny, NaN, infinite. */
static double nasty_double(void)
{
    static const double special[] = {0.0, -0.0, 1.0, -1.0, 1e-308, 5e-324, 1e9, -1e9,
                                     1e10, 1e12, 1e300, 1e308, -1e308, 2000.0, 5000.0};
    switch (below(6)) {
    case 0: return NAN;
    case 1: return below(2) ? INFINITY : -INFINITY;
    case 2: return special[below(sizeof special / sizeof special[0])];
    case 3: return uniform(-1e6, 1e6);
    default: return uniform(-100.0, 200.0);
    }
}

/* A communication step: mostly ordinary, sometimes negative, zero, tiny, huge, NaN. */
static double step_size(void)
{
    static const double ordinary[] = {0.1, 0.5, 1.0, 1.2, 2.4, 3.6, 5.0, 12.0, 60.0};
    static const double hostile[] = {0.0, -1.0, -1e-9, 1e-12, 1e-300, 1e5, 1e6, 1.2e6,
                                     1.2e9, 1e300, INFINITY, NAN};
    if (below(4)) {
        return below(3) ? ordinary[below(sizeof ordinary / sizeof ordinary[0])]
                        : uniform(0.01, 30.0);
    }
    return hostile[below(sizeof hostile / sizeof hostile[0])];
}

static fmi2ValueReference any_vr(void)
{
    switch (below(8)) {
    case 0: return (fmi2ValueReference)(spec.n_real + below(4));
    case 1: return (fmi2ValueReference)next_u64();
    default: return (fmi2ValueReference)below(spec.n_real);
    }
}

/* --- the fuzzed instance ----------------------------------------------------------------- */

typedef struct {
    const Api *api;
    const Api *other;
    const char *other_guid;
    fmi2CallbackFunctions callbacks;
    fmi2Component c;
    fmi2FMUstate slots[N_SLOTS];
    int warnings; /* fmi2Warning returns since the last (re)start */
    int settings; /* settings of the warns_on_change input since then */
} Fuzz;

/* Count a setting of the warns_on_change input among vr[0..n). */
static void note_settings(Fuzz *f, const fmi2ValueReference *vr, size_t n)
{
    size_t i;
    for (i = 0; vr && i < n; i++) {
        f->settings += spec.warn_vr >= 0 && vr[i] == (fmi2ValueReference)spec.warn_vr;
    }
}

/* A call returned fmi2Error since the last valid start: the instance is likely in error. */
static int broken;

/* Check a status from a call on the live instance (error_logs taken before the call). */
static fmi2Status seen(fmi2Status status, long long logs_before, const char *call)
{
    calls++;
    if ((int)status < (int)fmi2OK || (int)status > (int)fmi2Pending) {
        finding("%s returned %d, not an fmi2Status", call, (int)status);
    }
    if (status == fmi2Error) {
        error_returns++;
        broken = 1;
        if (error_logs == logs_before) {
            finding("%s returned fmi2Error without logging why", call);
        }
    }
    if (status == fmi2Warning) {
        warning_returns++;
    }
    return status;
}

#define CALL(f, call) (logs_before = error_logs, seen((call), logs_before, #call))

/* The instance's state as serialised bytes (NULL when it cannot be taken, e.g. in error). */
static fmi2Byte *snapshot(Fuzz *f, fmi2FMUstate state, size_t *size)
{
    fmi2FMUstate taken = NULL;
    fmi2Byte *bytes = NULL;
    const Api *api = f->api;
    if (!state && api->get_state(f->c, &taken) != fmi2OK) {
        return NULL; /* taking a state in the error state is refused: nothing to compare */
    }
    if (api->state_size(f->c, state ? state : taken, size) == fmi2OK) {
        bytes = (fmi2Byte *)malloc(*size);
        if (bytes && api->serialize(f->c, state ? state : taken, bytes, *size) != fmi2OK) {
            free(bytes);
            bytes = NULL;
        }
    }
    api->free_state(f->c, &taken);
    return bytes;
}

static void same_snapshot(const fmi2Byte *before, const fmi2Byte *after, size_t size,
                          const char *what)
{
    if (before && (!after || memcmp(before, after, size) != 0)) {
        finding("%s changed after a refused restore", what);
    }
}

static void free_slots(Fuzz *f)
{
    int i;
    for (i = 0; i < N_SLOTS; i++) {
        if (f->slots[i] && f->api->free_state(f->c, &f->slots[i]) != fmi2OK) {
            finding("fmi2FreeFMUstate of a state of this FMU failed");
        }
        f->slots[i] = NULL;
    }
}

static fmi2Component instantiate(Fuzz *f)
{
    return f->api->instantiate("fuzz", fmi2CoSimulation, spec.guid, "file:///nowhere",
                               &f->callbacks, fmi2False, below(2) ? fmi2True : fmi2False);
}

/* --- operations -------------------------------------------------------------------------- */

static void op_lifecycle(Fuzz *f)
{
    const Api *api = f->api;
    long long logs_before;
    switch (below(6)) {
    case 0: {
        const double start = below(3) ? 0.0 : nasty_double();
        CALL(f, api->setup_experiment(f->c, below(2), uniform(0, 1), start, below(2),
                                      nasty_double()));
        break;
    }
    case 1: CALL(f, api->enter_initialization(f->c)); break;
    case 2:
        if (CALL(f, api->exit_initialization(f->c)) == fmi2Warning) {
            f->warnings++;
        }
        break;
    case 3: CALL(f, api->terminate(f->c)); break;
    case 4:
        CALL(f, api->reset(f->c));
        f->warnings = 0;
        f->settings = 0;
        break;
    default: {
        static const char *const categories[] = {"logAll", "logStatusError", "nonsense", NULL};
        const char *chosen[2] = {categories[below(4)], categories[below(4)]};
        CALL(f, api->set_debug_logging(f->c, below(2), below(3), below(8) ? chosen : NULL));
    }
    }
}

/* Set every input to a value drawn from the fractions [from, to] of its plausible range. */
static fmi2Status set_inputs(Fuzz *f, double from, double to)
{
    fmi2Real value[8];
    fmi2ValueReference vr[8];
    size_t i, n = spec.n_inputs < 8 ? spec.n_inputs : 8;
    for (i = 0; i < n; i++) {
        const unsigned k = spec.inputs[i];
        vr[i] = k;
        value[i] = spec.lo[k] + (spec.hi[k] - spec.lo[k]) * uniform(from, to);
    }
    note_settings(f, vr, n);
    return f->api->set_real(f->c, vr, n, value);
}

static void op_set_get(Fuzz *f)
{
    const Api *api = f->api;
    long long logs_before;
    fmi2ValueReference vr[4];
    fmi2Real value[4];
    size_t n = 1 + below(4), i;
    for (i = 0; i < n; i++) {
        vr[i] = any_vr();
        value[i] = nasty_double();
    }
    switch (below(5)) {
    case 0: /* plausible inputs: the run moves on */
        CALL(f, set_inputs(f, 0.0, 1.0));
        break;
    case 1:
        note_settings(f, vr, n);
        CALL(f, api->set_real(f->c, vr, n, below(10) ? value : NULL));
        break;
    case 2: CALL(f, api->get_real(f->c, below(10) ? vr : NULL, n, value)); break;
    case 3: { /* a parameter scaled: large but often still accepted */
        fmi2Real current;
        vr[0] = (fmi2ValueReference)below(spec.n_real);
        if (api->get_real(f->c, vr, 1, &current) == fmi2OK) {
            value[0] = current * (below(2) ? uniform(0.5, 2.0) : uniform(-1e3, 1e3));
            calls++;
            CALL(f, api->set_real(f->c, vr, 1, value));
        }
        break;
    }
    default: {
        fmi2Integer ints[4] = {0};
        fmi2Boolean bools[4] = {0};
        fmi2String strings[4] = {"a", "b", "c", "d"};
        switch (below(6)) {
        case 0: CALL(f, api->get_integer(f->c, vr, n, ints)); break;
        case 1: CALL(f, api->set_integer(f->c, vr, n, ints)); break;
        case 2: CALL(f, api->get_boolean(f->c, vr, n, bools)); break;
        case 3: CALL(f, api->set_boolean(f->c, vr, n, bools)); break;
        case 4: CALL(f, api->get_string(f->c, vr, n, strings)); break;
        default: CALL(f, api->set_string(f->c, vr, below(2) ? 0 : n, strings)); break;
        }
    }
    }
}

static void op_step(Fuzz *f)
{
    const Api *api = f->api;
    long long logs_before;
    fmi2Real now = 0.0, output;
    fmi2Status status;
    unsigned k;
    api->get_real_status(f->c, fmi2LastSuccessfulTime, &now);
    calls++;
    double h = step_size();
    if (!below(6)) {
        now = below(2) ? nasty_double() : now + uniform(-1.0, 1.0);
    }
    if (spec.period_vr >= 0 && below(2)) { /* sampled: whole numbers of samples only */
        fmi2ValueReference period_vr = (fmi2ValueReference)spec.period_vr;
        if (api->get_real(f->c, &period_vr, 1, &h) == fmi2OK) {
            h *= 1 + below(below(8) ? 10 : 20000);
        }
    } else if (spec.period_s > 0.0 && below(4)) { /* one sample, often: what some take only */
        h = spec.period_s * (below(2) ? 1 : 1 + below(below(8) ? 10 : 20000));
    }
    status = CALL(f, api->do_step(f->c, now, h, below(2)));
    if (status == fmi2OK || status == fmi2Warning) {
        f->warnings += status == fmi2Warning;
        steps_taken++;
        for (k = 0; k < spec.n_outputs; k++) {
            output = NAN;
            if (api->get_real(f->c, &spec.outputs[k], 1, &output) != fmi2OK ||
                !isfinite(output)) {
                finding("after a step that returned %d output %u is %g", (int)status,
                        spec.outputs[k], output);
            }
            calls++;
        }
    }
}

static void op_misc(Fuzz *f)
{
    const Api *api = f->api;
    long long logs_before;
    /* an FMU without inputs (a signal source) is asked about its output twice */
    fmi2ValueReference vr[2] = {spec.outputs[0],
                                spec.n_inputs ? spec.inputs[0] : spec.outputs[0]};
    fmi2Real real[2] = {0.0, 0.0}, number;
    fmi2Integer order[2] = {1, 1}, integer;
    fmi2Status status;
    fmi2Boolean boolean;
    fmi2String string;
    const fmi2StatusKind kind = (fmi2StatusKind)below(4);
    switch (below(8)) {
    case 0: CALL(f, api->get_status(f->c, kind, below(8) ? &status : NULL)); break;
    case 1: CALL(f, api->get_real_status(f->c, kind, below(8) ? &number : NULL)); break;
    case 2: CALL(f, api->get_integer_status(f->c, kind, &integer)); break;
    case 3: CALL(f, api->get_boolean_status(f->c, kind, &boolean)); break;
    case 4: CALL(f, api->get_string_status(f->c, kind, &string)); break;
    case 5: CALL(f, api->cancel_step(f->c)); break;
    case 6: CALL(f, api->directional_derivative(f->c, vr, 1, vr + 1, 1, real, real + 1)); break;
    default:
        CALL(f, below(2) ? api->set_input_derivatives(f->c, vr + 1, 1, order, real)
                         : api->get_output_derivatives(f->c, vr, 1, order, real));
    }
}

static void op_state(Fuzz *f)
{
    const Api *api = f->api;
    long long logs_before;
    const unsigned slot = below(N_SLOTS);
    switch (below(5)) {
    case 0: CALL(f, api->get_state(f->c, &f->slots[slot])); break;
    case 1: {
        size_t size = 0;
        fmi2Byte *before = snapshot(f, NULL, &size), *after;
        if (CALL(f, api->set_state(f->c, f->slots[slot])) == fmi2Error) {
            after = snapshot(f, NULL, &size);
            same_snapshot(before, after, size, "the instance");
            free(after);
        } else {
            f->warnings = 0; /* the restored state says whether it warned */
            f->settings = 0;
        }
        free(before);
        break;
    }
    case 2: CALL(f, api->free_state(f->c, &f->slots[slot])); break;
    case 3: {
        size_t size = 0;
        fmi2Byte *bytes;
        if (!f->slots[slot] || api->state_size(f->c, f->slots[slot], &size) != fmi2OK) {
            break;
        }
        bytes = (fmi2Byte *)malloc(size);
        if (CALL(f, api->serialize(f->c, f->slots[slot], bytes, size)) == fmi2OK &&
            CALL(f, api->deserialize(f->c, bytes, size, &f->slots[below(N_SLOTS)])) != fmi2OK) {
            finding("a state this FMU serialised was refused");
        }
        free(bytes);
        break;
    }
    default: CALL(f, api->state_size(f->c, f->slots[slot], NULL)); break;
    }
}

/* Where a serialised state keeps ModelData: the payload ends with it. */
static size_t data_offset(size_t size)
{
    return size - spec.data_size;
}

static void put_int(fmi2Byte *bytes, size_t at, int value)
{
    memcpy(bytes + at, &value, sizeof value);
}

static void put_double(fmi2Byte *bytes, size_t at, double value)
{
    memcpy(bytes + at, &value, sizeof value);
}

static int nasty_int(void)
{
    static const int special[] = {-1, 0, 1, 2, 3, 7, 16, 31, INT_MAX, INT_MIN, 4095, 4096, 4097};
    return below(4) ? special[below(sizeof special / sizeof special[0])] : (int)next_u64();
}

/* Damage a serialised state in one of several ways; size may change. */
static void tamper(fmi2Byte **bytes, size_t *size)
{
    const size_t data = data_offset(*size);
    if (*size < spec.data_size + 96) {
        finding("a serialised state of %lu bytes cannot hold a header and ModelData (%lu bytes)",
                (unsigned long)*size, (unsigned long)spec.data_size);
    }
    switch (below(8)) {
    case 0: { /* flip a few bytes anywhere */
        unsigned k, n = 1 + below(4);
        for (k = 0; k < n; k++) {
            (*bytes)[below((unsigned)*size)] ^= (fmi2Byte)(1u << below(8));
        }
        break;
    }
    case 1: /* the header: format, GUID, payload size */
        (*bytes)[below((unsigned)(data < 96 ? data : 96))] ^= (fmi2Byte)(1 + below(255));
        break;
    case 2: /* the mode, just before ModelData */
        put_int(*bytes, data - 8, nasty_int());
        break;
    case 3: /* an int of the component: a flag, a ring index, a count */
    case 5:
        if (spec.n_int_fields && below(4)) {
            put_int(*bytes, data + spec.int_fields[below(spec.n_int_fields)], nasty_int());
        } else { /* any int-sized word */
            put_int(*bytes, data + 4 * below((unsigned)(spec.data_size / 4)), nasty_int());
        }
        break;
    case 4: /* a double of the state or of the variables */
        put_double(*bytes, data + sizeof(double) * below((unsigned)(spec.data_size / 8)),
                   nasty_double());
        break;
    case 6: /* truncated */
        *size = below(2) ? *size - 1 - below((unsigned)*size - 1) : *size - 1;
        break;
    default: { /* extended by a few bytes */
        fmi2Byte *longer = (fmi2Byte *)realloc(*bytes, *size + 8);
        if (longer) {
            memset(longer + *size, 0x5a, 8);
            *bytes = longer;
            *size += 1 + below(8);
        }
    }
    }
}

/* An accepted serialised state holds a finite time and finite variables (ModelData starts
 * with time_s and real[], component.h). */
static void check_finite(const fmi2Byte *bytes, size_t size)
{
    const size_t data = data_offset(size);
    unsigned k;
    double value;
    for (k = 0; k <= spec.n_real; k++) {
        memcpy(&value, bytes + data + sizeof(double) * k, sizeof value);
        if (!isfinite(value)) {
            finding("a state with %s %g was accepted", k ? "a variable" : "time", value);
        }
    }
}

static void op_tampered_state(Fuzz *f)
{
    const Api *api = f->api;
    long long logs_before;
    fmi2FMUstate taken = NULL;
    const unsigned slot = below(N_SLOTS);
    size_t size = 0, target_size = 0;
    fmi2Byte *bytes, *target_before, *target_after, *before, *after;
    fmi2Status status;
    if (api->get_state(f->c, &taken) != fmi2OK ||
        api->state_size(f->c, taken, &size) != fmi2OK) {
        api->free_state(f->c, &taken);
        return;
    }
    bytes = (fmi2Byte *)malloc(size);
    api->serialize(f->c, taken, bytes, size);
    api->free_state(f->c, &taken);
    tamper(&bytes, &size);
    target_before = f->slots[slot] ? snapshot(f, f->slots[slot], &target_size) : NULL;
    status = CALL(f, api->deserialize(f->c, bytes, size, &f->slots[slot]));
    if (status == fmi2OK) {
        check_finite(bytes, size);
    }
    free(bytes);
    if (status != fmi2OK) {
        target_after = f->slots[slot] ? snapshot(f, f->slots[slot], &target_size) : NULL;
        same_snapshot(target_before, target_after, target_size, "the state to overwrite");
        free(target_after);
        free(target_before);
        return;
    }
    free(target_before);
    /* accepted: it passed every check, so restoring it and stepping must be safe */
    before = snapshot(f, NULL, &size);
    if (CALL(f, api->set_state(f->c, f->slots[slot])) == fmi2Error) {
        after = snapshot(f, NULL, &size);
        same_snapshot(before, after, size, "the instance");
        free(after);
    } else {
        f->warnings = 0;
        f->settings = 0;
    }
    free(before);
    op_step(f);
}

/* States and serialised states of another FMU must be refused without harm. */
static void op_foreign_state(Fuzz *f)
{
    const Api *api = f->api, *other = f->other;
    long long logs_before;
    fmi2Component oc;
    fmi2FMUstate foreign = NULL, mine = NULL;
    size_t size = 0;
    fmi2Byte *bytes;
    if (!other) {
        return;
    }
    oc = other->instantiate("other", fmi2CoSimulation, f->other_guid, "", &f->callbacks,
                            fmi2False, fmi2False);
    if (!oc || other->get_state(oc, &foreign) != fmi2OK ||
        other->state_size(oc, foreign, &size) != fmi2OK) {
        finding("the other FMU did not instantiate or give a state");
    }
    bytes = (fmi2Byte *)malloc(size);
    other->serialize(oc, foreign, bytes, size);
    if (CALL(f, api->set_state(f->c, foreign)) != fmi2Error ||
        CALL(f, api->deserialize(f->c, bytes, size, &mine)) != fmi2Error || mine != NULL ||
        CALL(f, api->serialize(f->c, foreign, bytes, size)) != fmi2Error) {
        finding("a state of another FMU was accepted");
    }
    free(bytes);
    other->free_state(oc, &foreign);
    other->free_instance(oc);
}

static void op_recycle(Fuzz *f)
{
    if (below(2)) {
        free_slots(f);
    }
    f->api->free_instance(f->c);
    f->c = instantiate(f);
    f->warnings = 0;
    f->settings = 0;
    if (!f->c) {
        finding("fmi2Instantiate failed with valid arguments");
    }
}

static void one_call(Fuzz *f)
{
    /* half the time, an instance in error is started again, so that most calls reach deep */
    switch (broken && below(2) ? 19 : below(20)) {
    case 0:
    case 1: op_lifecycle(f); break;
    case 2:
    case 3:
    case 4:
    case 5: op_set_get(f); break;
    case 6:
    case 7:
    case 8:
    case 9:
    case 10: op_step(f); break;
    case 11:
    case 12:
    case 13: op_state(f); break;
    case 14:
    case 15: op_tampered_state(f); break;
    case 16: op_misc(f); break;
    case 17: op_foreign_state(f); break;
    case 18: op_recycle(f); break;
    default: { /* a valid start, so that most sequences reach step mode */
        const Api *api = f->api;
        api->reset(f->c);
        api->setup_experiment(f->c, fmi2False, 0.0, uniform(-100.0, 100.0), fmi2False, 0.0);
        api->enter_initialization(f->c);
        set_inputs(f, 0.05, 0.75); /* well inside the plausible range */
        f->warnings = api->exit_initialization(f->c) == fmi2Warning;
        f->settings = 0; /* the start's own warning is the one allowed */
        calls += 5;
        broken = 0;
    }
    }
    if (f->warnings > 1 + f->settings) {
        finding("more than one fmi2Warning since the instance started (and one per setting "
                "of the warns_on_change input)");
    }
}

/* Calls that must fail cleanly without an instance. */
static void hostile_instantiate(const Api *api, fmi2CallbackFunctions *callbacks)
{
    fmi2CallbackFunctions none = {NULL, NULL, NULL, NULL, NULL};
    if (api->instantiate("x", fmi2CoSimulation, "{wrong}", "", callbacks, 0, 0) ||
        api->instantiate("x", fmi2ModelExchange, spec.guid, "", callbacks, 0, 0) ||
        api->instantiate("", fmi2CoSimulation, spec.guid, "", callbacks, 0, 0) ||
        api->instantiate(NULL, fmi2CoSimulation, spec.guid, "", callbacks, 0, 0) ||
        api->instantiate("x", fmi2CoSimulation, NULL, "", callbacks, 0, 0) ||
        api->instantiate("x", fmi2CoSimulation, spec.guid, "", NULL, 0, 0)) {
        finding("fmi2Instantiate accepted bad arguments");
    }
    if (api->do_step(NULL, 0.0, 1.0, fmi2True) != fmi2Error ||
        api->get_real(NULL, NULL, 0, NULL) != fmi2Error) {
        finding("a call without an instance did not return fmi2Error");
    }
    {
        fmi2Component c = api->instantiate("nolog", fmi2CoSimulation, spec.guid, "", &none, 0, 1);
        if (c) { /* no logger, default memory functions: must still work */
            api->do_step(c, 0.0, 1.0, fmi2True);
            api->free_instance(c);
        }
    }
    calls += 9;
}

int main(int argc, char **argv)
{
    Api api, other;
    Fuzz f;
    long sequences, s;
    struct timespec t0, t1;
    if (argc != 5 && argc != 7) {
        fprintf(stderr, "usage: %s BINARY SPEC SEED SEQUENCES [OTHER_BINARY OTHER_GUID]\n",
                argv[0]);
        return 2;
    }
    read_spec(argv[2]);
    load_api(&api, argv[1]);
    seed_arg = strtoull(argv[3], NULL, 10);
    sequences = atol(argv[4]);
    memset(&f, 0, sizeof f);
    f.api = &api;
    if (argc == 7) {
        load_api(&other, argv[5]);
        f.other = &other;
        f.other_guid = argv[6];
    }
    f.callbacks.logger = logger;
    f.callbacks.allocateMemory = calloc;
    f.callbacks.freeMemory = free;
    signal(SIGALRM, on_alarm);
    clock_gettime(CLOCK_MONOTONIC, &t0);
    rng_state = seed_arg;
    hostile_instantiate(&api, &f.callbacks);
    for (s = 0; s < sequences; s++) {
        unsigned n, k;
        current_sequence = s;
        rng_state = seed_arg * 0x100000001b3ull + (uint64_t)s;
        alarm(HANG_S);
        f.c = instantiate(&f);
        f.warnings = 0;
        f.settings = 0;
        if (!f.c) {
            finding("fmi2Instantiate failed with valid arguments");
        }
        n = 1 + below(MAX_CALLS);
        for (k = 0; k < n; k++) {
            one_call(&f);
        }
        free_slots(&f);
        api.free_instance(f.c);
        calls += 1;
    }
    alarm(0);
    free(spec.kind), free(spec.start), free(spec.lo), free(spec.hi);
    free(spec.inputs), free(spec.outputs);
    clock_gettime(CLOCK_MONOTONIC, &t1);
    printf("fuzz: %ld sequences, %lld calls, %lld steps taken, %lld fmi2Error, %lld fmi2Warning, "
           "%.2f s\n",
           sequences, calls, steps_taken, error_returns, warning_returns,
           (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec));
    return 0;
}
