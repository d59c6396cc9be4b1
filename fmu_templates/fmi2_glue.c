/* Generic FMI 2.0 co-simulation glue of every gatetwin plant FMU. Never changes per model.
 *
 * What differs per model lives in model_config.h (generated: GUID, value references, start
 * values) and in the family's dynamics file; this file talks to them only through component.h.
 *
 * Policy, stricter than the Reference-FMUs: a call the FMU cannot honour (wrong state, bad
 * pointer, unknown value reference, bad input, a step size it cannot take) returns fmi2Error
 * with a logged reason and moves the instance to the error state (FMI 2.0, section 2.1.3);
 * fmi2SetFMUstate or fmi2Reset recover from it. A refused FMU state (fmi2SetFMUstate,
 * fmi2DeSerializeFMUstate) is the exception: the instance stays as it was, in its mode.
 * Warnings and errors are always logged; informational messages only when logging is on.
 *
 * A restored state is checked completely before it is used (plant_check_state): identity
 * (the GUID in a serialised state's header, the library that made an in-memory one), format
 * version and size, mode, every flag, index and count, every double finite.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "component.h"

#define INSTANCE_MAGIC 0x67617465u /* "gate" */
#define STATE_MAGIC 0x73746174u    /* "stat" */
#define SERIAL_FORMAT "gatetwin-state-2"

typedef enum {
    MODE_INSTANTIATED = 1,
    MODE_INITIALIZATION = 2,
    MODE_STEP_COMPLETE = 4,
    MODE_TERMINATED = 8,
    MODE_ERROR = 16
} Mode;

#define ANY_MODE                                                                          \
    (MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_STEP_COMPLETE | MODE_TERMINATED |     \
     MODE_ERROR)

/* Where messages go: small, so fmi2Instantiate can log before anything is allocated. */
typedef struct {
    char name[128];
    fmi2CallbackFunctions callbacks;
    fmi2Boolean logging_on;
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
    char guid[64];   /* GT_GUID: a state only fits the build it came from */
    unsigned long long payload_size;
} SerialHeader;

/* --- memory and logging ---------------------------------------------------------------------- */

static void *allocate(const fmi2CallbackFunctions *cb, size_t size)
{
    return cb->allocateMemory ? cb->allocateMemory(1, size) : calloc(1, size);
}

static void release(const fmi2CallbackFunctions *cb, void *p)
{
    if (cb->freeMemory) {
        cb->freeMemory(p);
    } else {
        free(p);
    }
}

/* The logger treats the message as a printf format: pass it with any '%' made harmless. */
static void log_text(const LogTarget *sink, fmi2Status status, const char *text)
{
    static const char *const category[] = {"logAll", "logStatusWarning", "logStatusWarning",
                                           "logStatusError", "logStatusError"};
    char message[768];
    size_t i;
    if (!sink->callbacks.logger || (status == fmi2OK && !sink->logging_on)) {
        return;
    }
    for (i = 0; i + 1 < sizeof message && text[i] != '\0'; i++) {
        message[i] = text[i] == '%' ? '#' : text[i];
    }
    message[i] = '\0';
    sink->callbacks.logger(sink->callbacks.componentEnvironment, sink->name, status,
                           category[status <= fmi2Fatal ? status : fmi2Error], message);
}

#if defined(__GNUC__)
static void log_message(const LogTarget *sink, fmi2Status status, const char *format, ...)
    __attribute__((format(printf, 3, 4)));
static fmi2Status fail(Instance *inst, const char *format, ...)
    __attribute__((format(printf, 2, 3)));
static fmi2Status refuse(Instance *inst, const char *format, ...)
    __attribute__((format(printf, 2, 3)));
#endif

static void log_message(const LogTarget *sink, fmi2Status status, const char *format, ...)
{
    char text[768];
    va_list args;
    va_start(args, format);
    vsnprintf(text, sizeof text, format, args);
    va_end(args);
    log_text(sink, status, text);
}

/* Log why, enter the error state, return fmi2Error. */
static fmi2Status fail(Instance *inst, const char *format, ...)
{
    char text[768];
    va_list args;
    va_start(args, format);
    vsnprintf(text, sizeof text, format, args);
    va_end(args);
    log_text(&inst->sink, fmi2Error, text);
    inst->mode = MODE_ERROR;
    return fmi2Error;
}

