/* Generic FMI 3.0 co-simulation glue of every gatetwin C FMU. Never changes per model.
 *
 * The FMI 3.0 rendering of the same component as fmi2_glue.c: it talks to the model only through
 * component.h, and model_config.h (generated: instantiation token, value references, start values)
 * is the one the FMI 2.0 FMU gets. Every variable is a scalar Float64. What the two versions do
 * alike (logging, modes, the FMU state, the step) is glue_core.c's, to which this file passes
 * FMI 3.0's status values and its logger.
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
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "glue_core.h"

/* The independent variable `time` follows the component's Real variables (see
 * gatetwin.fmu.description3). */
#define VR_TIME GT_N_REAL

static void emit(const GlueSink *sink, int status, const char *category, const char *text)
{
    const fmi3LogMessageCallback logger = (fmi3LogMessageCallback)sink->callbacks.logger;
    logger(sink->callbacks.environment, (fmi3Status)status, category, text);
}

static const GlueVersion FMI3 = {
    fmi3OK, fmi3Warning, fmi3Discard, fmi3Error,
    0x67746633u /* "gtf3" */, 0x73743346u /* "st3F" */, "gatetwin-state-3", emit,
};

static Instance *checked(fmi3Instance c, const char *function, unsigned allowed_modes)
{
    return glue_checked(c, &FMI3, function, allowed_modes);
}

/* A function of a capability the model description does not declare. */
static fmi3Status unsupported(fmi3Instance c, const char *function, const char *why)
{
    Instance *inst = checked(c, function, ANY_MODE);
    return inst ? glue_fail(inst, "%s: not supported (%s)", function, why) : fmi3Error;
}

/* --- inquire version, logging ---------------------------------------------------------------- */

const char *fmi3GetVersion(void)
{
    return fmi3Version;
}

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[])
{
    Instance *inst = checked(instance, "fmi3SetDebugLogging", ANY_MODE);
    return inst ? glue_set_debug_logging(inst, "fmi3SetDebugLogging", loggingOn, nCategories,
                                         categories)
                : fmi3Error;
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
    GlueSink sink;
    const char *problem = instantiation_problem(instanceName, instantiationToken, eventModeUsed,
                                                nRequiredIntermediateVariables);
    (void)resourcePath, (void)visible, (void)earlyReturnAllowed;
    (void)requiredIntermediateVariables, (void)intermediateUpdate;
    glue_sink_init(&sink, &FMI3, instanceName, loggingOn);
    sink.callbacks.environment = instanceEnvironment;
    sink.callbacks.logger = (void (*)(void))logMessage;
    sink.callbacks.allocate = calloc;
    sink.callbacks.release = free;
    if (problem) {
        glue_log_format(&sink, fmi3Error, "fmi3InstantiateCoSimulation: %s", problem);
        return NULL;
    }
    return glue_new_instance(&sink, "fmi3InstantiateCoSimulation");
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
        glue_free_instance(inst);
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
        return glue_fail(inst, "fmi3EnterInitializationMode: startTime %g s must be finite with "
                               "|t| <= %g s", startTime, GT_MAX_TIME_S);
    }
    inst->data.time_s = startTime;
    inst->mode = MODE_INITIALIZATION;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance)
{
    Instance *inst = checked(instance, "fmi3ExitInitializationMode", MODE_INITIALIZATION);
    return inst ? glue_exit_initialization(inst) : fmi3Error;
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
    glue_reset(inst);
    return fmi3OK;
}

/* --- getting and setting values -------------------------------------------------------------- */

