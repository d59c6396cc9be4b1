/* Generic FMI 3.0 co-simulation glue of every gatetwin C FMU. Never changes per model.
 *
 * The FMI 3.0 rendering of the same component as fmi2_glue.c: it talks to the model only through
 * component.h, and model_config.h (generated: instantiation token, value references, start values)
 * is the one the FMI 2.0 FMU gets. Every variable is a scalar Float64.
 *
 * Policy, as in the FMI 2.0 glue: a call the FMU cannot honour (wrong state, bad pointer,
 * unknown value reference, bad input, a step size it cannot take, a capability the model
 * description does not declare) returns fmi3Error with a logged reason and moves the instance
 * to the error state; fmi3SetFMUState or fmi3Reset recover from it. A refused FMU state
 * (fmi3SetFMUState, fmi3DeserializeFMUState) leaves the instance as it was, in its mode.
 * Warnings and errors are always logged; informational messages only when logging is on.
 * fmi3DoStep never returns early and never asks for event handling (hasEventMode="false").
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "component.h"

#define INSTANCE_MAGIC 0x67746633u /* "gtf3" */
#define STATE_MAGIC 0x73743346u    /* "st3F" */
#define SERIAL_FORMAT "gatetwin-state-3"
/* The independent variable `time` follows the component's Real variables (see
 * gatetwin.fmu.description3). */
#define VR_TIME GT_N_REAL

typedef enum {
    MODE_INSTANTIATED = 1,
    MODE_INITIALIZATION = 2,
    MODE_STEP = 4,
    MODE_TERMINATED = 8,
    MODE_ERROR = 16
} Mode;

#define ANY_MODE (MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_STEP | MODE_TERMINATED | MODE_ERROR)

/* Where messages go: small, so the instantiate functions can log before allocating. */
typedef struct {
    char name[128];
    fmi3InstanceEnvironment environment;
    fmi3LogMessageCallback logger;
    fmi3Boolean logging_on;
} LogTarget;

typedef struct {
    unsigned magic;
    LogTarget sink;
    Mode mode;
    ModelData data;
} Instance;

/* What an FMU state holds and serialises: everything in ModelData and the mode it was taken
 * in. */
typedef struct {
    Mode mode;
    ModelData data;
} StatePayload;

/* An FMU state in memory; `owner` tells states of this library from another FMU's. */
typedef struct {
    unsigned magic;
    const void *owner;
    StatePayload payload;
} StoredState;

#define STATE_OWNER ((const void *)plant_variables)

typedef struct {
    char format[17]; /* SERIAL_FORMAT */
    char token[64];  /* GT_GUID: a state only fits the build it came from */
    unsigned long long payload_size;
} SerialHeader;

/* --- logging --------------------------------------------------------------------------------- */

static void log_text(const LogTarget *sink, fmi3Status status, const char *text)
{
    static const char *const category[] = {"logAll", "logStatusWarning", "logStatusWarning",
                                           "logStatusError", "logStatusError"};
    if (!sink->logger || (status == fmi3OK && !sink->logging_on)) {
        return;
    }
    sink->logger(sink->environment, status, category[status <= fmi3Fatal ? status : fmi3Error],
                 text);
}

#if defined(__GNUC__)
static void log_message(const LogTarget *sink, fmi3Status status, const char *format, ...)
    __attribute__((format(printf, 3, 4)));
static fmi3Status fail(Instance *inst, const char *format, ...)
    __attribute__((format(printf, 2, 3)));
static fmi3Status refuse(Instance *inst, const char *format, ...)
    __attribute__((format(printf, 2, 3)));
#endif

static void log_message(const LogTarget *sink, fmi3Status status, const char *format, ...)
{
    char text[768];
    va_list args;
    va_start(args, format);
    vsnprintf(text, sizeof text, format, args);
    va_end(args);
    log_text(sink, status, text);
}

/* Log why, enter the error state, return fmi3Error. */
static fmi3Status fail(Instance *inst, const char *format, ...)
{
    char text[768];
    va_list args;
    va_start(args, format);
    vsnprintf(text, sizeof text, format, args);
    va_end(args);
    log_text(&inst->sink, fmi3Error, text);
    inst->mode = MODE_ERROR;
    return fmi3Error;
}

/* Log why and return fmi3Error, leaving the instance as it was (refused FMU states). */
static fmi3Status refuse(Instance *inst, const char *format, ...)
{
    char text[768];
    va_list args;
    va_start(args, format);
    vsnprintf(text, sizeof text, format, args);
    va_end(args);
    log_text(&inst->sink, fmi3Error, text);
    return fmi3Error;
}