/* Log why and return fmi2Error, leaving the instance as it was (refused FMU states). */
static fmi2Status refuse(Instance *inst, const char *format, ...)
{
    char text[768];
    va_list args;
    va_start(args, format);
    vsnprintf(text, sizeof text, format, args);
    va_end(args);
    log_text(&inst->sink, fmi2Error, text);
    return fmi2Error;
}

static const char *mode_name(Mode mode)
{
    switch (mode) {
    case MODE_INSTANTIATED: return "instantiated";
    case MODE_INITIALIZATION: return "initialization mode";
    case MODE_STEP_COMPLETE: return "step mode";
    case MODE_TERMINATED: return "terminated";
    default: return "error";
    }
}

/* The instance behind c if c is one and the call is legal in its mode, else NULL. */
static Instance *checked(fmi2Component c, const char *function, unsigned allowed_modes)
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
static fmi2Status report(Instance *inst, PlantStatus status, const PlantMessage *msg)
{
    if (status == PLANT_ERROR) {
        return fail(inst, "%s", msg->text);
    }
    if (status == PLANT_WARNING) {
        log_text(&inst->sink, fmi2Warning, msg->text);
        return fmi2Warning;
    }
    return fmi2OK;
}

/* --- inquire version, logging ------------------------------------------------------------- */

const char *fmi2GetTypesPlatform(void)
{
    return fmi2TypesPlatform;
}

const char *fmi2GetVersion(void)
{
    return fmi2Version;
}

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[])
{
    static const char *const known[] = GT_LOG_CATEGORIES;
    Instance *inst = checked(c, "fmi2SetDebugLogging", ANY_MODE);
    size_t i, k;
    if (!inst) {
        return fmi2Error;
    }
    if (nCategories > 0 && !categories) {
        return fail(inst, "fmi2SetDebugLogging: categories is NULL");
    }
    for (i = 0; i < nCategories; i++) {
        int found = 0;
        for (k = 0; k < sizeof known / sizeof known[0]; k++) {
            found = found || (categories[i] && strcmp(categories[i], known[k]) == 0);
        }
        if (!found) {
            return fail(inst, "fmi2SetDebugLogging: unknown log category '%s'",
                        categories[i] ? categories[i] : "(NULL)");
        }
    }
    inst->sink.logging_on = loggingOn;
    return fmi2OK;
}

/* --- creation and destruction ------------------------------------------------------------- */

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn)
{
    LogTarget sink;
    Instance *inst;
    (void)fmuResourceLocation;
    (void)visible;
    if (!functions) {
        return NULL;
    }
    memset(&sink, 0, sizeof sink);
    sink.callbacks = *functions;
    sink.logging_on = loggingOn;
    snprintf(sink.name, sizeof sink.name, "%s", instanceName ? instanceName : "(NULL)");
    if (!instanceName || instanceName[0] == '\0') {
        log_text(&sink, fmi2Error, "fmi2Instantiate: instanceName must be a non-empty string");
        return NULL;
    }
    if (fmuType != fmi2CoSimulation) {
        log_text(&sink, fmi2Error, "fmi2Instantiate: this FMU supports co-simulation only");
        return NULL;
    }
    if (!fmuGUID || strcmp(fmuGUID, GT_GUID) != 0) {
        log_message(&sink, fmi2Error, "fmi2Instantiate: GUID '%s' does not match '%s'",
                    fmuGUID ? fmuGUID : "(NULL)", GT_GUID);
        return NULL;
    }
    inst = (Instance *)allocate(functions, sizeof *inst);
    if (!inst) {
        log_text(&sink, fmi2Error, "fmi2Instantiate: out of memory");
        return NULL;
    }
    inst->magic = INSTANCE_MAGIC;
    inst->sink = sink;
    inst->mode = MODE_INSTANTIATED;
    plant_set_defaults(&inst->data);
    log_text(&inst->sink, fmi2OK, "instantiated " GT_MODEL_IDENTIFIER);
    return inst;
}

void fmi2FreeInstance(fmi2Component c)
{
    Instance *inst = checked(c, "fmi2FreeInstance", ANY_MODE);
    if (inst) {
        const fmi2CallbackFunctions callbacks = inst->sink.callbacks;
        inst->magic = 0;
        release(&callbacks, inst);
    }
}