/* Every variable is a scalar: exactly one value per value reference (glue_check_arrays). */
fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, fmi3Float64 values[], size_t nValues)
{
    Instance *inst = checked(instance, "fmi3GetFloat64", ANY_MODE);
    size_t i;
    if (!inst || glue_check_arrays(inst, "fmi3GetFloat64", valueReferences, nValueReferences,
                                   values, nValues) != fmi3OK) {
        return fmi3Error;
    }
    for (i = 0; i < nValueReferences; i++) {
        const fmi3ValueReference vr = valueReferences[i];
        if (vr == VR_TIME) {
            values[i] = inst->data.time_s;
        } else if (vr > VR_TIME) {
            return glue_fail(inst, "fmi3GetFloat64: no Float64 variable has value reference %u",
                             (unsigned)vr);
        } else if (glue_get_real(inst, "fmi3GetFloat64", vr, &values[i]) != fmi3OK) {
            return fmi3Error;
        }
    }
    return fmi3OK;
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, const fmi3Float64 values[], size_t nValues)
{
    Instance *inst = checked(instance, "fmi3SetFloat64",
                             MODE_INSTANTIATED | MODE_INITIALIZATION | MODE_STEP);
    size_t i;
    if (!inst || glue_check_arrays(inst, "fmi3SetFloat64", valueReferences, nValueReferences,
                                   values, nValues) != fmi3OK) {
        return fmi3Error;
    }
    for (i = 0; i < nValueReferences; i++) {
        const fmi3ValueReference vr = valueReferences[i];
        if (vr >= VR_TIME) {
            return glue_fail(inst, "fmi3SetFloat64: value reference %u %s", (unsigned)vr,
                             vr == VR_TIME ? "is time, the independent variable"
                                           : "is no Float64 variable's");
        }
        if (glue_set_real(inst, "fmi3SetFloat64", vr, values[i]) != fmi3OK) {
            return fmi3Error;
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
    if (!inst || glue_check_arrays(inst, function, vr, nvr, values, nValues) != fmi3OK) {
        return fmi3Error;
    }
    if (nvr > 0) {
        return glue_fail(inst, "%s: no variable of this type has value reference %u", function,
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

fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState)
{
    Instance *inst = checked(instance, "fmi3GetFMUState", ANY_MODE ^ MODE_ERROR);
    return inst ? glue_get_state(inst, "fmi3GetFMUState", FMUState) : fmi3Error;
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState)
{
    Instance *inst = checked(instance, "fmi3SetFMUState", ANY_MODE);
    return inst ? glue_set_state(inst, "fmi3SetFMUState", FMUState) : fmi3Error;
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState)
{
    Instance *inst = checked(instance, "fmi3FreeFMUState", ANY_MODE);
    return inst ? glue_free_state(inst, "fmi3FreeFMUState", FMUState) : fmi3Error;
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState, size_t *size)
{
    Instance *inst = checked(instance, "fmi3SerializedFMUStateSize", ANY_MODE);
    (void)FMUState;
    return inst ? glue_serialized_size(inst, "fmi3SerializedFMUStateSize", size) : fmi3Error;
}

fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState,
                                 fmi3Byte serializedState[], size_t size)
{
    Instance *inst = checked(instance, "fmi3SerializeFMUState", ANY_MODE);
    return inst ? glue_serialize(inst, "fmi3SerializeFMUState", FMUState, serializedState, size)
                : fmi3Error;
}

/* Refused bytes leave *FMUState and the instance as they were. */
fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[],
                                   size_t size, fmi3FMUState *FMUState)
{
    Instance *inst = checked(instance, "fmi3DeserializeFMUState", ANY_MODE);
    return inst ? glue_deserialize(inst, "fmi3DeserializeFMUState", serializedState, size,
                                   FMUState)
                : fmi3Error;
}

/* --- simulating the slave -------------------------------------------------------------------- */

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                      fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime)
{
    Instance *inst = checked(instance, "fmi3DoStep", MODE_STEP);
    fmi3Status status;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!inst) {
        return fmi3Error;
    }
    if (!eventHandlingNeeded || !terminateSimulation || !earlyReturn || !lastSuccessfulTime) {
        return glue_fail(inst, "fmi3DoStep: NULL output argument");
    }
    *eventHandlingNeeded = fmi3False;
    *terminateSimulation = fmi3False;
    *earlyReturn = fmi3False;
    status = glue_do_step(inst, "fmi3DoStep", currentCommunicationPoint, communicationStepSize);
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
