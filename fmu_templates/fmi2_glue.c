/* Generic FMI 2.0 co-simulation glue of every gatetwin C FMU. Never changes per model.
 *
 * What differs per model lives in model_config.h (generated: GUID, value references, start
 * values) and in the component's files; this file talks to them only through component.h,
 * and shares with fmi3_glue.c what the two versions do alike (glue_core.h: logging, modes,
 * the FMU state, the step), to which it passes FMI 2.0's status values and its logger.
 *
 * Policy, stricter than the Reference-FMUs: a call the FMU cannot honour (wrong state, bad
 * pointer, unknown value reference, bad input, a step size it cannot take) returns fmi2Error
 * with a logged reason and moves the instance to the error state (FMI 2.0, section 2.1.3);
 * fmi2SetFMUstate or fmi2Reset recover from it. A refused FMU state (fmi2SetFMUstate,
 * fmi2DeSerializeFMUstate) is the exception: the instance stays as it was, in its mode.
 * Warnings and errors are always logged; informational messages only when logging is on.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "glue_core.h"

/* FMI 2.0's logger takes the message as a printf format: pass it with any '%' made
 * harmless. */
static void emit(const GlueSink *sink, int status, const char *category, const char *text)
{
    const fmi2CallbackLogger logger = (fmi2CallbackLogger)sink->callbacks.logger;
    char message[768];
    size_t i;
    for (i = 0; i + 1 < sizeof message && text[i] != '\0'; i++) {
        message[i] = text[i] == '%' ? '#' : text[i];
    }
    message[i] = '\0';
    logger(sink->callbacks.environment, sink->name, (fmi2Status)status, category, message);
}

static const GlueVersion FMI2 = {
    fmi2OK, fmi2Warning, fmi2Discard, fmi2Error,
    0x67617465u /* "gate" */, 0x73746174u /* "stat" */, "gatetwin-state-2", emit,
};

static Instance *checked(fmi2Component c, const char *function, unsigned allowed_modes)
{
    return glue_checked(c, &FMI2, function, allowed_modes);
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
    Instance *inst = checked(c, "fmi2SetDebugLogging", ANY_MODE);
    return inst ? glue_set_debug_logging(inst, "fmi2SetDebugLogging", loggingOn, nCategories,
                                         categories)
                : fmi2Error;
}

/* --- creation and destruction ------------------------------------------------------------- */

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn)
{
    GlueSink sink;
    (void)fmuResourceLocation;
    (void)visible;
    if (!functions) {
        return NULL;
    }
    glue_sink_init(&sink, &FMI2, instanceName, loggingOn);
    sink.callbacks.environment = functions->componentEnvironment;
    sink.callbacks.logger = (void (*)(void))functions->logger;
    sink.callbacks.allocate = functions->allocateMemory ? functions->allocateMemory : calloc;
    sink.callbacks.release = functions->freeMemory ? functions->freeMemory : free;
    if (!instanceName || instanceName[0] == '\0') {
        glue_log(&sink, fmi2Error, "fmi2Instantiate: instanceName must be a non-empty string");
        return NULL;
    }
    if (fmuType != fmi2CoSimulation) {
        glue_log(&sink, fmi2Error, "fmi2Instantiate: this FMU supports co-simulation only");
        return NULL;
    }
    if (!fmuGUID || strcmp(fmuGUID, GT_GUID) != 0) {
        glue_log_format(&sink, fmi2Error, "fmi2Instantiate: GUID '%s' does not match '%s'",
                        fmuGUID ? fmuGUID : "(NULL)", GT_GUID);
        return NULL;
    }
    return glue_new_instance(&sink, "fmi2Instantiate");
}