/* --- initialisation, termination, reset ------------------------------------------------------ */

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined,
                               fmi2Real stopTime)
{
    Instance *inst = checked(c, "fmi2SetupExperiment", MODE_INSTANTIATED);
    (void)toleranceDefined;
    (void)tolerance;
    (void)stopTimeDefined;
    (void)stopTime;
    if (!inst) {
        return fmi2Error;
    }
    if (!(fabs(startTime) <= GT_MAX_TIME_S)) {
        return fail(inst, "fmi2SetupExperiment: startTime %g s must be finite with |t| <= %g s",
                    startTime, GT_MAX_TIME_S);
    }
    inst->data.time_s = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c)
{
    Instance *inst = checked(c, "fmi2EnterInitializationMode", MODE_INSTANTIATED);
    if (!inst) {
        return fmi2Error;
    }
    inst->mode = MODE_INITIALIZATION;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c)
{
    Instance *inst = checked(c, "fmi2ExitInitializationMode", MODE_INITIALIZATION);
    PlantMessage msg;
    PlantStatus status;
    if (!inst) {
        return fmi2Error;
    }
    status = plant_initialize(&inst->data, &msg);
    if (status != PLANT_ERROR) {
        inst->mode = MODE_STEP_COMPLETE;
    }
    return report(inst, status, &msg);
}

fmi2Status fmi2Terminate(fmi2Component c)
{
    Instance *inst = checked(c, "fmi2Terminate", MODE_STEP_COMPLETE);
    if (!inst) {
        return fmi2Error;
    }
    inst->mode = MODE_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c)
{
    Instance *inst = checked(c, "fmi2Reset", ANY_MODE);
    if (!inst) {
        return fmi2Error;
    }
    plant_set_defaults(&inst->data);
    inst->mode = MODE_INSTANTIATED;
    return fmi2OK;
}

/* --- getting and setting values ------------------------------------------------------------ */