static const char *mode_name(Mode mode)
{
    switch (mode) {
    case MODE_INSTANTIATED: return "instantiated";
    case MODE_INITIALIZATION: return "initialization mode";
    case MODE_STEP: return "step mode";
    case MODE_TERMINATED: return "terminated";
    default: return "error";
    }
}

/* The instance behind c if c is one and the call is legal in its mode, else NULL. */
static Instance *checked(fmi3Instance c, const char *function, unsigned allowed_modes)
{
    Instance *inst = (Instance *)c;
    if (!inst || inst->magic != INSTANCE_MAGIC) {
        return NULL;
    }
    if (!(inst->mode & allowed_modes)) {
        fail(inst, "%s must not be called in %s", function, mode_name(inst->mode));
        return NULL;
    }
    return inst;
}

/* Status of a plant call, logged; errors enter the error state. */
static fmi3Status report(Instance *inst, PlantStatus status, const PlantMessage *msg)
{
    if (status == PLANT_ERROR) {
        return fail(inst, "%s", msg->text);
    }
    if (status == PLANT_WARNING) {
        log_text(&inst->sink, fmi3Warning, msg->text);
        return fmi3Warning;
    }
    return fmi3OK;
}

/* A function of a capability the model description does not declare. */
static fmi3Status unsupported(fmi3Instance c, const char *function, const char *why)
{
    Instance *inst = checked(c, function, ANY_MODE);
    return inst ? fail(inst, "%s: not supported (%s)", function, why) : fmi3Error;
}

/* --- inquire version, logging ---------------------------------------------------------------- */

const char *fmi3GetVersion(void)
{
    return fmi3Version;
}

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[])
{
    static const char *const known[] = GT_LOG_CATEGORIES;
    Instance *inst = checked(instance, "fmi3SetDebugLogging", ANY_MODE);
    size_t i, k;
    if (!inst) {
        return fmi3Error;
    }
    if (nCategories > 0 && !categories) {
        return fail(inst, "fmi3SetDebugLogging: categories is NULL");
    }
    for (i = 0; i < nCategories; i++) {
        int found = 0;
        for (k = 0; k < sizeof known / sizeof known[0]; k++) {
            found = found || (categories[i] && strcmp(categories[i], known[k]) == 0);
        }
        if (!found) {
            return fail(inst, "fmi3SetDebugLogging: unknown log category '%s'",
                        categories[i] ? categories[i] : "(NULL)");
        }
    }
    inst->sink.logging_on = loggingOn;
    return fmi3OK;
}

/* --- creation and destruction ---------------------------------------------------------------- */

/* Why the arguments of fmi3InstantiateCoSimulation cannot be honoured, or NULL. */
static const char *instantiation_problem(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3Boolean eventModeUsed,
                                         size_t nRequiredIntermediateVariables)
{
    if (!instanceName || instanceName[0] == '\0') {
        return "instanceName must be a non-empty string";
    }
    if (!instantiationToken || strcmp(instantiationToken, GT_GUID) != 0) {
        return "instantiationToken does not match this FMU's";
    }
    if (eventModeUsed) {
        return "eventModeUsed: this FMU has no event mode (hasEventMode=\"false\")";
    }
    if (nRequiredIntermediateVariables > 0) {
        return "requiredIntermediateVariables: this FMU provides no intermediate update";
    }
    return NULL;
}

fmi3Instance fmi3InstantiateCoSimulation(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
    fmi3Boolean earlyReturnAllowed, const fmi3ValueReference requiredIntermediateVariables[],
    size_t nRequiredIntermediateVariables, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3IntermediateUpdateCallback intermediateUpdate)
{
    LogTarget sink;
    Instance *inst;
    const char *problem = instantiation_problem(instanceName, instantiationToken, eventModeUsed,
                                                nRequiredIntermediateVariables);
    (void)resourcePath, (void)visible, (void)earlyReturnAllowed;
    (void)requiredIntermediateVariables, (void)intermediateUpdate;
    memset(&sink, 0, sizeof sink);
    sink.environment = instanceEnvironment;
    sink.logger = logMessage;
    sink.logging_on = loggingOn;
    snprintf(sink.name, sizeof sink.name, "%s", instanceName ? instanceName : "(NULL)");
    if (problem) {
        log_message(&sink, fmi3Error, "fmi3InstantiateCoSimulation: %s", problem);
        return NULL;
    }
    inst = (Instance *)calloc(1, sizeof *inst);
    if (!inst) {
        log_text(&sink, fmi3Error, "fmi3InstantiateCoSimulation: out of memory");
        return NULL;
    }
    inst->magic = INSTANCE_MAGIC;
    inst->sink = sink;
    inst->mode = MODE_INSTANTIATED;
    plant_set_defaults(&inst->data);
    log_text(&inst->sink, fmi3OK, "instantiated " GT_MODEL_IDENTIFIER);
    return inst;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible,
                                          fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage)
{
    (void)instantiationToken, (void)resourcePath, (void)visible, (void)loggingOn;
    if (logMessage) {
        logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                   "fmi3InstantiateModelExchange: this FMU supports co-simulation only");
    }
    (void)instanceName;
    return NULL;
}

