/*
 * fmu_common3.h -- the FMI 3.0 model-exchange function set shared by the
 * FMUs of integrator-bench's native problems (spring_pendulum, two_mass,
 * bouncing_ball) and of its FMI 3.0 model with arrays (state_space): the
 * FMI 3.0 counterpart of fmu_common.h over the SAME model hooks, so that each
 * model's equations are written once. A model file
 * includes this header instead of fmu_common.h when compiled with the
 * preprocessor definition FMI_VERSION=3 (set in the FMU's
 * sources/buildDescription.xml by problems/fmu_build.py). Plain C99, no
 * library beyond the C standard library and the FMI 3.0 headers.
 *
 * Source: Modelica Association, "Functional Mock-up Interface Specification",
 * version 3.0.1 (2023): chapter 2 (common concepts: instantiation,
 * initialization, variable access, FMU state, directional derivatives;
 * sect. 2.4, the model description and its ModelStructure; sect. 2.5, the
 * FMU distribution) and chapter 3
 * (model exchange: its functions and the state machine of their calling
 * sequence).
 *
 * Value references (states, der(...), parameters, time, then the computed
 * outputs), the model file's defines and its hooks are those of fmu_core.h
 * (see there), which holds the logic this header shares with fmu_common.h;
 * the functions below adapt the FMI 3.0 signatures to it. The hooks use the
 * neutral type `real` (= fmi3Float64 = double) and return plain int flags.
 * MODEL_GUID is the instantiationToken of modelDescription3.xml.
 *
 * Every function of fmi3Functions.h is exported (importers such as fmpy bind
 * them all). Those of interfaces the FMUs do not offer (Co-Simulation,
 * Scheduled Execution, clocks, configuration mode) and the capabilities the
 * model description declares false (serialization, adjoint derivatives,
 * per-element dependencies) return fmi3Error with a log line.
 */
#ifndef FMU_COMMON3_H
#define FMU_COMMON3_H

#include "fmi3Functions.h"

#define FMU_VALUE_REFERENCE fmi3ValueReference
#define FMU_LOGGER fmi3LogMessageCallback
#define FMU_DIRECTIONAL_FLAG "providesDirectionalDerivatives"
#include "fmu_core.h"

/* fmu_core.h's status values are fmi3Status's (a negative array size when not) */
typedef char fmu_status_values_agree[((int)fmi3OK == FMU_OK && (int)fmi3Warning == FMU_WARNING
                                      && (int)fmi3Error == FMU_ERROR) ? 1 : -1];

static void fmu_emit(FmuInstance *m, fmu_status status, const char *category,
                     const char *message)
{
    m->logger(m->env, (fmi3Status)status, category, message);
}

/* ---------------------------------------------------------- common functions */
const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn,
                               size_t nCategories, const fmi3String categories[])
{
    (void)nCategories; (void)categories;
    return (fmi3Status)fmu_set_logging((FmuInstance *)instance, loggingOn);
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName,
                                          fmi3String instantiationToken,
                                          fmi3String resourcePath,
                                          fmi3Boolean visible,
                                          fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage)
{
    (void)resourcePath; (void)visible;
    if (instanceName == NULL || instantiationToken == NULL
        || strcmp(instantiationToken, MODEL_GUID) != 0) {
        if (logMessage != NULL)
            logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                       "fmi3InstantiateModelExchange: needs an instance name "
                       "and the instantiationToken " MODEL_GUID);
        return NULL;
    }
    return fmu_new(instanceName, logMessage, instanceEnvironment, loggingOn);
}

/* The model description has no CoSimulation or ScheduledExecution element. */
fmi3Instance fmi3InstantiateCoSimulation(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
    fmi3Boolean earlyReturnAllowed, const fmi3ValueReference requiredIntermediateVariables[],
    size_t nRequiredIntermediateVariables, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3IntermediateUpdateCallback intermediateUpdate)
{
    (void)instanceName; (void)instantiationToken; (void)resourcePath; (void)visible;
    (void)loggingOn; (void)eventModeUsed; (void)earlyReturnAllowed;
    (void)requiredIntermediateVariables; (void)nRequiredIntermediateVariables;
    (void)intermediateUpdate;
    if (logMessage != NULL)
        logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                   "fmi3InstantiateCoSimulation: the FMU offers model exchange only");
    return NULL;
}