static fmi2Status check_arrays(Instance *inst, const char *function, const void *vr, size_t nvr,
                               const void *value)
{
    if (nvr > 0 && (!vr || !value)) {
        return fail(inst, "%s: NULL value-reference or value array", function);
    }
    return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       fmi2Real value[])
{
    Instance *inst = checked(c, "fmi2GetReal", ANY_MODE);
    size_t i;
    if (!inst || check_arrays(inst, "fmi2GetReal", vr, nvr, value) != fmi2OK) {
        return fmi2Error;
    }
    for (i = 0; i < nvr; i++) {
        if (vr[i] >= GT_N_REAL) {
            return fail(inst, "fmi2GetReal: no Real variable has value reference %u", vr[i]);
        }
        if (plant_variables[vr[i]].kind == GT_KIND_OUTPUT) {
            PlantMessage msg;
            if (plant_output(&inst->data, vr[i], &value[i], &msg) != PLANT_OK) {
                return fail(inst, "fmi2GetReal: %s", msg.text);
            }
        } else {
            value[i] = inst->data.real[vr[i]];
        }
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[])
{
    Instance *inst = checked(c, "fmi2SetReal",
                             MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_STEP_COMPLETE);
    size_t i;
    if (!inst || check_arrays(inst, "fmi2SetReal", vr, nvr, value) != fmi2OK) {
        return fmi2Error;
    }
    for (i = 0; i < nvr; i++) {
        VariableKind kind;
        if (vr[i] >= GT_N_REAL) {
            return fail(inst, "fmi2SetReal: no Real variable has value reference %u", vr[i]);
        }
        kind = plant_variables[vr[i]].kind;
        if (kind == GT_KIND_OUTPUT) {
            return fail(inst, "fmi2SetReal: %s is an output", plant_variables[vr[i]].name);
        }
        if (kind == GT_KIND_FIXED && inst->mode == MODE_STEP_COMPLETE) {
            return fail(inst, "fmi2SetReal: %s is a fixed parameter, settable only before "
                              "fmi2ExitInitializationMode", plant_variables[vr[i]].name);
        }
        if (!isfinite(value[i])) { /* every value an FMU state holds stays finite */
            return fail(inst, "fmi2SetReal: %s = %g is not finite", plant_variables[vr[i]].name,
                        value[i]);
        }
        inst->data.real[vr[i]] = value[i];
        if (kind != GT_KIND_INPUT) {
            inst->data.parameters_changed = 1;
        }
    }
    return fmi2OK;
}

/* The model has Real variables only. */
static fmi2Status no_such_variables(fmi2Component c, const char *function, const char *type,
                                    const fmi2ValueReference vr[], size_t nvr,
                                    const void *value)
{
    Instance *inst = checked(c, function, ANY_MODE);
    if (!inst || check_arrays(inst, function, vr, nvr, value) != fmi2OK) {
        return fmi2Error;
    }
    if (nvr > 0) {
        return fail(inst, "%s: no %s variable has value reference %u", function, type, vr[0]);
    }
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Integer value[])
{
    return no_such_variables(c, "fmi2GetInteger", "Integer", vr, nvr, value);
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Boolean value[])
{
    return no_such_variables(c, "fmi2GetBoolean", "Boolean", vr, nvr, value);
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         fmi2String value[])
{
    return no_such_variables(c, "fmi2GetString", "String", vr, nvr, value);
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Integer value[])
{
    return no_such_variables(c, "fmi2SetInteger", "Integer", vr, nvr, value);
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Boolean value[])
{
    return no_such_variables(c, "fmi2SetBoolean", "Boolean", vr, nvr, value);
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         const fmi2String value[])
{
    return no_such_variables(c, "fmi2SetString", "String", vr, nvr, value);
}

/* --- FMU state ------------------------------------------------------------------------------- */

/* Whether a stored state can be restored into this FMU: its mode and ModelData (component.h). */
static fmi2Status check_payload(Instance *inst, const char *function, const StatePayload *p)
{
    PlantMessage msg;
    int initialized;
    switch (p->mode) {
    case MODE_INSTANTIATED:
    case MODE_INITIALIZATION: initialized = 0; break;
    case MODE_STEP_COMPLETE:
    case MODE_TERMINATED: initialized = 1; break;
    default:
        return refuse(inst, "%s: the state's mode %d is not a mode a state is taken in", function,
                      (int)p->mode);
    }
    if (plant_check_state(&p->data, initialized, &msg) != PLANT_OK) {
        return refuse(inst, "%s: corrupt state refused, the instance is unchanged: %s", function,
                      msg.text);
    }
    return fmi2OK;
}

/* The state behind an FMUstate argument if it is one of this library's, else NULL. */
static StoredState *own_state(fmi2FMUstate FMUstate)
{
    StoredState *stored = (StoredState *)FMUstate;
    if (!stored || stored->magic != STATE_MAGIC || stored->owner != STATE_OWNER) {
        return NULL;
    }
    return stored;
}

static StoredState *new_state(Instance *inst)
{
    StoredState *stored = (StoredState *)allocate(&inst->sink.callbacks, sizeof *stored);
    if (stored) {
        stored->magic = STATE_MAGIC;
        stored->owner = STATE_OWNER;
    }
    return stored;
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    Instance *inst = checked(c, "fmi2GetFMUstate", ANY_MODE ^ MODE_ERROR);
    StoredState *stored;
    if (!inst) {
        return fmi2Error;
    }
    if (!FMUstate) {
        return fail(inst, "fmi2GetFMUstate: FMUstate is NULL");
    }
    stored = own_state(*FMUstate);
    if (*FMUstate && !stored) {
        return fail(inst, "fmi2GetFMUstate: *FMUstate is not a state of this FMU");
    }
    if (!stored) {
        stored = new_state(inst);
        if (!stored) {
            return fail(inst, "fmi2GetFMUstate: out of memory");
        }
    }
    stored->payload.mode = inst->mode;
    memcpy(&stored->payload.data, &inst->data, sizeof inst->data);
    *FMUstate = stored;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate)
{
    Instance *inst = checked(c, "fmi2SetFMUstate", ANY_MODE);
    const StoredState *stored = own_state(FMUstate);
    if (!inst) {
        return fmi2Error;
    }
    if (!stored) {
        return refuse(inst, "fmi2SetFMUstate: FMUstate is NULL or not a state of this FMU");
    }
    if (check_payload(inst, "fmi2SetFMUstate", &stored->payload) != fmi2OK) {
        return fmi2Error;
    }
    memcpy(&inst->data, &stored->payload.data, sizeof inst->data);
    inst->mode = stored->payload.mode;
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    Instance *inst = checked(c, "fmi2FreeFMUstate", ANY_MODE);
    StoredState *stored;
    if (!inst) {
        return fmi2Error;
    }
    if (!FMUstate || !*FMUstate) {
        return fmi2OK;
    }
    stored = own_state(*FMUstate);
    if (!stored) {
        return fail(inst, "fmi2FreeFMUstate: *FMUstate is not a state of this FMU");
    }
    stored->magic = 0;
    release(&inst->sink.callbacks, stored);
    *FMUstate = NULL;
    return fmi2OK;
}

/* Bytes of a serialised state: the header, then the payload. */
#define SERIAL_SIZE (sizeof(SerialHeader) + sizeof(StatePayload))

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size)
{
    Instance *inst = checked(c, "fmi2SerializedFMUstateSize", ANY_MODE);
    (void)FMUstate;
    if (!inst) {
        return fmi2Error;
    }
    if (!size) {
        return fail(inst, "fmi2SerializedFMUstateSize: size is NULL");
    }
    *size = SERIAL_SIZE;
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[],
                                 size_t size)
{
    Instance *inst = checked(c, "fmi2SerializeFMUstate", ANY_MODE);
    const StoredState *stored = own_state(FMUstate);
    SerialHeader header;
    if (!inst) {
        return fmi2Error;
    }
    if (!stored || !serializedState) {
        return fail(inst, "fmi2SerializeFMUstate: NULL buffer, or FMUstate is not a state of "
                          "this FMU");
    }
    if (size != SERIAL_SIZE) {
        return fail(inst, "fmi2SerializeFMUstate: buffer holds %lu bytes, the state needs %lu",
                    (unsigned long)size, (unsigned long)SERIAL_SIZE);
    }
    memset(&header, 0, sizeof header);
    memcpy(header.format, SERIAL_FORMAT, sizeof SERIAL_FORMAT);
    snprintf(header.guid, sizeof header.guid, "%s", GT_GUID);
    header.payload_size = sizeof stored->payload;
    memcpy(serializedState, &header, sizeof header);
    memcpy(serializedState + sizeof header, &stored->payload, sizeof stored->payload);
    return fmi2OK;
}

