/*
 * fmu_common3.h -- the FMI 3.0 model-exchange function set shared by the
 * FMUs of integrator-bench's native problems (spring_pendulum, two_mass,
 * bouncing_ball): the FMI 3.0 counterpart of fmu_common.h over the SAME model
 * hooks, so that each model's equations are written once. A model file
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
 * outputs), the model file's defines and hooks are those of
 * fmu_common.h (see there); the hooks use the neutral type `real`
 * (= fmi3Float64 = double) and return plain int flags. MODEL_GUID is the
 * instantiationToken of modelDescription3.xml.
 *
 * Every function of fmi3Functions.h is exported (importers such as fmpy bind
 * them all). Those of interfaces the FMUs do not offer (Co-Simulation,
 * Scheduled Execution, clocks, configuration mode) and the capabilities the
 * model description declares false (serialization, adjoint derivatives,
 * per-element dependencies) return fmi3Error with a log line.
 */
#ifndef FMU_COMMON3_H
#define FMU_COMMON3_H

#include <stdlib.h>
#include <string.h>
#include <stdio.h>
#include "fmi3Functions.h"

typedef fmi3Float64 real;

#define VR_DER0 (N_STATES)
#define VR_PAR0 (2 * N_STATES)
#define VR_TIME (2 * N_STATES + N_PARAMS)
#ifndef N_OUTPUTS
#define N_OUTPUTS 0
#endif
#define VR_OUT0 (VR_TIME + 1)
#define VR_END (VR_OUT0 + N_OUTPUTS)

/* ---------------------------------------------------------- model hooks */
/* start values: states (ignored when STATES_CALCULATED), then parameters */
static const real START[N_STATES + N_PARAMS];
/* the states' calculated start values from the parameters p */
static void model_initial(real *s, const real *p);
/* dx = f(t, s; p) */
static void model_derivatives(real t, const real *s, const real *p, real *dx);
#if PROVIDES_DIRECTIONAL_DERIVATIVE
/* J[i][j] = d dx_i / d s_j */
static void model_jacobian(real t, const real *s, const real *p,
                           real J[N_STATES][N_STATES]);
#endif
#if N_OUTPUTS
/* out[N_OUTPUTS] = g(t, s; p), the computed outputs */
static void model_outputs(real t, const real *s, const real *p, real *out);
#if PROVIDES_DIRECTIONAL_DERIVATIVE
/* G[i][j] = d out_i / d s_j */
static void model_output_jacobian(real t, const real *s, const real *p,
                                  real G[N_OUTPUTS][N_STATES]);
#endif
#else
/* a model without computed outputs */
static void model_outputs(real t, const real *s, const real *p, real *out)
{
    (void)t; (void)s; (void)p; (void)out;
}
#endif
#if N_EVENT_INDICATORS
/* z[N_EVENT_INDICATORS] */
static void model_event_indicators(real t, const real *s, const real *p, real *z);
/* the discrete update at an event; returns whether a state changed */
static int model_event_update(real t, real *s, const real *p);
#else
/* a model without events: no indicators, and an event changes nothing */
static void model_event_indicators(real t, const real *s, const real *p, real *z)
{
    (void)t; (void)s; (void)p; (void)z;
}

static int model_event_update(real t, real *s, const real *p)
{
    (void)t; (void)s; (void)p;
    return 0;
}
#endif

/* ---------------------------------------------------------- the instance */
enum {
    MODE_INSTANTIATED = 1, MODE_INIT = 2, MODE_EVENT = 4, MODE_CONT = 8,
    MODE_TERMINATED = 16, MODE_ERROR = 32
};
#define MODE_ANY 63
#define MODE_AFTER_INSTANTIATED (MODE_INIT | MODE_EVENT | MODE_CONT | \
                                 MODE_TERMINATED | MODE_ERROR)

/* Everything fmi3GetFMUState copies. */
typedef struct {
    real time;
    real s[N_STATES];
    real p[N_PARAMS];
    int mode;
} FmuData;

typedef struct {
    FmuData d;
    char *name;
    fmi3LogMessageCallback logger;
    fmi3InstanceEnvironment env;
    fmi3Boolean logging_on;
} FmuInstance;