fmi3Instance fmi3InstantiateScheduledExecution(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
    fmi3LockPreemptionCallback lockPreemption, fmi3UnlockPreemptionCallback unlockPreemption)
{
    (void)instanceName, (void)instantiationToken, (void)resourcePath, (void)visible;
    (void)loggingOn, (void)clockUpdate, (void)lockPreemption, (void)unlockPreemption;
    if (logMessage) {
        logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                   "fmi3InstantiateScheduledExecution: this FMU supports co-simulation only");
    }
    return NULL;
}

void fmi3FreeInstance(fmi3Instance instance)
{
    Instance *inst = checked(instance, "fmi3FreeInstance", ANY_MODE);
    if (inst) {
        inst->magic = 0;
        free(inst);
    }
}

/* --- initialisation, termination, reset ------------------------------------------------------ */

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined,
                                       fmi3Float64 tolerance, fmi3Float64 startTime,
                                       fmi3Boolean stopTimeDefined, fmi3Float64 stopTime)
{
    Instance *inst = checked(instance, "fmi3EnterInitializationMode", MODE_INSTANTIATED);
    (void)toleranceDefined, (void)tolerance, (void)stopTimeDefined, (void)stopTime;
    if (!inst) {
        return fmi3Error;
    }
    if (!(fabs(startTime) <= GT_MAX_TIME_S)) {
        return fail(inst,
                    "fmi3EnterInitializationMode: startTime %g s must be finite with |t| <= %g s",
                    startTime, GT_MAX_TIME_S);
    }
    inst->data.time_s = startTime;
    inst->mode = MODE_INITIALIZATION;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance)
{
    Instance *inst = checked(instance, "fmi3ExitInitializationMode", MODE_INITIALIZATION);
    PlantMessage msg;
    PlantStatus status;
    if (!inst) {
        return fmi3Error;
    }
    status = plant_initialize(&inst->data, &msg);
    if (status != PLANT_ERROR) {
        inst->mode = MODE_STEP;
    }
    return report(inst, status, &msg);
}

fmi3Status fmi3EnterEventMode(fmi3Instance instance)
{
    return unsupported(instance, "fmi3EnterEventMode", "hasEventMode=\"false\"");
}

fmi3Status fmi3EnterStepMode(fmi3Instance instance)
{
    return unsupported(instance, "fmi3EnterStepMode", "hasEventMode=\"false\": "
                                                      "fmi3ExitInitializationMode enters step mode");
}

fmi3Status fmi3Terminate(fmi3Instance instance)
{
    Instance *inst = checked(instance, "fmi3Terminate", MODE_STEP);
    if (!inst) {
        return fmi3Error;
    }
    inst->mode = MODE_TERMINATED;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance instance)
{
    Instance *inst = checked(instance, "fmi3Reset", ANY_MODE);
    if (!inst) {
        return fmi3Error;
    }
    plant_set_defaults(&inst->data);
    inst->mode = MODE_INSTANTIATED;
    return fmi3OK;
}

/* --- getting and setting values -------------------------------------------------------------- */

