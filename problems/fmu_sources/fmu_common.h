/*
 * fmu_common.h -- the FMI 2.0 model-exchange function set shared by the
 * FMUs of integrator-bench's native problems (spring_pendulum, two_mass,
 * bouncing_ball). Plain C99, no library beyond the C standard library and
 * the FMI 2.0 headers.
 *
 * Source: Modelica Association, "Functional Mock-up Interface for Model
 * Exchange and Co-Simulation", version 2.0.4 (2022): sect. 2.1 (common
 * functions, FMU state, directional derivatives), sect. 3.2 (model-exchange
 * functions and the state machine of their calling sequence), sect. 2.2.8
 * (ModelStructure).
 *
 * Value references, the model file's defines and its hooks are those of
 * fmu_core.h (see there), which holds the logic this header shares with
 * fmu_common3.h, the FMI 3.0 function set (selected by the preprocessor
 * definition FMI_VERSION=3); the functions below adapt the FMI 2.0
 * signatures to it. The hooks use the neutral type `real` (= fmi2Real =
 * double) and return plain int flags.
 */
#ifndef FMU_COMMON_H
#define FMU_COMMON_H

#include "fmi2Functions.h"

#define FMU_VALUE_REFERENCE fmi2ValueReference
#define FMU_LOGGER fmi2CallbackLogger
#define FMU_DIRECTIONAL_FLAG "providesDirectionalDerivative"
#include "fmu_core.h"

/* fmu_core.h's status values are fmi2Status's (a negative array size when not) */
typedef char fmu_status_values_agree[((int)fmi2OK == FMU_OK && (int)fmi2Warning == FMU_WARNING
                                      && (int)fmi2Error == FMU_ERROR) ? 1 : -1];

static void fmu_emit(FmuInstance *m, fmu_status status, const char *category,
                     const char *message)
{
    m->logger(m->env, m->name, (fmi2Status)status, category, "%s", message);
}

/* ---------------------------------------------------------- common functions */
const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn,
                               size_t nCategories, const fmi2String categories[])
{
    (void)nCategories; (void)categories;
    return (fmi2Status)fmu_set_logging((FmuInstance *)c, loggingOn);
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType,
                              fmi2String fmuGUID, fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn)
{
    (void)fmuResourceLocation; (void)visible;
    if (instanceName == NULL || fmuGUID == NULL || fmuType != fmi2ModelExchange
        || strcmp(fmuGUID, MODEL_GUID) != 0) {
        if (functions != NULL && functions->logger != NULL)
            functions->logger(functions->componentEnvironment,
                              instanceName ? instanceName : "?", fmi2Error,
                              "logStatusError", "%s",
                              "fmi2Instantiate: needs an instance name, "
                              "fmi2ModelExchange and the GUID " MODEL_GUID);
        return NULL;
    }
    return fmu_new(instanceName, functions != NULL ? functions->logger : NULL,
                   functions != NULL ? functions->componentEnvironment : NULL, loggingOn);
}

void fmi2FreeInstance(fmi2Component c) { fmu_free((FmuInstance *)c); }

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined,
                               fmi2Real tolerance, fmi2Real startTime,
                               fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    return (fmi2Status)fmu_set_time((FmuInstance *)c, "fmi2SetupExperiment",
                                  MODE_INSTANTIATED, startTime);
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c)
{
    return (fmi2Status)fmu_enter((FmuInstance *)c, "fmi2EnterInitializationMode",
                                 MODE_INSTANTIATED, MODE_INIT);
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c)
{
    return (fmi2Status)fmu_exit_init((FmuInstance *)c, "fmi2ExitInitializationMode");
}

fmi2Status fmi2Terminate(fmi2Component c)
{
    return (fmi2Status)fmu_enter((FmuInstance *)c, "fmi2Terminate",
                                 MODE_EVENT | MODE_CONT, MODE_TERMINATED);
}

fmi2Status fmi2Reset(fmi2Component c)
{
    return (fmi2Status)fmu_reset((FmuInstance *)c, "fmi2Reset");
}

/* ---------------------------------------------------------- variable access */
fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       fmi2Real value[])
{
    return (fmi2Status)fmu_get_real((FmuInstance *)c, "fmi2GetReal", vr, nvr, value, nvr);
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[])
{
    return (fmi2Status)fmu_set_real((FmuInstance *)c, "fmi2SetReal", vr, nvr, value, nvr);
}