/* Refused bytes leave *FMUstate and the instance as they were. */
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate)
{
    Instance *inst = checked(c, "fmi2DeSerializeFMUstate", ANY_MODE);
    SerialHeader header;
    StoredState *target, *decoded;
    if (!inst) {
        return fmi2Error;
    }
    if (!serializedState || !FMUstate) {
        return refuse(inst, "fmi2DeSerializeFMUstate: NULL argument");
    }
    target = own_state(*FMUstate);
    if (*FMUstate && !target) {
        return refuse(inst, "fmi2DeSerializeFMUstate: *FMUstate is not a state of this FMU");
    }
    if (size != SERIAL_SIZE) {
        return refuse(inst, "fmi2DeSerializeFMUstate: %lu bytes given, a state of this FMU has %lu",
                      (unsigned long)size, (unsigned long)SERIAL_SIZE);
    }
    memcpy(&header, serializedState, sizeof header);
    if (memcmp(header.format, SERIAL_FORMAT, sizeof SERIAL_FORMAT) != 0) {
        return refuse(inst, "fmi2DeSerializeFMUstate: not a serialised state of format %s",
                      SERIAL_FORMAT);
    }
    if (strncmp(header.guid, GT_GUID, sizeof header.guid) != 0) {
        header.guid[sizeof header.guid - 1] = '\0';
        return refuse(inst, "fmi2DeSerializeFMUstate: the state is of FMU %s, this FMU is %s",
                      header.guid, GT_GUID);
    }
    if (header.payload_size != sizeof(StatePayload)) {
        return refuse(inst, "fmi2DeSerializeFMUstate: payload of %llu bytes, this FMU's has %lu",
                      header.payload_size, (unsigned long)sizeof(StatePayload));
    }
    decoded = new_state(inst);
    if (!decoded) {
        return refuse(inst, "fmi2DeSerializeFMUstate: out of memory");
    }
    memcpy(&decoded->payload, serializedState + sizeof header, sizeof decoded->payload);
    if (check_payload(inst, "fmi2DeSerializeFMUstate", &decoded->payload) != fmi2OK) {
        decoded->magic = 0;
        release(&inst->sink.callbacks, decoded);
        return fmi2Error;
    }
    if (target) {
        memcpy(&target->payload, &decoded->payload, sizeof target->payload);
        decoded->magic = 0;
        release(&inst->sink.callbacks, decoded);
        decoded = target;
    }
    *FMUstate = decoded;
    return fmi2OK;
}