void fmi2FreeInstance(fmi2Component c)
{
    Instance *inst = checked(c, "fmi2FreeInstance", ANY_MODE);
    if (inst) {
        glue_free_instance(inst);
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
        return glue_fail(inst, "fmi2SetupExperiment: startTime %g s must be finite with |t| <= "
                               "%g s", startTime, GT_MAX_TIME_S);
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
    return inst ? glue_exit_initialization(inst) : fmi2Error;
}

fmi2Status fmi2Terminate(fmi2Component c)
{
    Instance *inst = checked(c, "fmi2Terminate", MODE_STEP);
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
    glue_reset(inst);
    return fmi2OK;
}

/* --- getting and setting values ------------------------------------------------------------ */

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       fmi2Real value[])
{
    Instance *inst = checked(c, "fmi2GetReal", ANY_MODE);
    size_t i;
    if (!inst || glue_check_arrays(inst, "fmi2GetReal", vr, nvr, value, nvr) != fmi2OK) {
        return fmi2Error;
    }
    for (i = 0; i < nvr; i++) {
        if (vr[i] >= GT_N_REAL) {
            return glue_fail(inst, "fmi2GetReal: no Real variable has value reference %u",
                             vr[i]);
        }
        if (glue_get_real(inst, "fmi2GetReal", vr[i], &value[i]) != fmi2OK) {
            return fmi2Error;
        }
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[])
{
    Instance *inst = checked(c, "fmi2SetReal", MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_STEP);
    size_t i;
    if (!inst || glue_check_arrays(inst, "fmi2SetReal", vr, nvr, value, nvr) != fmi2OK) {
        return fmi2Error;
    }
    for (i = 0; i < nvr; i++) {
        if (vr[i] >= GT_N_REAL) {
            return glue_fail(inst, "fmi2SetReal: no Real variable has value reference %u",
                             vr[i]);
        }
        if (glue_set_real(inst, "fmi2SetReal", vr[i], value[i]) != fmi2OK) {
            return fmi2Error;
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
    if (!inst || glue_check_arrays(inst, function, vr, nvr, value, nvr) != fmi2OK) {
        return fmi2Error;
    }
    if (nvr > 0) {
        return glue_fail(inst, "%s: no %s variable has value reference %u", function, type,
                         vr[0]);
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

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    Instance *inst = checked(c, "fmi2GetFMUstate", ANY_MODE ^ MODE_ERROR);
    return inst ? glue_get_state(inst, "fmi2GetFMUstate", FMUstate) : fmi2Error;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate)
{
    Instance *inst = checked(c, "fmi2SetFMUstate", ANY_MODE);
    return inst ? glue_set_state(inst, "fmi2SetFMUstate", FMUstate) : fmi2Error;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    Instance *inst = checked(c, "fmi2FreeFMUstate", ANY_MODE);
    return inst ? glue_free_state(inst, "fmi2FreeFMUstate", FMUstate) : fmi2Error;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size)
{
    Instance *inst = checked(c, "fmi2SerializedFMUstateSize", ANY_MODE);
    (void)FMUstate;
    return inst ? glue_serialized_size(inst, "fmi2SerializedFMUstateSize", size) : fmi2Error;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[],
                                 size_t size)
{
    Instance *inst = checked(c, "fmi2SerializeFMUstate", ANY_MODE);
    return inst ? glue_serialize(inst, "fmi2SerializeFMUstate", FMUstate, serializedState, size)
                : fmi2Error;
}

/* Refused bytes leave *FMUstate and the instance as they were. */
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate)
{
    Instance *inst = checked(c, "fmi2DeSerializeFMUstate", ANY_MODE);
    return inst ? glue_deserialize(inst, "fmi2DeSerializeFMUstate", serializedState, size,
                                   FMUstate)
                : fmi2Error;
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
    return inst ? glue_fail(inst, "fmi2GetDirectionalDerivative: not provided "
                             "(providesDirectionalDerivative=\"false\")")
                : fmi2Error;
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[])
{
    Instance *inst = checked(c, "fmi2SetRealInputDerivatives", ANY_MODE);
    (void)vr, (void)nvr, (void)order, (void)value;
    return inst ? glue_fail(inst, "fmi2SetRealInputDerivatives: inputs are piecewise constant "
                             "(canInterpolateInputs=\"false\")")
                : fmi2Error;
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                        size_t nvr, const fmi2Integer order[], fmi2Real value[])
{
    Instance *inst = checked(c, "fmi2GetRealOutputDerivatives", ANY_MODE);
    (void)vr, (void)nvr, (void)order, (void)value;
    return inst ? glue_fail(inst, "fmi2GetRealOutputDerivatives: not provided "
                             "(maxOutputDerivativeOrder=\"0\")")
                : fmi2Error;
}

/* --- simulating the slave ------------------------------------------------------------------- */

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize, fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    Instance *inst = checked(c, "fmi2DoStep", MODE_STEP);
    (void)noSetFMUStatePriorToCurrentPoint;
    return inst ? glue_do_step(inst, "fmi2DoStep", currentCommunicationPoint,
                               communicationStepSize)
                : fmi2Error;
}

fmi2Status fmi2CancelStep(fmi2Component c)
{
    Instance *inst = checked(c, "fmi2CancelStep", ANY_MODE);
    return inst ? glue_fail(inst, "fmi2CancelStep: fmi2DoStep never returns fmi2Pending here")
                : fmi2Error;
}

static fmi2Status status_unavailable(fmi2Component c, const char *function, const void *value)
{
    Instance *inst = checked(c, function, ANY_MODE);
    if (!inst) {
        return fmi2Error;
    }
    if (!value) {
        return glue_fail(inst, "%s: value is NULL", function);
    }
    glue_log_format(&inst->sink, fmi2Discard, "%s: no such status (fmi2DoStep is synchronous)",
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