/* No Integer, Boolean or String variables: only empty requests succeed. */
#define FMU_NO_VARIABLES(fname, ctype)                                          \
    fmi2Status fname(fmi2Component c, const fmi2ValueReference vr[],           \
                     size_t nvr, ctype value[])                                \
    {                                                                          \
        (void)vr; (void)value;                                                 \
        return (fmi2Status)fmu_no_variables((FmuInstance *)c, #fname, nvr, nvr); \
    }
FMU_NO_VARIABLES(fmi2GetInteger, fmi2Integer)
FMU_NO_VARIABLES(fmi2GetBoolean, fmi2Boolean)
FMU_NO_VARIABLES(fmi2GetString, fmi2String)
FMU_NO_VARIABLES(fmi2SetInteger, const fmi2Integer)
FMU_NO_VARIABLES(fmi2SetBoolean, const fmi2Boolean)
FMU_NO_VARIABLES(fmi2SetString, const fmi2String)

/* ---------------------------------------------------------- FMU state */
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    return (fmi2Status)fmu_get_state((FmuInstance *)c, "fmi2GetFMUstate", FMUstate);
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate)
{
    return (fmi2Status)fmu_set_state((FmuInstance *)c, "fmi2SetFMUstate", FMUstate);
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    (void)c;
    return (fmi2Status)fmu_free_state(FMUstate);
}

/* canSerializeFMUstate="false" */
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate,
                                      size_t *size)
{
    (void)FMUstate; (void)size;
    return (fmi2Status)fmu_error((FmuInstance *)c,
                                 "fmi2SerializedFMUstateSize: not supported");
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate,
                                 fmi2Byte serializedState[], size_t size)
{
    (void)FMUstate; (void)serializedState; (void)size;
    return (fmi2Status)fmu_error((FmuInstance *)c, "fmi2SerializeFMUstate: not supported");
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[],
                                   size_t size, fmi2FMUstate *FMUstate)
{
    (void)serializedState; (void)size; (void)FMUstate;
    return (fmi2Status)fmu_error((FmuInstance *)c, "fmi2DeSerializeFMUstate: not supported");
}

/* ---------------------------------------------------------- directional derivatives */
/* FMI 2.0.4 sect. 2.1.9: every variable is a scalar, one seed per known. */
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c,
                                        const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[])
{
    return (fmi2Status)fmu_directional_derivative(
        (FmuInstance *)c, "fmi2GetDirectionalDerivative", vUnknown_ref, nUnknown,
        vKnown_ref, nKnown, dvKnown, nKnown, dvUnknown, nUnknown);
}

/* ---------------------------------------------------------- co-simulation
 * (not offered: the modelDescription has no CoSimulation element) */

/* ---------------------------------------------------------- model exchange */
fmi2Status fmi2EnterEventMode(fmi2Component c)
{
    return (fmi2Status)fmu_enter((FmuInstance *)c, "fmi2EnterEventMode",
                                 MODE_EVENT | MODE_CONT, MODE_EVENT);
}

fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *info)
{
    FmuInstance *m = (FmuInstance *)c;
    if (fmu_check(m, "fmi2NewDiscreteStates", MODE_EVENT, info != NULL) != FMU_OK)
        return fmi2Error;
    info->valuesOfContinuousStatesChanged = fmu_event_update(m, "fmi2NewDiscreteStates");
    info->newDiscreteStatesNeeded = fmi2False;
    info->terminateSimulation = fmi2False;
    info->nominalsOfContinuousStatesChanged = fmi2False;
    info->nextEventTimeDefined = fmi2False;
    info->nextEventTime = 0.0;
    return fmi2OK;
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c)
{
    return (fmi2Status)fmu_enter((FmuInstance *)c, "fmi2EnterContinuousTimeMode",
                                 MODE_EVENT, MODE_CONT);
}

fmi2Status fmi2CompletedIntegratorStep(fmi2Component c,
                                       fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi2Boolean *enterEventMode,
                                       fmi2Boolean *terminateSimulation)
{
    (void)noSetFMUStatePriorToCurrentPoint;
    if (fmu_check((FmuInstance *)c, "fmi2CompletedIntegratorStep", MODE_CONT,
                  enterEventMode != NULL && terminateSimulation != NULL) != FMU_OK)
        return fmi2Error;
    *enterEventMode = fmi2False;
    *terminateSimulation = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2SetTime(fmi2Component c, fmi2Real time)
{
    return (fmi2Status)fmu_set_time((FmuInstance *)c, "fmi2SetTime", MODE_EVENT | MODE_CONT,
                                  time);
}

fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx)
{
    return (fmi2Status)fmu_set_states((FmuInstance *)c, "fmi2SetContinuousStates", x, nx);
}

fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real derivatives[], size_t nx)
{
    return (fmi2Status)fmu_get_derivatives((FmuInstance *)c, "fmi2GetDerivatives",
                                           derivatives, nx);
}

fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real eventIndicators[], size_t ni)
{
    return (fmi2Status)fmu_get_event_indicators((FmuInstance *)c, "fmi2GetEventIndicators",
                                                eventIndicators, ni);
}

fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx)
{
    return (fmi2Status)fmu_get_states((FmuInstance *)c, "fmi2GetContinuousStates", x, nx);
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x_nominal[],
                                             size_t nx)
{
    return (fmi2Status)fmu_get_nominals((FmuInstance *)c,
                                        "fmi2GetNominalsOfContinuousStates", x_nominal, nx);
}

#endif /* FMU_COMMON_H */