/* Every variable is a scalar: exactly one value per value reference. */
static fmi3Status check_arrays(Instance *inst, const char *function, const void *vr, size_t nvr,
                               const void *values, size_t nValues)
{
    if (nvr > 0 && (!vr || !values)) {
        return fail(inst, "%s: NULL value-reference or value array", function);
    }
    if (nValues != nvr) {
        return fail(inst, "%s: %lu values for %lu scalar variables", function,
                    (unsigned long)nValues, (unsigned long)nvr);
    }
    return fmi3OK;
}

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, fmi3Float64 values[], size_t nValues)
{
    Instance *inst = checked(instance, "fmi3GetFloat64", ANY_MODE);
    size_t i;
    if (!inst || check_arrays(inst, "fmi3GetFloat64", valueReferences, nValueReferences, values,
                              nValues) != fmi3OK) {
        return fmi3Error;
    }
    for (i = 0; i < nValueReferences; i++) {
        const fmi3ValueReference vr = valueReferences[i];
        if (vr == VR_TIME) {
            values[i] = inst->data.time_s;
            continue;
        }
        if (vr > VR_TIME) {
            return fail(inst, "fmi3GetFloat64: no Float64 variable has value reference %u",
                        (unsigned)vr);
        }
        if (plant_variables[vr].kind == GT_KIND_OUTPUT) {
            PlantMessage msg;
            if (plant_output(&inst->data, vr, &values[i], &msg) != PLANT_OK) {
                return fail(inst, "fmi3GetFloat64: %s", msg.text);
            }
        } else {
            values[i] = inst->data.real[vr];
        }
    }
    return fmi3OK;
}

/* Why value cannot be set into variable vr in mode, or NULL. */
static const char *set_problem(fmi3ValueReference vr, Mode mode, double value)
{
    if (vr == VR_TIME) {
        return "is the independent variable";
    }
    if (vr > VR_TIME) {
        return "no Float64 variable has this value reference";
    }
    if (plant_variables[vr].kind == GT_KIND_OUTPUT) {
        return "is an output";
    }
    if (plant_variables[vr].kind == GT_KIND_FIXED && mode == MODE_STEP) {
        return "is a fixed parameter, settable only before fmi3ExitInitializationMode";
    }
    if (!isfinite(value)) { /* every value an FMU state holds stays finite */
        return "must be finite";
    }
    return NULL;
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, const fmi3Float64 values[], size_t nValues)
{
    Instance *inst = checked(instance, "fmi3SetFloat64",
                             MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_STEP);
    size_t i;
    if (!inst || check_arrays(inst, "fmi3SetFloat64", valueReferences, nValueReferences, values,
                              nValues) != fmi3OK) {
        return fmi3Error;
    }
    for (i = 0; i < nValueReferences; i++) {
        const fmi3ValueReference vr = valueReferences[i];
        const char *problem = set_problem(vr, inst->mode, values[i]);
        if (problem) {
            return fail(inst, "fmi3SetFloat64: %s (value reference %u) = %g: %s",
                        vr < GT_N_REAL ? plant_variables[vr].name : "?", (unsigned)vr,
                        values[i], problem);
        }
        inst->data.real[vr] = values[i];
        if (plant_variables[vr].kind != GT_KIND_INPUT) {
            inst->data.parameters_changed = 1;
        }
    }
    return fmi3OK;
}

/* The model has Float64 variables only: any other type's value reference is unknown. */
static fmi3Status no_such_variables(fmi3Instance instance, const char *function,
                                    const fmi3ValueReference vr[], size_t nvr,
                                    const void *values, size_t nValues)
{
    Instance *inst = checked(instance, function, ANY_MODE);
    if (!inst || check_arrays(inst, function, vr, nvr, values, nValues) != fmi3OK) {
        return fmi3Error;
    }
    if (nvr > 0) {
        return fail(inst, "%s: no variable of this type has value reference %u", function,
                    (unsigned)vr[0]);
    }
    return fmi3OK;
}

#define NO_VARIABLES_OF(TYPE)                                                                   \
    fmi3Status fmi3Get##TYPE(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, \
                             fmi3##TYPE values[], size_t nValues)                              \
    {                                                                                           \
        return no_such_variables(instance, "fmi3Get" #TYPE, vr, nvr, values, nValues);         \
    }                                                                                           \
    fmi3Status fmi3Set##TYPE(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, \
                             const fmi3##TYPE values[], size_t nValues)                        \
    {                                                                                           \
        return no_such_variables(instance, "fmi3Set" #TYPE, vr, nvr, values, nValues);         \
    }

NO_VARIABLES_OF(Float32)
NO_VARIABLES_OF(Int8)
NO_VARIABLES_OF(UInt8)
NO_VARIABLES_OF(Int16)
NO_VARIABLES_OF(UInt16)
NO_VARIABLES_OF(Int32)
NO_VARIABLES_OF(UInt32)
NO_VARIABLES_OF(Int64)
NO_VARIABLES_OF(UInt64)
NO_VARIABLES_OF(Boolean)
NO_VARIABLES_OF(String)

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                         size_t valueSizes[], fmi3Binary values[], size_t nValues)
{
    (void)valueSizes;
    return no_such_variables(instance, "fmi3GetBinary", vr, nvr, values, nValues);
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                         const size_t valueSizes[], const fmi3Binary values[], size_t nValues)
{
    (void)valueSizes;
    return no_such_variables(instance, "fmi3SetBinary", vr, nvr, values, nValues);
}

fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                        fmi3Clock values[])
{
    return no_such_variables(instance, "fmi3GetClock", vr, nvr, values, nvr);
}

fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                        const fmi3Clock values[])
{
    return no_such_variables(instance, "fmi3SetClock", vr, nvr, values, nvr);
}

/* --- FMU state ------------------------------------------------------------------------------- */

/* Whether a stored state can be restored into this FMU: its mode and ModelData (component.h). */
static fmi3Status check_payload(Instance *inst, const char *function, const StatePayload *p)
{
    PlantMessage msg;
    int initialized;
    switch (p->mode) {
    case MODE_INSTANTIATED:
    case MODE_INITIALIZATION: initialized = 0; break;
    case MODE_STEP:
    case MODE_TERMINATED: initialized = 1; break;
    default:
        return refuse(inst, "%s: the state's mode %d is not a mode a state is taken in", function,
                      (int)p->mode);
    }
    if (plant_check_state(&p->data, initialized, &msg) != PLANT_OK) {
        return refuse(inst, "%s: corrupt state refused, the instance is unchanged: %s", function,
                      msg.text);
    }
    return fmi3OK;
}

/* The state behind an FMUState argument if it is one of this library's, else NULL. */
static StoredState *own_state(fmi3FMUState FMUState)
{
    StoredState *stored = (StoredState *)FMUState;
    if (!stored || stored->magic != STATE_MAGIC || stored->owner != STATE_OWNER) {
        return NULL;
    }
    return stored;
}

static StoredState *new_state(void)
{
    StoredState *stored = (StoredState *)calloc(1, sizeof *stored);
    if (stored) {
        stored->magic = STATE_MAGIC;
        stored->owner = STATE_OWNER;
    }
    return stored;
}

static void free_state(StoredState *stored)
{
    stored->magic = 0;
    free(stored);
}

fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState)
{
    Instance *inst = checked(instance, "fmi3GetFMUState", ANY_MODE ^ MODE_ERROR);
    StoredState *stored;
    if (!inst) {
        return fmi3Error;
    }
    if (!FMUState) {
        return fail(inst, "fmi3GetFMUState: FMUState is NULL");
    }
    stored = own_state(*FMUState);
    if (*FMUState && !stored) {
        return fail(inst, "fmi3GetFMUState: *FMUState is not a state of this FMU");
    }
    if (!stored) {
        stored = new_state();
        if (!stored) {
            return fail(inst, "fmi3GetFMUState: out of memory");
        }
    }
    stored->payload.mode = inst->mode;
    memcpy(&stored->payload.data, &inst->data, sizeof inst->data);
    *FMUState = stored;
    return fmi3OK;
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState)
{
    Instance *inst = checked(instance, "fmi3SetFMUState", ANY_MODE);
    const StoredState *stored = own_state(FMUState);
    if (!inst) {
        return fmi3Error;
    }
    if (!stored) {
        return refuse(inst, "fmi3SetFMUState: FMUState is NULL or not a state of this FMU");
    }
    if (check_payload(inst, "fmi3SetFMUState", &stored->payload) != fmi3OK) {
        return fmi3Error;
    }
    memcpy(&inst->data, &stored->payload.data, sizeof inst->data);
    inst->mode = stored->payload.mode;
    return fmi3OK;
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState)
{
    Instance *inst = checked(instance, "fmi3FreeFMUState", ANY_MODE);
    StoredState *stored;
    if (!inst) {
        return fmi3Error;
    }
    if (!FMUState || !*FMUState) {
        return fmi3OK;
    }
    stored = own_state(*FMUState);
    if (!stored) {
        return fail(inst, "fmi3FreeFMUState: *FMUState is not a state of this FMU");
    }
    free_state(stored);
    *FMUState = NULL;
    return fmi3OK;
}

/* Bytes of a serialised state: the header, then the payload. */
#define SERIAL_SIZE (sizeof(SerialHeader) + sizeof(StatePayload))

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState, size_t *size)
{
    Instance *inst = checked(instance, "fmi3SerializedFMUStateSize", ANY_MODE);
    (void)FMUState;
    if (!inst) {
        return fmi3Error;
    }
    if (!size) {
        return fail(inst, "fmi3SerializedFMUStateSize: size is NULL");
    }
    *size = SERIAL_SIZE;
    return fmi3OK;
}

fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState,
                                 fmi3Byte serializedState[], size_t size)
{
    Instance *inst = checked(instance, "fmi3SerializeFMUState", ANY_MODE);
    const StoredState *stored = own_state(FMUState);
    SerialHeader header;
    if (!inst) {
        return fmi3Error;
    }
    if (!stored || !serializedState) {
        return fail(inst, "fmi3SerializeFMUState: NULL buffer, or FMUState is not a state of "
                          "this FMU");
    }
    if (size != SERIAL_SIZE) {
        return fail(inst, "fmi3SerializeFMUState: buffer holds %lu bytes, the state needs %lu",
                    (unsigned long)size, (unsigned long)SERIAL_SIZE);
    }
    memset(&header, 0, sizeof header);
    memcpy(header.format, SERIAL_FORMAT, sizeof SERIAL_FORMAT);
    snprintf(header.token, sizeof header.token, "%s", GT_GUID);
    header.payload_size = sizeof stored->payload;
    memcpy(serializedState, &header, sizeof header);
    memcpy(serializedState + sizeof header, &stored->payload, sizeof stored->payload);
    return fmi3OK;
}

/* Why a serialised state's header does not fit this FMU, or NULL. */
static const char *header_problem(const SerialHeader *header)
{
    if (memcmp(header->format, SERIAL_FORMAT, sizeof SERIAL_FORMAT) != 0) {
        return "not a serialised state of format " SERIAL_FORMAT;
    }
    if (strncmp(header->token, GT_GUID, sizeof header->token) != 0) {
        return "the state is of another FMU (instantiation token differs)";
    }
    if (header->payload_size != sizeof(StatePayload)) {
        return "the payload's size is not this FMU's";
    }
    return NULL;
}

/* Refused bytes leave *FMUState and the instance as they were. */
fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[],
                                   size_t size, fmi3FMUState *FMUState)
{
    Instance *inst = checked(instance, "fmi3DeserializeFMUState", ANY_MODE);
    SerialHeader header;
    StoredState *target, *decoded;
    const char *problem;
    if (!inst) {
        return fmi3Error;
    }
    if (!serializedState || !FMUState) {
        return refuse(inst, "fmi3DeserializeFMUState: NULL argument");
    }
    target = own_state(*FMUState);
    if (*FMUState && !target) {
        return refuse(inst, "fmi3DeserializeFMUState: *FMUState is not a state of this FMU");
    }
    if (size != SERIAL_SIZE) {
        return refuse(inst, "fmi3DeserializeFMUState: %lu bytes given, a state of this FMU has %lu",
                      (unsigned long)size, (unsigned long)SERIAL_SIZE);
    }
    memcpy(&header, serializedState, sizeof header);
    problem = header_problem(&header);
    if (problem) {
        return refuse(inst, "fmi3DeserializeFMUState: %s", problem);
    }
    decoded = new_state();
    if (!decoded) {
        return refuse(inst, "fmi3DeserializeFMUState: out of memory");
    }
    memcpy(&decoded->payload, serializedState + sizeof header, sizeof decoded->payload);
    if (check_payload(inst, "fmi3DeserializeFMUState", &decoded->payload) != fmi3OK) {
        free_state(decoded);
        return fmi3Error;
    }
    if (target) {
        memcpy(&target->payload, &decoded->payload, sizeof target->payload);
        free_state(decoded);
        decoded = target;
    }
    *FMUState = decoded;
    return fmi3OK;
}

/* --- simulating the slave -------------------------------------------------------------------- */

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                      fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime)
{
    Instance *inst = checked(instance, "fmi3DoStep", MODE_STEP);
    PlantMessage msg;
    fmi3Status status;
    double time_s;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!inst) {
        return fmi3Error;
    }
    if (!eventHandlingNeeded || !terminateSimulation || !earlyReturn || !lastSuccessfulTime) {
        return fail(inst, "fmi3DoStep: NULL output argument");
    }
    *eventHandlingNeeded = fmi3False;
    *terminateSimulation = fmi3False;
    *earlyReturn = fmi3False;
    time_s = inst->data.time_s;
    *lastSuccessfulTime = time_s;
    if (!(fabs(currentCommunicationPoint - time_s) <=
          GT_COMMUNICATION_POINT_RTOL * fmax(1.0, fabs(time_s)))) {
        return fail(inst,
                    "fmi3DoStep: currentCommunicationPoint %.17g s differs from the FMU's time "
                    "%.17g s",
                    currentCommunicationPoint, time_s);
    }
    status = report(inst, plant_do_step(&inst->data, communicationStepSize, &msg), &msg);
    *lastSuccessfulTime = inst->data.time_s;
    return status;
}