static void fmu_log(FmuInstance *m, fmi3Status status, const char *category,
                    const char *message)
{
    if (m->logger != NULL && (m->logging_on || status >= fmi3Warning))
        m->logger(m->env, status, category, message);
}

/* Whether `fname` may be called in the current mode (fmi3Error and a log
 * line when not). */
static int fmu_allowed(FmuInstance *m, const char *fname, int modes)
{
    char msg[160];
    if (m == NULL)
        return 0;
    if (m->d.mode & modes)
        return 1;
    snprintf(msg, sizeof msg, "%s: not allowed in the current mode (%d)",
             fname, m->d.mode);
    fmu_log(m, fmi3Error, "logStatusError", msg);
    return 0;
}

static fmi3Status fmu_error(FmuInstance *m, const char *message)
{
    if (m != NULL)
        fmu_log(m, fmi3Error, "logStatusError", message);
    return fmi3Error;
}

static void fmu_set_start(FmuInstance *m)
{
    int i;
    m->d.time = 0.0;
    for (i = 0; i < N_STATES; i++)
        m->d.s[i] = START[i];
    for (i = 0; i < N_PARAMS; i++)
        m->d.p[i] = START[N_STATES + i];
    m->d.mode = MODE_INSTANTIATED;
}

/* Before initialization ends, calculated states follow the parameters. */
static void fmu_update_calculated(FmuInstance *m)
{
#if STATES_CALCULATED
    if (m->d.mode & (MODE_INSTANTIATED | MODE_INIT))
        model_initial(m->d.s, m->d.p);
#else
    (void)m;
    (void)model_initial;    /* states with exact start values */
#endif
}

/* ---------------------------------------------------------- common functions */
const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn,
                               size_t nCategories, const fmi3String categories[])
{
    FmuInstance *m = (FmuInstance *)instance;
    (void)nCategories; (void)categories;
    if (m == NULL)
        return fmi3Error;
    m->logging_on = loggingOn;
    return fmi3OK;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName,
                                          fmi3String instantiationToken,
                                          fmi3String resourcePath,
                                          fmi3Boolean visible,
                                          fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage)
{
    FmuInstance *m;
    (void)resourcePath; (void)visible;
    if (instanceName == NULL || instantiationToken == NULL
        || strcmp(instantiationToken, MODEL_GUID) != 0) {
        if (logMessage != NULL)
            logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                       "fmi3InstantiateModelExchange: needs an instance name "
                       "and the instantiationToken " MODEL_GUID);
        return NULL;
    }
    m = (FmuInstance *)calloc(1, sizeof(FmuInstance));
    if (m == NULL)
        return NULL;
    m->name = (char *)malloc(strlen(instanceName) + 1);
    if (m->name == NULL) {
        free(m);
        return NULL;
    }
    strcpy(m->name, instanceName);
    m->logger = logMessage;
    m->env = instanceEnvironment;
    m->logging_on = loggingOn;
    fmu_set_start(m);
    return m;
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

void fmi3FreeInstance(fmi3Instance instance)
{
    FmuInstance *m = (FmuInstance *)instance;
    if (m == NULL)
        return;
    free(m->name);
    free(m);
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined,
                                       fmi3Float64 tolerance, fmi3Float64 startTime,
                                       fmi3Boolean stopTimeDefined, fmi3Float64 stopTime)
{
    FmuInstance *m = (FmuInstance *)instance;
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    if (!fmu_allowed(m, "fmi3EnterInitializationMode", MODE_INSTANTIATED))
        return fmi3Error;
    m->d.time = startTime;
    m->d.mode = MODE_INIT;
    return fmi3OK;
}

/* Model exchange leaves initialization in Event Mode (FMI 3.0.1 chapter 3). */
fmi3Status fmi3ExitInitializationMode(fmi3Instance instance)
{
    FmuInstance *m = (FmuInstance *)instance;
    if (!fmu_allowed(m, "fmi3ExitInitializationMode", MODE_INIT))
        return fmi3Error;
    fmu_update_calculated(m);
    m->d.mode = MODE_EVENT;
    return fmi3OK;
}