fmi3Instance fmi3InstantiateScheduledExecution(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
    fmi3LockPreemptionCallback lockPreemption, fmi3UnlockPreemptionCallback unlockPreemption)
{
    (void)instanceName; (void)instantiationToken; (void)resourcePath; (void)visible;
    (void)loggingOn; (void)clockUpdate; (void)lockPreemption; (void)unlockPreemption;
    if (logMessage != NULL)
        logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                   "fmi3InstantiateScheduledExecution: the FMU offers model exchange only");
    return NULL;
}


void fmi3FreeInstance(fmi3Instance instance) { fmu_free((FmuInstance *)instance); }

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined,
                                       fmi3Float64 tolerance, fmi3Float64 startTime,
                                       fmi3Boolean stopTimeDefined, fmi3Float64 stopTime)
{
    FmuInstance *m = (FmuInstance *)instance;
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    if (fmu_set_time(m, "fmi3EnterInitializationMode", MODE_INSTANTIATED,
                     startTime) != FMU_OK)
        return fmi3Error;
    m->d.mode = MODE_INIT;
    return fmi3OK;
}

/* Model exchange leaves initialization in Event Mode (FMI 3.0.1 chapter 3). */
fmi3Status fmi3ExitInitializationMode(fmi3Instance instance)
{
    return (fmi3Status)fmu_exit_init((FmuInstance *)instance, "fmi3ExitInitializationMode");
}

fmi3Status fmi3EnterEventMode(fmi3Instance instance)
{
    return (fmi3Status)fmu_enter((FmuInstance *)instance, "fmi3EnterEventMode",
                                 MODE_EVENT | MODE_CONT, MODE_EVENT);
}

fmi3Status fmi3Terminate(fmi3Instance instance)
{
    return (fmi3Status)fmu_enter((FmuInstance *)instance, "fmi3Terminate",
                                 MODE_EVENT | MODE_CONT, MODE_TERMINATED);
}

fmi3Status fmi3Reset(fmi3Instance instance)
{
    return (fmi3Status)fmu_reset((FmuInstance *)instance, "fmi3Reset");
}

/* ---------------------------------------------------------- variable access */
/* nValues is the number of elements of the value references (a scalar's 1,
 * an array's its size; FMI 3.0.1 chapter 2, "Serialization of Array
 * Variables"). */
fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference vr[],
                          size_t nvr, fmi3Float64 values[], size_t nValues)
{
    return (fmi3Status)fmu_get_real((FmuInstance *)instance, "fmi3GetFloat64", vr, nvr,
                                    values, nValues);
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference vr[],
                          size_t nvr, const fmi3Float64 values[], size_t nValues)
{
    return (fmi3Status)fmu_set_real((FmuInstance *)instance, "fmi3SetFloat64", vr, nvr,
                                    values, nValues);
}

/* No variables of the other types: only empty requests succeed. */
#define FMU_NO_VARIABLES(fname, ctype)                                          \
    fmi3Status fname(fmi3Instance instance, const fmi3ValueReference vr[],     \
                     size_t nvr, ctype values[], size_t nValues)               \
    {                                                                          \
        (void)vr; (void)values;                                                \
        return (fmi3Status)fmu_no_variables((FmuInstance *)instance, #fname,   \
                                            nvr, nValues);                     \
    }
FMU_NO_VARIABLES(fmi3GetFloat32, fmi3Float32)
FMU_NO_VARIABLES(fmi3GetInt8, fmi3Int8)
FMU_NO_VARIABLES(fmi3GetUInt8, fmi3UInt8)
FMU_NO_VARIABLES(fmi3GetInt16, fmi3Int16)
FMU_NO_VARIABLES(fmi3GetUInt16, fmi3UInt16)
FMU_NO_VARIABLES(fmi3GetInt32, fmi3Int32)
FMU_NO_VARIABLES(fmi3GetUInt32, fmi3UInt32)
FMU_NO_VARIABLES(fmi3GetInt64, fmi3Int64)
FMU_NO_VARIABLES(fmi3GetBoolean, fmi3Boolean)
FMU_NO_VARIABLES(fmi3GetString, fmi3String)
FMU_NO_VARIABLES(fmi3SetFloat32, const fmi3Float32)
FMU_NO_VARIABLES(fmi3SetInt8, const fmi3Int8)
FMU_NO_VARIABLES(fmi3SetUInt8, const fmi3UInt8)
FMU_NO_VARIABLES(fmi3SetInt16, const fmi3Int16)
FMU_NO_VARIABLES(fmi3SetUInt16, const fmi3UInt16)
FMU_NO_VARIABLES(fmi3SetInt32, const fmi3Int32)
FMU_NO_VARIABLES(fmi3SetUInt32, const fmi3UInt32)
FMU_NO_VARIABLES(fmi3SetInt64, const fmi3Int64)
FMU_NO_VARIABLES(fmi3SetBoolean, const fmi3Boolean)
FMU_NO_VARIABLES(fmi3SetString, const fmi3String)