/* --- capabilities this FMU does not declare -------------------------------------------------- */

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance,
                                               fmi3ValueReference valueReference,
                                               size_t *nDependencies)
{
    (void)valueReference, (void)nDependencies;
    return unsupported(instance, "fmi3GetNumberOfVariableDependencies",
                       "providesPerElementDependencies=\"false\"");
}

fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent,
                                       size_t elementIndicesOfDependent[],
                                       fmi3ValueReference independents[],
                                       size_t elementIndicesOfIndependents[],
                                       fmi3DependencyKind dependencyKinds[], size_t nDependencies)
{
    (void)dependent, (void)elementIndicesOfDependent, (void)independents;
    (void)elementIndicesOfIndependents, (void)dependencyKinds, (void)nDependencies;
    return unsupported(instance, "fmi3GetVariableDependencies",
                       "providesPerElementDependencies=\"false\"");
}

fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance,
                                        const fmi3ValueReference unknowns[], size_t nUnknowns,
                                        const fmi3ValueReference knowns[], size_t nKnowns,
                                        const fmi3Float64 seed[], size_t nSeed,
                                        fmi3Float64 sensitivity[], size_t nSensitivity)
{
    (void)unknowns, (void)nUnknowns, (void)knowns, (void)nKnowns, (void)seed, (void)nSeed;
    (void)sensitivity, (void)nSensitivity;
    return unsupported(instance, "fmi3GetDirectionalDerivative",
                       "providesDirectionalDerivatives=\"false\"");
}

fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[],
                                    size_t nUnknowns, const fmi3ValueReference knowns[],
                                    size_t nKnowns, const fmi3Float64 seed[], size_t nSeed,
                                    fmi3Float64 sensitivity[], size_t nSensitivity)
{
    (void)unknowns, (void)nUnknowns, (void)knowns, (void)nKnowns, (void)seed, (void)nSeed;
    (void)sensitivity, (void)nSensitivity;
    return unsupported(instance, "fmi3GetAdjointDerivative",
                       "providesAdjointDerivatives=\"false\"");
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance,
                                    const fmi3ValueReference valueReferences[],
                                    size_t nValueReferences, const fmi3Int32 orders[],
                                    fmi3Float64 values[], size_t nValues)
{
    (void)valueReferences, (void)nValueReferences, (void)orders, (void)values, (void)nValues;
    return unsupported(instance, "fmi3GetOutputDerivatives", "maxOutputDerivativeOrder=\"0\"");
}

#define NO_STRUCTURAL_PARAMETERS "the model has no structural parameters"
#define NO_CLOCKS "the model has no clocks"
#define NO_EVENTS "hasEventMode=\"false\""
#define CO_SIMULATION_ONLY "the FMU supports co-simulation only"

fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance)
{
    return unsupported(instance, "fmi3EnterConfigurationMode", NO_STRUCTURAL_PARAMETERS);
}

fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance)
{
    return unsupported(instance, "fmi3ExitConfigurationMode", NO_STRUCTURAL_PARAMETERS);
}

fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance,
                                  const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, fmi3Float64 intervals[],
                                  fmi3IntervalQualifier qualifiers[])
{
    (void)valueReferences, (void)nValueReferences, (void)intervals, (void)qualifiers;
    return unsupported(instance, "fmi3GetIntervalDecimal", NO_CLOCKS);
}

fmi3Status fmi3GetIntervalFraction(fmi3Instance instance,
                                   const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, fmi3UInt64 counters[],
                                   fmi3UInt64 resolutions[], fmi3IntervalQualifier qualifiers[])
{
    (void)valueReferences, (void)nValueReferences, (void)counters, (void)resolutions;
    (void)qualifiers;
    return unsupported(instance, "fmi3GetIntervalFraction", NO_CLOCKS);
}

fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, fmi3Float64 shifts[])
{
    (void)valueReferences, (void)nValueReferences, (void)shifts;
    return unsupported(instance, "fmi3GetShiftDecimal", NO_CLOCKS);
}