fmi3Status fmi3EnterEventMode(fmi3Instance instance)
{
    FmuInstance *m = (FmuInstance *)instance;
    if (!fmu_allowed(m, "fmi3EnterEventMode", MODE_EVENT | MODE_CONT))
        return fmi3Error;
    m->d.mode = MODE_EVENT;
    return fmi3OK;
}

fmi3Status fmi3Terminate(fmi3Instance instance)
{
    FmuInstance *m = (FmuInstance *)instance;
    if (!fmu_allowed(m, "fmi3Terminate", MODE_EVENT | MODE_CONT))
        return fmi3Error;
    m->d.mode = MODE_TERMINATED;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance instance)
{
    FmuInstance *m = (FmuInstance *)instance;
    if (!fmu_allowed(m, "fmi3Reset", MODE_ANY))
        return fmi3Error;
    fmu_set_start(m);
    return fmi3OK;
}

/* ---------------------------------------------------------- variable access */
/* All variables are scalar: nValues must equal nValueReferences. */
fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference vr[],
                          size_t nvr, fmi3Float64 values[], size_t nValues)
{
    FmuInstance *m = (FmuInstance *)instance;
    real dx[N_STATES];
    real out[N_OUTPUTS + 1];        /* + 1: no empty array when N_OUTPUTS = 0 */
    size_t i;
    if (!fmu_allowed(m, "fmi3GetFloat64", MODE_AFTER_INSTANTIATED))
        return fmi3Error;
    if (nValues != nvr)
        return fmu_error(m, "fmi3GetFloat64: nValues differs from the number of "
                            "value references (all variables are scalar)");
    if (nvr > 0 && (vr == NULL || values == NULL))
        return fmu_error(m, "fmi3GetFloat64: NULL argument");
    fmu_update_calculated(m);
    model_derivatives(m->d.time, m->d.s, m->d.p, dx);
    model_outputs(m->d.time, m->d.s, m->d.p, out);
    for (i = 0; i < nvr; i++) {
        fmi3ValueReference r = vr[i];
        if (r < VR_DER0)
            values[i] = m->d.s[r];
        else if (r < VR_PAR0)
            values[i] = dx[r - VR_DER0];
        else if (r < VR_TIME)
            values[i] = m->d.p[r - VR_PAR0];
        else if (r == VR_TIME)
            values[i] = m->d.time;
        else if (r < VR_END)
            values[i] = out[r - VR_OUT0];
        else
            return fmu_error(m, "fmi3GetFloat64: unknown value reference");
    }
    return fmi3OK;
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference vr[],
                          size_t nvr, const fmi3Float64 values[], size_t nValues)
{
    FmuInstance *m = (FmuInstance *)instance;
    size_t i;
    if (!fmu_allowed(m, "fmi3SetFloat64", MODE_INSTANTIATED | MODE_INIT))
        return fmi3Error;
    if (nValues != nvr)
        return fmu_error(m, "fmi3SetFloat64: nValues differs from the number of "
                            "value references (all variables are scalar)");
    if (nvr > 0 && (vr == NULL || values == NULL))
        return fmu_error(m, "fmi3SetFloat64: NULL argument");
    for (i = 0; i < nvr; i++) {
        fmi3ValueReference r = vr[i];
        if (r < VR_DER0 && !STATES_CALCULATED)
            m->d.s[r] = values[i];
        else if (r >= VR_PAR0 && r < VR_TIME)
            m->d.p[r - VR_PAR0] = values[i];
        else
            return fmu_error(m, "fmi3SetFloat64: the value reference is not a "
                                "parameter or a state with an exact start value");
    }
    return fmi3OK;
}

