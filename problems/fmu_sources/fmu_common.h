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
 * Value references (the same in every model):
 *   0 .. N_STATES-1                        continuous states, in the native
 *                                          problem's `components` order
 *   N_STATES .. 2 N_STATES-1               their derivatives der(...)
 *   2 N_STATES .. 2 N_STATES+N_PARAMS-1    parameters (variability "fixed")
 *   VR_TIME = 2 N_STATES+N_PARAMS          the independent variable, time
 *   VR_OUT0 .. VR_OUT0+N_OUTPUTS-1         outputs computed from the states
 *     (VR_OUT0 = VR_TIME+1)                and parameters (causality "output",
 *                                          initial "calculated"), e.g. energy
 *
 * A model file defines, before including this header:
 *   MODEL_GUID             the guid of its modelDescription.xml
 *   N_STATES, N_PARAMS, N_EVENT_INDICATORS
 *   N_OUTPUTS              optional, default 0: the number of computed
 *                          outputs (the states are outputs too, at their own
 *                          value references; these are the others)
 *   STATES_CALCULATED      1: the states have initial="calculated" and are
 *                          set by model_initial() from the parameters (they
 *                          cannot be set with fmi2SetReal); 0: initial="exact",
 *                          their start values are START[0 .. N_STATES-1]
 *   PROVIDES_DIRECTIONAL_DERIVATIVE  1 or 0
 * and, after including it, START[N_STATES + N_PARAMS] (start values of the
 * states, then of the parameters) and the model hooks declared below, in the
 * neutral type `real` (= fmi2Real = double) with plain int flags, so that the
 * same model file also builds with fmu_common3.h, the FMI 3.0 function set
 * (selected by the preprocessor definition FMI_VERSION=3).
 */
#ifndef FMU_COMMON_H
#define FMU_COMMON_H

#include <stdlib.h>
#include <string.h>
#include <stdio.h>
#include "fmi2Functions.h"

/* the model hooks' floating-point type (fmu_common3.h: fmi3Float64) */
typedef fmi2Real real;

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
static void model_derivatives(real t, const real *s, const real *p,
                              real *dx);
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
static void model_event_indicators(real t, const real *s,
                                   const real *p, real *z);
/* the discrete update at an event; returns whether a state changed */
static int model_event_update(real t, real *s, const real *p);
#else
/* a model without events: no indicators, and an event changes nothing */
static void model_event_indicators(real t, const real *s,
                                   const real *p, real *z)
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

/* Everything fmi2GetFMUstate copies. */
typedef struct {
    fmi2Real time;
    fmi2Real s[N_STATES];
    fmi2Real p[N_PARAMS];
    int mode;
} FmuData;

typedef struct {
    FmuData d;
    char *name;
    fmi2CallbackLogger logger;
    fmi2ComponentEnvironment env;
    fmi2Boolean logging_on;
} FmuInstance;

static void fmu_log(FmuInstance *m, fmi2Status status, const char *category,
                    const char *message)
{
    if (m->logger != NULL && (m->logging_on || status >= fmi2Warning))
        m->logger(m->env, m->name, status, category, "%s", message);
}