fmi3Status fmi3GetShiftFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, fmi3UInt64 counters[],
                                fmi3UInt64 resolutions[])
{
    (void)valueReferences, (void)nValueReferences, (void)counters, (void)resolutions;
    return unsupported(instance, "fmi3GetShiftFraction", NO_CLOCKS);
}

fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance,
                                  const fmi3ValueReference valueReferences[],
                                  size_t nValueReferences, const fmi3Float64 intervals[])
{
    (void)valueReferences, (void)nValueReferences, (void)intervals;
    return unsupported(instance, "fmi3SetIntervalDecimal", NO_CLOCKS);
}

fmi3Status fmi3SetIntervalFraction(fmi3Instance instance,
                                   const fmi3ValueReference valueReferences[],
                                   size_t nValueReferences, const fmi3UInt64 counters[],
                                   const fmi3UInt64 resolutions[])
{
    (void)valueReferences, (void)nValueReferences, (void)counters, (void)resolutions;
    return unsupported(instance, "fmi3SetIntervalFraction", NO_CLOCKS);
}

fmi3Status fmi3SetShiftDecimal(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                               size_t nValueReferences, const fmi3Float64 shifts[])
{
    (void)valueReferences, (void)nValueReferences, (void)shifts;
    return unsupported(instance, "fmi3SetShiftDecimal", NO_CLOCKS);
}

fmi3Status fmi3SetShiftFraction(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                                size_t nValueReferences, const fmi3UInt64 counters[],
                                const fmi3UInt64 resolutions[])
{
    (void)valueReferences, (void)nValueReferences, (void)counters, (void)resolutions;
    return unsupported(instance, "fmi3SetShiftFraction", NO_CLOCKS);
}

fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance)
{
    return unsupported(instance, "fmi3EvaluateDiscreteStates", NO_EVENTS);
}

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation,
                                    fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged,
                                    fmi3Boolean *nextEventTimeDefined, fmi3Float64 *nextEventTime)
{
    (void)discreteStatesNeedUpdate, (void)terminateSimulation;
    (void)nominalsOfContinuousStatesChanged, (void)valuesOfContinuousStatesChanged;
    (void)nextEventTimeDefined, (void)nextEventTime;
    return unsupported(instance, "fmi3UpdateDiscreteStates", NO_EVENTS);
}

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance)
{
    return unsupported(instance, "fmi3EnterContinuousTimeMode", CO_SIMULATION_ONLY);
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance,
                                       fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode,
                                       fmi3Boolean *terminateSimulation)
{
    (void)noSetFMUStatePriorToCurrentPoint, (void)enterEventMode, (void)terminateSimulation;
    return unsupported(instance, "fmi3CompletedIntegratorStep", CO_SIMULATION_ONLY);
}

fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time)
{
    (void)time;
    return unsupported(instance, "fmi3SetTime", CO_SIMULATION_ONLY);
}

fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 continuousStates[],
                                   size_t nContinuousStates)
{
    (void)continuousStates, (void)nContinuousStates;
    return unsupported(instance, "fmi3SetContinuousStates", CO_SIMULATION_ONLY);
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[],
                                             size_t nContinuousStates)
{
    (void)derivatives, (void)nContinuousStates;
    return unsupported(instance, "fmi3GetContinuousStateDerivatives", CO_SIMULATION_ONLY);
}

fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[],
                                  size_t nEventIndicators)
{
    (void)eventIndicators, (void)nEventIndicators;
    return unsupported(instance, "fmi3GetEventIndicators", CO_SIMULATION_ONLY);
}

fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 continuousStates[],
                                   size_t nContinuousStates)
{
    (void)continuousStates, (void)nContinuousStates;
    return unsupported(instance, "fmi3GetContinuousStates", CO_SIMULATION_ONLY);
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[],
                                             size_t nContinuousStates)
{
    (void)nominals, (void)nContinuousStates;
    return unsupported(instance, "fmi3GetNominalsOfContinuousStates", CO_SIMULATION_ONLY);
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *nEventIndicators)
{
    (void)nEventIndicators;
    return unsupported(instance, "fmi3GetNumberOfEventIndicators", CO_SIMULATION_ONLY);
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *nContinuousStates)
{
    (void)nContinuousStates;
    return unsupported(instance, "fmi3GetNumberOfContinuousStates", CO_SIMULATION_ONLY);
}

fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime)
{
    (void)clockReference, (void)activationTime;
    return unsupported(instance, "fmi3ActivateModelPartition", CO_SIMULATION_ONLY);
}