/* --- capabilities this FMU does not declare ------------------------------------------------- */

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[],
                                        size_t nUnknown, const fmi2ValueReference vKnown_ref[],
                                        size_t nKnown, const fmi2Real dvKnown[],
                                        fmi2Real dvUnknown[])
{
    Instance *inst = checked(c, "fmi2GetDirectionalDerivative", ANY_MODE);
    (void)vUnknown_ref, (void)nUnknown, (void)vKnown_ref, (void)nKnown, (void)dvKnown;
    (void)dvUnknown;
    return inst ? fail(inst, "fmi2GetDirectionalDerivative: not provided "
                             "(providesDirectionalDerivative=\"false\")")
                : fmi2Error;
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[])
{
    Instance *inst = checked(c, "fmi2SetRealInputDerivatives", ANY_MODE);
    (void)vr, (void)nvr, (void)order, (void)value;
    return inst ? fail(inst, "fmi2SetRealInputDerivatives: inputs are piecewise constant "
                             "(canInterpolateInputs=\"false\")")
                : fmi2Error;
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                        size_t nvr, const fmi2Integer order[], fmi2Real value[])
{
    Instance *inst = checked(c, "fmi2GetRealOutputDerivatives", ANY_MODE);
    (void)vr, (void)nvr, (void)order, (void)value;
    return inst ? fail(inst, "fmi2GetRealOutputDerivatives: not provided "
                             "(maxOutputDerivativeOrder=\"0\")")
                : fmi2Error;
}

/* --- simulating the slave ------------------------------------------------------------------- */

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    Instance *inst = checked(c, "fmi2DoStep", MODE_STEP_COMPLETE);
    PlantMessage msg;
    double time_s;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!inst) {
        return fmi2Error;
    }
    time_s = inst->data.time_s;
    if (!(fabs(currentCommunicationPoint - time_s) <=
          GT_COMMUNICATION_POINT_RTOL * fmax(1.0, fabs(time_s)))) {
        return fail(inst,
                    "fmi2DoStep: currentCommunicationPoint %.17g s differs from the FMU's time "
                    "%.17g s",
                    currentCommunicationPoint, time_s);
    }
    return report(inst, plant_do_step(&inst->data, communicationStepSize, &msg), &msg);
}

fmi2Status fmi2CancelStep(fmi2Component c)
{
    Instance *inst = checked(c, "fmi2CancelStep", ANY_MODE);
    return inst ? fail(inst, "fmi2CancelStep: fmi2DoStep never returns fmi2Pending here")
                : fmi2Error;
}

static fmi2Status status_unavailable(fmi2Component c, const char *function, const void *value)
{
    Instance *inst = checked(c, function, ANY_MODE);
    if (!inst) {
        return fmi2Error;
    }
    if (!value) {
        return fail(inst, "%s: value is NULL", function);
    }
    log_message(&inst->sink, fmi2Discard, "%s: no such status (fmi2DoStep is synchronous)",
                function);
    return fmi2Discard;
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value)
{
    (void)s;
    return status_unavailable(c, "fmi2GetStatus", value);
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value)
{
    Instance *inst = checked(c, "fmi2GetRealStatus", ANY_MODE);
    if (inst && value && s == fmi2LastSuccessfulTime) {
        *value = inst->data.time_s;
        return fmi2OK;
    }
    return status_unavailable(c, "fmi2GetRealStatus", value);
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value)
{
    (void)s;
    return status_unavailable(c, "fmi2GetIntegerStatus", value);
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value)
{
    Instance *inst = checked(c, "fmi2GetBooleanStatus", ANY_MODE);
    if (inst && value && s == fmi2Terminated) {
        *value = fmi2False;
        return fmi2OK;
    }
    return status_unavailable(c, "fmi2GetBooleanStatus", value);
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value)
{
    (void)s;
    return status_unavailable(c, "fmi2GetStringStatus", value);
}