/* Whether `fname` may be called in the current mode (fmi2Error and a log
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
    fmu_log(m, fmi2Error, "logStatusError", msg);
    return 0;
}

static fmi2Status fmu_error(FmuInstance *m, const char *message)
{
    fmu_log(m, fmi2Error, "logStatusError", message);
    return fmi2Error;
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
const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn,
                               size_t nCategories, const fmi2String categories[])
{
    FmuInstance *m = (FmuInstance *)c;
    (void)nCategories; (void)categories;
    if (m == NULL)
        return fmi2Error;
    m->logging_on = loggingOn;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType,
                              fmi2String fmuGUID, fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn)
{
    FmuInstance *m;
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
    m = (FmuInstance *)calloc(1, sizeof(FmuInstance));
    if (m == NULL)
        return NULL;
    m->name = (char *)malloc(strlen(instanceName) + 1);
    if (m->name == NULL) {
        free(m);
        return NULL;
    }
    strcpy(m->name, instanceName);
    if (functions != NULL) {
        m->logger = functions->logger;
        m->env = functions->componentEnvironment;
    }
    m->logging_on = loggingOn;
    fmu_set_start(m);
    return m;
}

void fmi2FreeInstance(fmi2Component c)
{
    FmuInstance *m = (FmuInstance *)c;
    if (m == NULL)
        return;
    free(m->name);
    free(m);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined,
                               fmi2Real tolerance, fmi2Real startTime,
                               fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    FmuInstance *m = (FmuInstance *)c;
    (void)toleranceDefined; (void)tolerance; (void)stopTimeDefined; (void)stopTime;
    if (!fmu_allowed(m, "fmi2SetupExperiment", MODE_INSTANTIATED))
        return fmi2Error;
    m->d.time = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c)
{
    FmuInstance *m = (FmuInstance *)c;
    if (!fmu_allowed(m, "fmi2EnterInitializationMode", MODE_INSTANTIATED))
        return fmi2Error;
    m->d.mode = MODE_INIT;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c)
{
    FmuInstance *m = (FmuInstance *)c;
    if (!fmu_allowed(m, "fmi2ExitInitializationMode", MODE_INIT))
        return fmi2Error;
    fmu_update_calculated(m);
    m->d.mode = MODE_EVENT;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c)
{
    FmuInstance *m = (FmuInstance *)c;
    if (!fmu_allowed(m, "fmi2Terminate", MODE_EVENT | MODE_CONT))
        return fmi2Error;
    m->d.mode = MODE_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c)
{
    FmuInstance *m = (FmuInstance *)c;
    if (!fmu_allowed(m, "fmi2Reset", MODE_ANY))
        return fmi2Error;
    fmu_set_start(m);
    return fmi2OK;
}

/* ---------------------------------------------------------- variable access */
fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       fmi2Real value[])
{
    FmuInstance *m = (FmuInstance *)c;
    fmi2Real dx[N_STATES];
    fmi2Real out[N_OUTPUTS + 1];    /* + 1: no empty array when N_OUTPUTS = 0 */
    size_t i;
    if (!fmu_allowed(m, "fmi2GetReal", MODE_AFTER_INSTANTIATED))
        return fmi2Error;
    if (nvr > 0 && (vr == NULL || value == NULL))
        return fmu_error(m, "fmi2GetReal: NULL argument");
    fmu_update_calculated(m);
    model_derivatives(m->d.time, m->d.s, m->d.p, dx);
    model_outputs(m->d.time, m->d.s, m->d.p, out);
    for (i = 0; i < nvr; i++) {
        fmi2ValueReference r = vr[i];
        if (r < VR_DER0)
            value[i] = m->d.s[r];
        else if (r < VR_PAR0)
            value[i] = dx[r - VR_DER0];
        else if (r < VR_TIME)
            value[i] = m->d.p[r - VR_PAR0];
        else if (r == VR_TIME)
            value[i] = m->d.time;
        else if (r < VR_END)
            value[i] = out[r - VR_OUT0];
        else
            return fmu_error(m, "fmi2GetReal: unknown value reference");
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[])
{
    FmuInstance *m = (FmuInstance *)c;
    size_t i;
    if (!fmu_allowed(m, "fmi2SetReal", MODE_INSTANTIATED | MODE_INIT))
        return fmi2Error;
    if (nvr > 0 && (vr == NULL || value == NULL))
        return fmu_error(m, "fmi2SetReal: NULL argument");
    for (i = 0; i < nvr; i++) {
        fmi2ValueReference r = vr[i];
        if (r < VR_DER0 && !STATES_CALCULATED)
            m->d.s[r] = value[i];
        else if (r >= VR_PAR0 && r < VR_TIME)
            m->d.p[r - VR_PAR0] = value[i];
        else
            return fmu_error(m, "fmi2SetReal: the value reference is not a "
                                "parameter or a state with an exact start value");
    }
    return fmi2OK;
}

/* No Integer, Boolean or String variables: only empty requests succeed. */
#define FMU_NO_VARIABLES(fname, ctype)                                          \
    fmi2Status fname(fmi2Component c, const fmi2ValueReference vr[],           \
                     size_t nvr, ctype value[])                                \
    {                                                                          \
        FmuInstance *m = (FmuInstance *)c;                                     \
        (void)vr; (void)value;                                                 \
        if (!fmu_allowed(m, #fname, MODE_ANY))                                 \
            return fmi2Error;                                                  \
        return nvr == 0 ? fmi2OK                                               \
                        : fmu_error(m, #fname ": the model has no such variables"); \
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
    FmuInstance *m = (FmuInstance *)c;
    if (!fmu_allowed(m, "fmi2GetFMUstate", MODE_ANY))
        return fmi2Error;
    if (FMUstate == NULL)
        return fmu_error(m, "fmi2GetFMUstate: NULL argument");
    if (*FMUstate == NULL) {
        *FMUstate = calloc(1, sizeof(FmuData));
        if (*FMUstate == NULL)
            return fmu_error(m, "fmi2GetFMUstate: out of memory");
    }
    memcpy(*FMUstate, &m->d, sizeof(FmuData));
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate)
{
    FmuInstance *m = (FmuInstance *)c;
    if (!fmu_allowed(m, "fmi2SetFMUstate", MODE_ANY))
        return fmi2Error;
    if (FMUstate == NULL)
        return fmu_error(m, "fmi2SetFMUstate: NULL state");
    memcpy(&m->d, FMUstate, sizeof(FmuData));
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate)
{
    (void)c;
    if (FMUstate != NULL) {
        free(*FMUstate);
        *FMUstate = NULL;
    }
    return fmi2OK;
}

/* canSerializeFMUstate="false" */
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate,
                                      size_t *size)
{
    (void)FMUstate; (void)size;
    return fmu_error((FmuInstance *)c, "fmi2SerializedFMUstateSize: not supported");
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate,
                                 fmi2Byte serializedState[], size_t size)
{
    (void)FMUstate; (void)serializedState; (void)size;
    return fmu_error((FmuInstance *)c, "fmi2SerializeFMUstate: not supported");
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[],
                                   size_t size, fmi2FMUstate *FMUstate)
{
    (void)serializedState; (void)size; (void)FMUstate;
    return fmu_error((FmuInstance *)c, "fmi2DeSerializeFMUstate: not supported");
}

/* ---------------------------------------------------------- directional derivatives */
/* dvUnknown = (d unknowns / d knowns) dvKnown with unknowns derivatives,
 * states or computed outputs and knowns states (FMI 2.0.4 sect. 2.1.9). */
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c,
                                        const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[])
{
    FmuInstance *m = (FmuInstance *)c;
#if PROVIDES_DIRECTIONAL_DERIVATIVE
    fmi2Real J[N_STATES][N_STATES];
#if N_OUTPUTS
    fmi2Real G[N_OUTPUTS][N_STATES];
#endif
    size_t i, j;
    if (!fmu_allowed(m, "fmi2GetDirectionalDerivative", MODE_AFTER_INSTANTIATED))
        return fmi2Error;
    if ((nUnknown > 0 && (vUnknown_ref == NULL || dvUnknown == NULL))
        || (nKnown > 0 && (vKnown_ref == NULL || dvKnown == NULL)))
        return fmu_error(m, "fmi2GetDirectionalDerivative: NULL argument");
    for (j = 0; j < nKnown; j++)
        if (vKnown_ref[j] >= VR_DER0)
            return fmu_error(m, "fmi2GetDirectionalDerivative: the knowns must be states");
    fmu_update_calculated(m);
    model_jacobian(m->d.time, m->d.s, m->d.p, J);
#if N_OUTPUTS
    model_output_jacobian(m->d.time, m->d.s, m->d.p, G);
#endif
    for (i = 0; i < nUnknown; i++) {
        fmi2ValueReference u = vUnknown_ref[i];
        fmi2Real sum = 0.0;
        if ((u >= VR_PAR0 && u < VR_OUT0) || u >= VR_END)
            return fmu_error(m, "fmi2GetDirectionalDerivative: the unknowns must be "
                                "derivatives, states or computed outputs");
        for (j = 0; j < nKnown; j++) {
            fmi2ValueReference k = vKnown_ref[j];
#if N_OUTPUTS
            if (u >= VR_OUT0)
                sum += G[u - VR_OUT0][k] * dvKnown[j];
            else
#endif
            if (u >= VR_DER0)
                sum += J[u - VR_DER0][k] * dvKnown[j];
            else if (u == k)
                sum += dvKnown[j];
        }
        dvUnknown[i] = sum;
    }
    return fmi2OK;
#else
    (void)vUnknown_ref; (void)nUnknown; (void)vKnown_ref; (void)nKnown;
    (void)dvKnown; (void)dvUnknown;
    return fmu_error(m, "fmi2GetDirectionalDerivative: not provided "
                        "(providesDirectionalDerivative=\"false\")");
#endif
}

/* ---------------------------------------------------------- co-simulation
 * (not offered: the modelDescription has no CoSimulation element) */

/* ---------------------------------------------------------- model exchange */
fmi2Status fmi2EnterEventMode(fmi2Component c)
{
    FmuInstance *m = (FmuInstance *)c;
    if (!fmu_allowed(m, "fmi2EnterEventMode", MODE_EVENT | MODE_CONT))
        return fmi2Error;
    m->d.mode = MODE_EVENT;
    return fmi2OK;
}

fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *info)
{
    FmuInstance *m = (FmuInstance *)c;
    fmi2Boolean changed;
    if (!fmu_allowed(m, "fmi2NewDiscreteStates", MODE_EVENT))
        return fmi2Error;
    if (info == NULL)
        return fmu_error(m, "fmi2NewDiscreteStates: NULL argument");
    changed = model_event_update(m->d.time, m->d.s, m->d.p);
    if (changed)
        fmu_log(m, fmi2OK, "logEvents", "fmi2NewDiscreteStates: states reset");
    info->newDiscreteStatesNeeded = fmi2False;
    info->terminateSimulation = fmi2False;
    info->nominalsOfContinuousStatesChanged = fmi2False;
    info->valuesOfContinuousStatesChanged = changed;
    info->nextEventTimeDefined = fmi2False;
    info->nextEventTime = 0.0;
    return fmi2OK;
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c)
{
    FmuInstance *m = (FmuInstance *)c;
    if (!fmu_allowed(m, "fmi2EnterContinuousTimeMode", MODE_EVENT))
        return fmi2Error;
    m->d.mode = MODE_CONT;
    return fmi2OK;
}

fmi2Status fmi2CompletedIntegratorStep(fmi2Component c,
                                       fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi2Boolean *enterEventMode,
                                       fmi2Boolean *terminateSimulation)
{
    FmuInstance *m = (FmuInstance *)c;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!fmu_allowed(m, "fmi2CompletedIntegratorStep", MODE_CONT))
        return fmi2Error;
    if (enterEventMode == NULL || terminateSimulation == NULL)
        return fmu_error(m, "fmi2CompletedIntegratorStep: NULL argument");
    *enterEventMode = fmi2False;
    *terminateSimulation = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2SetTime(fmi2Component c, fmi2Real time)
{
    FmuInstance *m = (FmuInstance *)c;
    if (!fmu_allowed(m, "fmi2SetTime", MODE_EVENT | MODE_CONT))
        return fmi2Error;
    m->d.time = time;
    return fmi2OK;
}

/* Allowed in Event Mode as well (more lenient than FMI 2.0.4 table 3.2.3),
 * so that an importer may place the state at a located event before
 * fmi2EnterEventMode. */
fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx)
{
    FmuInstance *m = (FmuInstance *)c;
    if (!fmu_allowed(m, "fmi2SetContinuousStates", MODE_EVENT | MODE_CONT))
        return fmi2Error;
    if (nx != N_STATES || x == NULL)
        return fmu_error(m, "fmi2SetContinuousStates: wrong number of states");
    memcpy(m->d.s, x, sizeof(m->d.s));
    return fmi2OK;
}

fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real derivatives[], size_t nx)
{
    FmuInstance *m = (FmuInstance *)c;
    if (!fmu_allowed(m, "fmi2GetDerivatives", MODE_AFTER_INSTANTIATED))
        return fmi2Error;
    if (nx != N_STATES || derivatives == NULL)
        return fmu_error(m, "fmi2GetDerivatives: wrong number of states");
    fmu_update_calculated(m);
    model_derivatives(m->d.time, m->d.s, m->d.p, derivatives);
    return fmi2OK;
}

fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real eventIndicators[], size_t ni)
{
    FmuInstance *m = (FmuInstance *)c;
    if (!fmu_allowed(m, "fmi2GetEventIndicators", MODE_AFTER_INSTANTIATED))
        return fmi2Error;
    if (ni != N_EVENT_INDICATORS || (ni > 0 && eventIndicators == NULL))
        return fmu_error(m, "fmi2GetEventIndicators: wrong number of event indicators");
    fmu_update_calculated(m);
    model_event_indicators(m->d.time, m->d.s, m->d.p, eventIndicators);
    return fmi2OK;
}

fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx)
{
    FmuInstance *m = (FmuInstance *)c;
    if (!fmu_allowed(m, "fmi2GetContinuousStates", MODE_AFTER_INSTANTIATED))
        return fmi2Error;
    if (nx != N_STATES || x == NULL)
        return fmu_error(m, "fmi2GetContinuousStates: wrong number of states");
    fmu_update_calculated(m);
    memcpy(x, m->d.s, sizeof(m->d.s));
    return fmi2OK;
}

/* nominal = the native problem's atol_scale, 1.0 for every state */
fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x_nominal[],
                                             size_t nx)
{
    FmuInstance *m = (FmuInstance *)c;
    size_t i;
    if (!fmu_allowed(m, "fmi2GetNominalsOfContinuousStates", MODE_ANY))
        return fmi2Error;
    if (nx != N_STATES || x_nominal == NULL)
        return fmu_error(m, "fmi2GetNominalsOfContinuousStates: wrong number of states");
    for (i = 0; i < nx; i++)
        x_nominal[i] = 1.0;
    return fmi2OK;
}

#endif /* FMU_COMMON_H */