/* The structural parameters (UInt64; none in a scalar model): read in any
 * mode, set in Configuration Mode. */
fmi3Status fmi3GetUInt64(fmi3Instance instance, const fmi3ValueReference vr[],
                         size_t nvr, fmi3UInt64 values[], size_t nValues)
{
    return (fmi3Status)fmu_structural((FmuInstance *)instance, "fmi3GetUInt64", vr, nvr,
                                      (unsigned long long *)values, nValues, 0);
}

fmi3Status fmi3SetUInt64(fmi3Instance instance, const fmi3ValueReference vr[],
                         size_t nvr, const fmi3UInt64 values[], size_t nValues)
{
    return (fmi3Status)fmu_structural((FmuInstance *)instance, "fmi3SetUInt64", vr, nvr,
                                      (unsigned long long *)values, nValues, 1);
}

/* Configuration Mode (FMI 3.0.1 chapter 3's state machine), for the
 * structural parameters: refused by a model without them. */
fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance)
{
    return (fmi3Status)fmu_configuration((FmuInstance *)instance,
                                         "fmi3EnterConfigurationMode", 1);
}

fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance)
{
    return (fmi3Status)fmu_configuration((FmuInstance *)instance,
                                         "fmi3ExitConfigurationMode", 0);
}

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                         size_t valueSizes[], fmi3Binary values[], size_t nValues)
{
    (void)vr; (void)valueSizes; (void)values;
    return (fmi3Status)fmu_no_variables((FmuInstance *)instance, "fmi3GetBinary",
                                        nvr, nValues);
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                         const size_t valueSizes[], const fmi3Binary values[], size_t nValues)
{
    (void)vr; (void)valueSizes; (void)values;
    return (fmi3Status)fmu_no_variables((FmuInstance *)instance, "fmi3SetBinary",
                                        nvr, nValues);
}

/* ---------------------------------------------------------- not offered
 * (no clocks, no per-element dependencies, no
 * serialization, no adjoint derivatives, no co-simulation or scheduled
 * execution): fmi3Error and a log line naming the function. */