/* No variables of the other types: only empty requests succeed. */
#define FMU_NO_VARIABLES(fname, ctype)                                          \
    fmi3Status fname(fmi3Instance instance, const fmi3ValueReference vr[],     \
                     size_t nvr, ctype values[], size_t nValues)               \
    {                                                                          \
        FmuInstance *m = (FmuInstance *)instance;                              \
        (void)vr; (void)values;                                                \
        if (!fmu_allowed(m, #fname, MODE_ANY))                                 \
            return fmi3Error;                                                  \
        return nvr == 0 && nValues == 0                                        \
            ? fmi3OK : fmu_error(m, #fname ": the model has no such variables"); \
    }
FMU_NO_VARIABLES(fmi3GetFloat32, fmi3Float32)
FMU_NO_VARIABLES(fmi3GetInt8, fmi3Int8)
FMU_NO_VARIABLES(fmi3GetUInt8, fmi3UInt8)
FMU_NO_VARIABLES(fmi3GetInt16, fmi3Int16)
FMU_NO_VARIABLES(fmi3GetUInt16, fmi3UInt16)
FMU_NO_VARIABLES(fmi3GetInt32, fmi3Int32)
FMU_NO_VARIABLES(fmi3GetUInt32, fmi3UInt32)
FMU_NO_VARIABLES(fmi3GetInt64, fmi3Int64)
FMU_NO_VARIABLES(fmi3GetUInt64, fmi3UInt64)
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
FMU_NO_VARIABLES(fmi3SetUInt64, const fmi3UInt64)
FMU_NO_VARIABLES(fmi3SetBoolean, const fmi3Boolean)
FMU_NO_VARIABLES(fmi3SetString, const fmi3String)

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                         size_t valueSizes[], fmi3Binary values[], size_t nValues)
{
    FmuInstance *m = (FmuInstance *)instance;
    (void)vr; (void)valueSizes; (void)values;
    if (!fmu_allowed(m, "fmi3GetBinary", MODE_ANY))
        return fmi3Error;
    return nvr == 0 && nValues == 0
        ? fmi3OK : fmu_error(m, "fmi3GetBinary: the model has no such variables");
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                         const size_t valueSizes[], const fmi3Binary values[], size_t nValues)
{
    FmuInstance *m = (FmuInstance *)instance;
    (void)vr; (void)valueSizes; (void)values;
    if (!fmu_allowed(m, "fmi3SetBinary", MODE_ANY))
        return fmi3Error;
    return nvr == 0 && nValues == 0
        ? fmi3OK : fmu_error(m, "fmi3SetBinary: the model has no such variables");
}

/* ---------------------------------------------------------- not offered
 * (no clocks, no configuration mode, no per-element dependencies, no
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
FMU_NOT_OFFERED(fmi3EnterConfigurationMode, (fmi3Instance instance), (void)0)
FMU_NOT_OFFERED(fmi3ExitConfigurationMode, (fmi3Instance instance), (void)0)
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
    FmuInstance *m = (FmuInstance *)instance;
    if (!fmu_allowed(m, "fmi3GetFMUState", MODE_ANY))
        return fmi3Error;
    if (FMUState == NULL)
        return fmu_error(m, "fmi3GetFMUState: NULL argument");
    if (*FMUState == NULL) {
        *FMUState = calloc(1, sizeof(FmuData));
        if (*FMUState == NULL)
            return fmu_error(m, "fmi3GetFMUState: out of memory");
    }
    memcpy(*FMUState, &m->d, sizeof(FmuData));
    return fmi3OK;
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState)
{
    FmuInstance *m = (FmuInstance *)instance;
    if (!fmu_allowed(m, "fmi3SetFMUState", MODE_ANY))
        return fmi3Error;
    if (FMUState == NULL)
        return fmu_error(m, "fmi3SetFMUState: NULL state");
    memcpy(&m->d, FMUState, sizeof(FmuData));
    return fmi3OK;
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState)
{
    (void)instance;
    if (FMUState != NULL) {
        free(*FMUState);
        *FMUState = NULL;
    }
    return fmi3OK;
}

/* ---------------------------------------------------------- directional derivatives */
/* sensitivity = (d unknowns / d knowns) seed with unknowns derivatives,
 * states or computed outputs and knowns states (FMI 3.0.1 chapter 2, partial derivatives);
 * every variable is a scalar, so nSeed = nKnowns and nSensitivity = nUnknowns. */
fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance,
                                        const fmi3ValueReference unknowns[], size_t nUnknowns,
                                        const fmi3ValueReference knowns[], size_t nKnowns,
                                        const fmi3Float64 seed[], size_t nSeed,
                                        fmi3Float64 sensitivity[], size_t nSensitivity)
{
    FmuInstance *m = (FmuInstance *)instance;
#if PROVIDES_DIRECTIONAL_DERIVATIVE
    real J[N_STATES][N_STATES];
#if N_OUTPUTS
    real G[N_OUTPUTS][N_STATES];
#endif
    size_t i, j;
    if (!fmu_allowed(m, "fmi3GetDirectionalDerivative", MODE_AFTER_INSTANTIATED))
        return fmi3Error;
    if (nSeed != nKnowns || nSensitivity != nUnknowns)
        return fmu_error(m, "fmi3GetDirectionalDerivative: nSeed must equal nKnowns and "
                            "nSensitivity nUnknowns (all variables are scalar)");
    if ((nUnknowns > 0 && (unknowns == NULL || sensitivity == NULL))
        || (nKnowns > 0 && (knowns == NULL || seed == NULL)))
        return fmu_error(m, "fmi3GetDirectionalDerivative: NULL argument");
    for (j = 0; j < nKnowns; j++)
        if (knowns[j] >= VR_DER0)
            return fmu_error(m, "fmi3GetDirectionalDerivative: the knowns must be states");
    fmu_update_calculated(m);
    model_jacobian(m->d.time, m->d.s, m->d.p, J);
#if N_OUTPUTS
    model_output_jacobian(m->d.time, m->d.s, m->d.p, G);
#endif
    for (i = 0; i < nUnknowns; i++) {
        fmi3ValueReference u = unknowns[i];
        real sum = 0.0;
        if ((u >= VR_PAR0 && u < VR_OUT0) || u >= VR_END)
            return fmu_error(m, "fmi3GetDirectionalDerivative: the unknowns must be "
                                "derivatives, states or computed outputs");
        for (j = 0; j < nKnowns; j++) {
            fmi3ValueReference k = knowns[j];
#if N_OUTPUTS
            if (u >= VR_OUT0)
                sum += G[u - VR_OUT0][k] * seed[j];
            else
#endif
            if (u >= VR_DER0)
                sum += J[u - VR_DER0][k] * seed[j];
            else if (u == k)
                sum += seed[j];
        }
        sensitivity[i] = sum;
    }
    return fmi3OK;
#else
    (void)unknowns; (void)nUnknowns; (void)knowns; (void)nKnowns;
    (void)seed; (void)nSeed; (void)sensitivity; (void)nSensitivity;
    return fmu_error(m, "fmi3GetDirectionalDerivative: not provided "
                        "(providesDirectionalDerivatives=\"false\")");
#endif
}

/* ---------------------------------------------------------- model exchange */
/* No discrete-time variables: there is nothing to evaluate. */
fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance)
{
    FmuInstance *m = (FmuInstance *)instance;
    if (!fmu_allowed(m, "fmi3EvaluateDiscreteStates", MODE_EVENT | MODE_CONT))
        return fmi3Error;
    return fmi3OK;
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
    int changed;
    if (!fmu_allowed(m, "fmi3UpdateDiscreteStates", MODE_EVENT))
        return fmi3Error;
    if (discreteStatesNeedUpdate == NULL || terminateSimulation == NULL
        || nominalsOfContinuousStatesChanged == NULL
        || valuesOfContinuousStatesChanged == NULL || nextEventTimeDefined == NULL
        || nextEventTime == NULL)
        return fmu_error(m, "fmi3UpdateDiscreteStates: NULL argument");
    changed = model_event_update(m->d.time, m->d.s, m->d.p);
    if (changed)
        fmu_log(m, fmi3OK, "logEvents", "fmi3UpdateDiscreteStates: states reset");
    *discreteStatesNeedUpdate = false;
    *terminateSimulation = false;
    *nominalsOfContinuousStatesChanged = false;
    *valuesOfContinuousStatesChanged = changed ? true : false;
    *nextEventTimeDefined = false;
    *nextEventTime = 0.0;
    return fmi3OK;
}

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance)
{
    FmuInstance *m = (FmuInstance *)instance;
    if (!fmu_allowed(m, "fmi3EnterContinuousTimeMode", MODE_EVENT))
        return fmi3Error;
    m->d.mode = MODE_CONT;
    return fmi3OK;
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance,
                                       fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode,
                                       fmi3Boolean *terminateSimulation)
{
    FmuInstance *m = (FmuInstance *)instance;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!fmu_allowed(m, "fmi3CompletedIntegratorStep", MODE_CONT))
        return fmi3Error;
    if (enterEventMode == NULL || terminateSimulation == NULL)
        return fmu_error(m, "fmi3CompletedIntegratorStep: NULL argument");
    *enterEventMode = false;
    *terminateSimulation = false;
    return fmi3OK;
}

fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time)
{
    FmuInstance *m = (FmuInstance *)instance;
    if (!fmu_allowed(m, "fmi3SetTime", MODE_EVENT | MODE_CONT))
        return fmi3Error;
    m->d.time = time;
    return fmi3OK;
}

/* Allowed in Event Mode as well, as in fmu_common.h, so that an importer may
 * place the state at a located event before fmi3EnterEventMode. */
fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 x[], size_t nx)
{
    FmuInstance *m = (FmuInstance *)instance;
    if (!fmu_allowed(m, "fmi3SetContinuousStates", MODE_EVENT | MODE_CONT))
        return fmi3Error;
    if (nx != N_STATES || x == NULL)
        return fmu_error(m, "fmi3SetContinuousStates: wrong number of states");
    memcpy(m->d.s, x, sizeof(m->d.s));
    return fmi3OK;
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[],
                                             size_t nx)
{
    FmuInstance *m = (FmuInstance *)instance;
    if (!fmu_allowed(m, "fmi3GetContinuousStateDerivatives", MODE_AFTER_INSTANTIATED))
        return fmi3Error;
    if (nx != N_STATES || derivatives == NULL)
        return fmu_error(m, "fmi3GetContinuousStateDerivatives: wrong number of states");
    fmu_update_calculated(m);
    model_derivatives(m->d.time, m->d.s, m->d.p, derivatives);
    return fmi3OK;
}

fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[],
                                  size_t ni)
{
    FmuInstance *m = (FmuInstance *)instance;
    if (!fmu_allowed(m, "fmi3GetEventIndicators", MODE_AFTER_INSTANTIATED))
        return fmi3Error;
    if (ni != N_EVENT_INDICATORS || (ni > 0 && eventIndicators == NULL))
        return fmu_error(m, "fmi3GetEventIndicators: wrong number of event indicators");
    fmu_update_calculated(m);
    model_event_indicators(m->d.time, m->d.s, m->d.p, eventIndicators);
    return fmi3OK;
}

fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 x[], size_t nx)
{
    FmuInstance *m = (FmuInstance *)instance;
    if (!fmu_allowed(m, "fmi3GetContinuousStates", MODE_AFTER_INSTANTIATED))
        return fmi3Error;
    if (nx != N_STATES || x == NULL)
        return fmu_error(m, "fmi3GetContinuousStates: wrong number of states");
    fmu_update_calculated(m);
    memcpy(x, m->d.s, sizeof(m->d.s));
    return fmi3OK;
}

/* nominal = the native problem's atol_scale, 1.0 for every state */
fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[],
                                             size_t nx)
{
    FmuInstance *m = (FmuInstance *)instance;
    size_t i;
    if (!fmu_allowed(m, "fmi3GetNominalsOfContinuousStates", MODE_ANY))
        return fmi3Error;
    if (nx != N_STATES || nominals == NULL)
        return fmu_error(m, "fmi3GetNominalsOfContinuousStates: wrong number of states");
    for (i = 0; i < nx; i++)
        nominals[i] = 1.0;
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *nEventIndicators)
{
    FmuInstance *m = (FmuInstance *)instance;
    if (!fmu_allowed(m, "fmi3GetNumberOfEventIndicators", MODE_ANY))
        return fmi3Error;
    if (nEventIndicators == NULL)
        return fmu_error(m, "fmi3GetNumberOfEventIndicators: NULL argument");
    *nEventIndicators = N_EVENT_INDICATORS;
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *nContinuousStates)
{
    FmuInstance *m = (FmuInstance *)instance;
    if (!fmu_allowed(m, "fmi3GetNumberOfContinuousStates", MODE_ANY))
        return fmi3Error;
    if (nContinuousStates == NULL)
        return fmu_error(m, "fmi3GetNumberOfContinuousStates: NULL argument");
    *nContinuousStates = N_STATES;
    return fmi3OK;
}

#endif /* FMU_COMMON3_H */