#define FMU_NOT_OFFERED(fname, params, unused)                                 \
    fmi3Status fname params                                                    \
    {                                                                          \
        unused;                                                                \
        return fmu_error((FmuInstance *)instance, #fname ": not offered by this FMU"); \
    }
FMU_NOT_OFFERED(fmi3GetClock, (fmi3Instance instance, const fmi3ValueReference vr[],
                size_t nvr, fmi3Clock values[]), (void)vr; (void)nvr; (void)values)
FMU_NOT_OFFERED(fmi3SetClock, (fmi3Instance instance, const fmi3ValueReference vr[],
                size_t nvr, const fmi3Clock values[]), (void)vr; (void)nvr; (void)values)
FMU_NOT_OFFERED(fmi3GetNumberOfVariableDependencies, (fmi3Instance instance,
                fmi3ValueReference vr, size_t *n), (void)vr; (void)n)
FMU_NOT_OFFERED(fmi3GetVariableDependencies, (fmi3Instance instance,
                fmi3ValueReference dependent, size_t elementIndicesOfDependent[],
                fmi3ValueReference independents[], size_t elementIndicesOfIndependents[],
                fmi3DependencyKind dependencyKinds[], size_t nDependencies),
                (void)dependent; (void)elementIndicesOfDependent; (void)independents;
                (void)elementIndicesOfIndependents; (void)dependencyKinds;
                (void)nDependencies)
FMU_NOT_OFFERED(fmi3SerializedFMUStateSize, (fmi3Instance instance,
                fmi3FMUState FMUState, size_t *size), (void)FMUState; (void)size)
FMU_NOT_OFFERED(fmi3SerializeFMUState, (fmi3Instance instance, fmi3FMUState FMUState,
                fmi3Byte serializedState[], size_t size),
                (void)FMUState; (void)serializedState; (void)size)
FMU_NOT_OFFERED(fmi3DeserializeFMUState, (fmi3Instance instance,
                const fmi3Byte serializedState[], size_t size, fmi3FMUState *FMUState),
                (void)serializedState; (void)size; (void)FMUState)
FMU_NOT_OFFERED(fmi3GetAdjointDerivative, (fmi3Instance instance,
                const fmi3ValueReference unknowns[], size_t nUnknowns,
                const fmi3ValueReference knowns[], size_t nKnowns,
                const fmi3Float64 seed[], size_t nSeed,
                fmi3Float64 sensitivity[], size_t nSensitivity),
                (void)unknowns; (void)nUnknowns; (void)knowns; (void)nKnowns;
                (void)seed; (void)nSeed; (void)sensitivity; (void)nSensitivity)
FMU_NOT_OFFERED(fmi3GetIntervalDecimal, (fmi3Instance instance,
                const fmi3ValueReference vr[], size_t nvr, fmi3Float64 intervals[],
                fmi3IntervalQualifier qualifiers[]),
                (void)vr; (void)nvr; (void)intervals; (void)qualifiers)
FMU_NOT_OFFERED(fmi3GetIntervalFraction, (fmi3Instance instance,
                const fmi3ValueReference vr[], size_t nvr, fmi3UInt64 counters[],
                fmi3UInt64 resolutions[], fmi3IntervalQualifier qualifiers[]),
                (void)vr; (void)nvr; (void)counters; (void)resolutions; (void)qualifiers)
FMU_NOT_OFFERED(fmi3GetShiftDecimal, (fmi3Instance instance,
                const fmi3ValueReference vr[], size_t nvr, fmi3Float64 shifts[]),
                (void)vr; (void)nvr; (void)shifts)
FMU_NOT_OFFERED(fmi3GetShiftFraction, (fmi3Instance instance,
                const fmi3ValueReference vr[], size_t nvr, fmi3UInt64 counters[],
                fmi3UInt64 resolutions[]),
                (void)vr; (void)nvr; (void)counters; (void)resolutions)
FMU_NOT_OFFERED(fmi3SetIntervalDecimal, (fmi3Instance instance,
                const fmi3ValueReference vr[], size_t nvr, const fmi3Float64 intervals[]),
                (void)vr; (void)nvr; (void)intervals)
FMU_NOT_OFFERED(fmi3SetIntervalFraction, (fmi3Instance instance,
                const fmi3ValueReference vr[], size_t nvr, const fmi3UInt64 counters[],
                const fmi3UInt64 resolutions[]),
                (void)vr; (void)nvr; (void)counters; (void)resolutions)
FMU_NOT_OFFERED(fmi3SetShiftDecimal, (fmi3Instance instance,
                const fmi3ValueReference vr[], size_t nvr, const fmi3Float64 shifts[]),
                (void)vr; (void)nvr; (void)shifts)
FMU_NOT_OFFERED(fmi3SetShiftFraction, (fmi3Instance instance,
                const fmi3ValueReference vr[], size_t nvr, const fmi3UInt64 counters[],
                const fmi3UInt64 resolutions[]),
                (void)vr; (void)nvr; (void)counters; (void)resolutions)
FMU_NOT_OFFERED(fmi3EnterStepMode, (fmi3Instance instance), (void)0)
FMU_NOT_OFFERED(fmi3GetOutputDerivatives, (fmi3Instance instance,
                const fmi3ValueReference vr[], size_t nvr, const fmi3Int32 orders[],
                fmi3Float64 values[], size_t nValues),
                (void)vr; (void)nvr; (void)orders; (void)values; (void)nValues)
FMU_NOT_OFFERED(fmi3DoStep, (fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime),
                (void)currentCommunicationPoint; (void)communicationStepSize;
                (void)noSetFMUStatePriorToCurrentPoint; (void)eventHandlingNeeded;
                (void)terminateSimulation; (void)earlyReturn; (void)lastSuccessfulTime)
FMU_NOT_OFFERED(fmi3ActivateModelPartition, (fmi3Instance instance,
                fmi3ValueReference clockReference, fmi3Float64 activationTime),
                (void)clockReference; (void)activationTime)


/* ---------------------------------------------------------- FMU state */
fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState)
{
    return (fmi3Status)fmu_get_state((FmuInstance *)instance, "fmi3GetFMUState", FMUState);
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState)
{
    return (fmi3Status)fmu_set_state((FmuInstance *)instance, "fmi3SetFMUState", FMUState);
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState)
{
    (void)instance;
    return (fmi3Status)fmu_free_state(FMUState);
}

/* ---------------------------------------------------------- directional derivatives */
/* FMI 3.0.1 chapter 2, partial derivatives: nSeed and nSensitivity count the
 * elements of the knowns and of the unknowns. */
fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance,
                                        const fmi3ValueReference unknowns[], size_t nUnknowns,
                                        const fmi3ValueReference knowns[], size_t nKnowns,
                                        const fmi3Float64 seed[], size_t nSeed,
                                        fmi3Float64 sensitivity[], size_t nSensitivity)
{
    return (fmi3Status)fmu_directional_derivative(
        (FmuInstance *)instance, "fmi3GetDirectionalDerivative", unknowns, nUnknowns,
        knowns, nKnowns, seed, nSeed, sensitivity, nSensitivity);
}

/* ---------------------------------------------------------- model exchange */
/* No discrete-time variables: there is nothing to evaluate. */
fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance)
{
    return (fmi3Status)fmu_check((FmuInstance *)instance, "fmi3EvaluateDiscreteStates",
                                 MODE_EVENT | MODE_CONT, 1);
}

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance,
                                    fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation,
                                    fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged,
                                    fmi3Boolean *nextEventTimeDefined,
                                    fmi3Float64 *nextEventTime)
{
    FmuInstance *m = (FmuInstance *)instance;
    if (fmu_check(m, "fmi3UpdateDiscreteStates", MODE_EVENT,
                  discreteStatesNeedUpdate != NULL && terminateSimulation != NULL
                  && nominalsOfContinuousStatesChanged != NULL
                  && valuesOfContinuousStatesChanged != NULL
                  && nextEventTimeDefined != NULL && nextEventTime != NULL) != FMU_OK)
        return fmi3Error;
    *valuesOfContinuousStatesChanged =
        fmu_event_update(m, "fmi3UpdateDiscreteStates") ? true : false;
    *discreteStatesNeedUpdate = false;
    *terminateSimulation = false;
    *nominalsOfContinuousStatesChanged = false;
    *nextEventTimeDefined = false;
    *nextEventTime = 0.0;
    return fmi3OK;
}

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance)
{
    return (fmi3Status)fmu_enter((FmuInstance *)instance, "fmi3EnterContinuousTimeMode",
                                 MODE_EVENT, MODE_CONT);
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance,
                                       fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode,
                                       fmi3Boolean *terminateSimulation)
{
    (void)noSetFMUStatePriorToCurrentPoint;
    if (fmu_check((FmuInstance *)instance, "fmi3CompletedIntegratorStep", MODE_CONT,
                  enterEventMode != NULL && terminateSimulation != NULL) != FMU_OK)
        return fmi3Error;
    *enterEventMode = false;
    *terminateSimulation = false;
    return fmi3OK;
}

fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time)
{
    return (fmi3Status)fmu_set_time((FmuInstance *)instance, "fmi3SetTime",
                                    MODE_EVENT | MODE_CONT, time);
}

fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 x[], size_t nx)
{
    return (fmi3Status)fmu_set_states((FmuInstance *)instance, "fmi3SetContinuousStates",
                                      x, nx);
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[],
                                             size_t nx)
{
    return (fmi3Status)fmu_get_derivatives((FmuInstance *)instance,
                                           "fmi3GetContinuousStateDerivatives",
                                           derivatives, nx);
}

fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[],
                                  size_t ni)
{
    return (fmi3Status)fmu_get_event_indicators((FmuInstance *)instance,
                                                "fmi3GetEventIndicators", eventIndicators, ni);
}

fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 x[], size_t nx)
{
    return (fmi3Status)fmu_get_states((FmuInstance *)instance, "fmi3GetContinuousStates",
                                      x, nx);
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[],
                                             size_t nx)
{
    return (fmi3Status)fmu_get_nominals((FmuInstance *)instance,
                                        "fmi3GetNominalsOfContinuousStates", nominals, nx);
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *nEventIndicators)
{
    if (fmu_check((FmuInstance *)instance, "fmi3GetNumberOfEventIndicators", MODE_ANY,
                  nEventIndicators != NULL) != FMU_OK)
        return fmi3Error;
    *nEventIndicators = N_EVENT_INDICATORS;
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *nContinuousStates)
{
    if (fmu_check((FmuInstance *)instance, "fmi3GetNumberOfContinuousStates", MODE_ANY,
                  nContinuousStates != NULL) != FMU_OK)
        return fmi3Error;
    *nContinuousStates = FMU_N_STATES((FmuInstance *)instance);
    return fmi3OK;
}

#endif /* FMU_COMMON3_H */
