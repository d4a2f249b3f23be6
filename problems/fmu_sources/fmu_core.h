/*
 * fmu_core.h -- the version-neutral core of the model-exchange function sets
 * fmu_common.h (FMI 2.0) and fmu_common3.h (FMI 3.0): value references, the
 * model hooks, the instance data and its mode bookkeeping, and one helper per
 * piece of logic the two standards share (instantiation, state machine,
 * variable access, FMU state, derivatives, event indicators, discrete
 * update, directional derivatives). Each version header includes this file
 * and keeps only its exported functions, as thin wrappers that adapt their
 * signatures to these helpers. Plain C99, the C standard library only.
 *
 * Sources: Modelica Association, "Functional Mock-up Interface for Model
 * Exchange and Co-Simulation", version 2.0.4 (2022), sect. 2.1 and 3.2;
 * "Functional Mock-up Interface Specification", version 3.0.1 (2023),
 * chapters 2 and 3. Both define the same status values (OK 0, Warning 1,
 * Error 3; FMI 2.0.4 sect. 2.1.3, FMI 3.0.1 sect. 2.2.3) and the same
 * model-exchange state machine for what these FMUs offer.
 *
 * Value references (the same in every model and both versions):
 *   0 .. N_STATES-1                        continuous states, in the native
 *                                          problem's `components` order
 *   N_STATES .. 2 N_STATES-1               their derivatives der(...)
 *   2 N_STATES .. 2 N_STATES+N_PARAMS-1    parameters (variability "fixed")
 *   VR_TIME = 2 N_STATES+N_PARAMS          the independent variable, time
 *   VR_OUT0 .. VR_OUT0+N_OUTPUTS-1         outputs computed from the states
 *     (VR_OUT0 = VR_TIME+1)                and parameters (causality "output",
 *                                          initial "calculated"), e.g. energy
 *
 * A model file defines, before including its version's header:
 *   MODEL_GUID             the guid of modelDescription.xml (FMI 2.0), resp.
 *                          the instantiationToken of modelDescription3.xml
 *   N_STATES, N_PARAMS, N_EVENT_INDICATORS
 *   N_OUTPUTS              optional, default 0: the number of computed
 *                          outputs (the states are outputs too, at their own
 *                          value references; these are the others)
 *   STATES_CALCULATED      1: the states have initial="calculated" and are
 *                          set by model_initial() from the parameters (they
 *                          cannot be set); 0: initial="exact", their start
 *                          values are START[0 .. N_STATES-1]
 *   PROVIDES_DIRECTIONAL_DERIVATIVE  1 or 0
 * and, after including it, START[N_STATES + N_PARAMS] (start values of the
 * states, then of the parameters) and the model hooks declared below.
 *
 * The version header defines, before including this file:
 *   FMU_VALUE_REFERENCE    its value-reference type
 *   FMU_LOGGER             its logger callback type
 *   FMU_DIRECTIONAL_FLAG   the model-description attribute that declares
 *                          directional derivatives (for the error message)
 * and, after it, fmu_emit(), which calls the logger with its signature.
 */
#ifndef FMU_CORE_H
#define FMU_CORE_H

#include <stdlib.h>
#include <string.h>
#include <stdio.h>

/* the model hooks' floating-point type (= fmi2Real = fmi3Float64) */
typedef double real;

/* the status values both standards share */
enum { FMU_OK = 0, FMU_WARNING = 1, FMU_ERROR = 3 };
typedef int fmu_status;

typedef FMU_VALUE_REFERENCE fmu_vr;

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

/* Everything fmi2GetFMUstate / fmi3GetFMUState copies. */
typedef struct {
    real time;
    real s[N_STATES];
    real p[N_PARAMS];
    int mode;
} FmuData;

typedef struct {
    FmuData d;
    char *name;
    FMU_LOGGER logger;
    void *env;              /* fmi2ComponentEnvironment, fmi3InstanceEnvironment */
    int logging_on;
} FmuInstance;

/* the version header's call of m->logger (m->logger != NULL) */
static void fmu_emit(FmuInstance *m, fmu_status status, const char *category,
                     const char *message);

static void fmu_log(FmuInstance *m, fmu_status status, const char *category,
                    const char *message)
{
    if (m->logger != NULL && (m->logging_on || status >= FMU_WARNING))
        fmu_emit(m, status, category, message);
}

/* Whether `fname` may be called in the current mode (an error log line
 * when not). */
static int fmu_allowed(FmuInstance *m, const char *fname, int modes)
{
    char msg[160];
    if (m == NULL)
        return 0;
    if (m->d.mode & modes)
        return 1;
    snprintf(msg, sizeof msg, "%s: not allowed in the current mode (%d)",
             fname, m->d.mode);
    fmu_log(m, FMU_ERROR, "logStatusError", msg);
    return 0;
}

static fmu_status fmu_error(FmuInstance *m, const char *message)
{
    if (m != NULL)
        fmu_log(m, FMU_ERROR, "logStatusError", message);
    return FMU_ERROR;
}

/* fmu_error with the message "<fname>: <what>" */
static fmu_status fmu_errorf(FmuInstance *m, const char *fname, const char *what)
{
    char msg[256];
    snprintf(msg, sizeof msg, "%s: %s", fname, what);
    return fmu_error(m, msg);
}

/* fmu_allowed, then whether the version's pointer arguments are all given
 * (args_ok; "<fname>: NULL argument" when not). */
static fmu_status fmu_check(FmuInstance *m, const char *fname, int modes, int args_ok)
{
    if (!fmu_allowed(m, fname, modes))
        return FMU_ERROR;
    return args_ok ? FMU_OK : fmu_errorf(m, fname, "NULL argument");
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

/* ---------------------------------------------------------- instance life */
/* A new instance at its start values (NULL when out of memory); the
 * version's wrapper has checked the name, type and GUID. */
static FmuInstance *fmu_new(const char *name, FMU_LOGGER logger, void *env,
                            int logging_on)
{
    FmuInstance *m = (FmuInstance *)calloc(1, sizeof(FmuInstance));
    if (m == NULL)
        return NULL;
    m->name = (char *)malloc(strlen(name) + 1);
    if (m->name == NULL) {
        free(m);
        return NULL;
    }
    strcpy(m->name, name);
    m->logger = logger;
    m->env = env;
    m->logging_on = logging_on;
    fmu_set_start(m);
    return m;
}

static void fmu_free(FmuInstance *m)
{
    if (m == NULL)
        return;
    free(m->name);
    free(m);
}

static fmu_status fmu_set_logging(FmuInstance *m, int logging_on)
{
    if (m == NULL)
        return FMU_ERROR;
    m->logging_on = logging_on;
    return FMU_OK;
}

/* A mode transition: allowed from `modes`, then `mode`. */
static fmu_status fmu_enter(FmuInstance *m, const char *fname, int modes, int mode)
{
    if (!fmu_allowed(m, fname, modes))
        return FMU_ERROR;
    m->d.mode = mode;
    return FMU_OK;
}

/* The time, allowed from `modes` (the start time before initialization,
 * MODE_INSTANTIATED; the current time in Event and Continuous-Time Mode). */
static fmu_status fmu_set_time(FmuInstance *m, const char *fname, int modes, real time)
{
    if (!fmu_allowed(m, fname, modes))
        return FMU_ERROR;
    m->d.time = time;
    return FMU_OK;
}

/* Model exchange leaves initialization in Event Mode. */
static fmu_status fmu_exit_init(FmuInstance *m, const char *fname)
{
    if (!fmu_allowed(m, fname, MODE_INIT))
        return FMU_ERROR;
    fmu_update_calculated(m);
    m->d.mode = MODE_EVENT;
    return FMU_OK;
}

static fmu_status fmu_reset(FmuInstance *m, const char *fname)
{
    if (!fmu_allowed(m, fname, MODE_ANY))
        return FMU_ERROR;
    fmu_set_start(m);
    return FMU_OK;
}

/* ---------------------------------------------------------- variable access */
#define NVALUES_DIFFER "nValues differs from the number of value references " \
                       "(all variables are scalar)"

/* All variables are scalar: nvalues must equal nvr (FMI 2.0 passes nvr). */
static fmu_status fmu_get_real(FmuInstance *m, const char *fname, const fmu_vr vr[],
                               size_t nvr, real values[], size_t nvalues)
{
    real dx[N_STATES];
    real out[N_OUTPUTS + 1];        /* + 1: no empty array when N_OUTPUTS = 0 */
    size_t i;
    if (!fmu_allowed(m, fname, MODE_AFTER_INSTANTIATED))
        return FMU_ERROR;
    if (nvalues != nvr)
        return fmu_errorf(m, fname, NVALUES_DIFFER);
    if (nvr > 0 && (vr == NULL || values == NULL))
        return fmu_errorf(m, fname, "NULL argument");
    fmu_update_calculated(m);
    model_derivatives(m->d.time, m->d.s, m->d.p, dx);
    model_outputs(m->d.time, m->d.s, m->d.p, out);
    for (i = 0; i < nvr; i++) {
        fmu_vr r = vr[i];
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
            return fmu_errorf(m, fname, "unknown value reference");
    }
    return FMU_OK;
}

static fmu_status fmu_set_real(FmuInstance *m, const char *fname, const fmu_vr vr[],
                               size_t nvr, const real values[], size_t nvalues)
{
    size_t i;
    if (!fmu_allowed(m, fname, MODE_INSTANTIATED | MODE_INIT))
        return FMU_ERROR;
    if (nvalues != nvr)
        return fmu_errorf(m, fname, NVALUES_DIFFER);
    if (nvr > 0 && (vr == NULL || values == NULL))
        return fmu_errorf(m, fname, "NULL argument");
    for (i = 0; i < nvr; i++) {
        fmu_vr r = vr[i];
        if (r < VR_DER0 && !STATES_CALCULATED)
            m->d.s[r] = values[i];
        else if (r >= VR_PAR0 && r < VR_TIME)
            m->d.p[r - VR_PAR0] = values[i];
        else
            return fmu_errorf(m, fname, "the value reference is not a parameter "
                                        "or a state with an exact start value");
    }
    return FMU_OK;
}

/* No variables of the other types: only empty requests succeed. */
static fmu_status fmu_no_variables(FmuInstance *m, const char *fname, size_t nvr,
                                   size_t nvalues)
{
    if (!fmu_allowed(m, fname, MODE_ANY))
        return FMU_ERROR;
    return nvr == 0 && nvalues == 0
        ? FMU_OK : fmu_errorf(m, fname, "the model has no such variables");
}

/* ---------------------------------------------------------- FMU state */
static fmu_status fmu_get_state(FmuInstance *m, const char *fname, void **state)
{
    if (!fmu_allowed(m, fname, MODE_ANY))
        return FMU_ERROR;
    if (state == NULL)
        return fmu_errorf(m, fname, "NULL argument");
    if (*state == NULL) {
        *state = calloc(1, sizeof(FmuData));
        if (*state == NULL)
            return fmu_errorf(m, fname, "out of memory");
    }
    memcpy(*state, &m->d, sizeof(FmuData));
    return FMU_OK;
}

static fmu_status fmu_set_state(FmuInstance *m, const char *fname, const void *state)
{
    if (!fmu_allowed(m, fname, MODE_ANY))
        return FMU_ERROR;
    if (state == NULL)
        return fmu_errorf(m, fname, "NULL state");
    memcpy(&m->d, state, sizeof(FmuData));
    return FMU_OK;
}

static fmu_status fmu_free_state(void **state)
{
    if (state != NULL) {
        free(*state);
        *state = NULL;
    }
    return FMU_OK;
}

/* ---------------------------------------------------------- directional derivatives */
/* dv_unknown = (d unknowns / d knowns) dv_known with unknowns derivatives,
 * states or computed outputs and knowns states (FMI 2.0.4 sect. 2.1.9,
 * FMI 3.0.1 chapter 2, partial derivatives); every variable is a scalar, so
 * n_seed = n_known and n_sens = n_unknown (FMI 2.0 passes those). */
static fmu_status fmu_directional_derivative(FmuInstance *m, const char *fname,
                                             const fmu_vr unknowns[], size_t n_unknown,
                                             const fmu_vr knowns[], size_t n_known,
                                             const real dv_known[], size_t n_seed,
                                             real dv_unknown[], size_t n_sens)
{
#if PROVIDES_DIRECTIONAL_DERIVATIVE
    real J[N_STATES][N_STATES];
#if N_OUTPUTS
    real G[N_OUTPUTS][N_STATES];
#endif
    size_t i, j;
    if (!fmu_allowed(m, fname, MODE_AFTER_INSTANTIATED))
        return FMU_ERROR;
    if (n_seed != n_known || n_sens != n_unknown)
        return fmu_errorf(m, fname, "nSeed must equal nKnowns and nSensitivity "
                                    "nUnknowns (all variables are scalar)");
    if ((n_unknown > 0 && (unknowns == NULL || dv_unknown == NULL))
        || (n_known > 0 && (knowns == NULL || dv_known == NULL)))
        return fmu_errorf(m, fname, "NULL argument");
    for (j = 0; j < n_known; j++)
        if (knowns[j] >= VR_DER0)
            return fmu_errorf(m, fname, "the knowns must be states");
    fmu_update_calculated(m);
    model_jacobian(m->d.time, m->d.s, m->d.p, J);
#if N_OUTPUTS
    model_output_jacobian(m->d.time, m->d.s, m->d.p, G);
#endif
    for (i = 0; i < n_unknown; i++) {
        fmu_vr u = unknowns[i];
        real sum = 0.0;
        if ((u >= VR_PAR0 && u < VR_OUT0) || u >= VR_END)
            return fmu_errorf(m, fname, "the unknowns must be derivatives, states "
                                        "or computed outputs");
        for (j = 0; j < n_known; j++) {
            fmu_vr k = knowns[j];
#if N_OUTPUTS
            if (u >= VR_OUT0)
                sum += G[u - VR_OUT0][k] * dv_known[j];
            else
#endif
            if (u >= VR_DER0)
                sum += J[u - VR_DER0][k] * dv_known[j];
            else if (u == k)
                sum += dv_known[j];
        }
        dv_unknown[i] = sum;
    }
    return FMU_OK;
#else
    (void)unknowns; (void)n_unknown; (void)knowns; (void)n_known;
    (void)dv_known; (void)n_seed; (void)dv_unknown; (void)n_sens;
    return fmu_errorf(m, fname, "not provided (" FMU_DIRECTIONAL_FLAG "=\"false\")");
#endif
}

/* ---------------------------------------------------------- model exchange */
/* The discrete update at an event (after the wrapper's fmu_check in Event
 * Mode); returns whether a state changed. */
static int fmu_event_update(FmuInstance *m, const char *fname)
{
    char msg[160];
    int changed = model_event_update(m->d.time, m->d.s, m->d.p);
    if (changed) {
        snprintf(msg, sizeof msg, "%s: states reset", fname);
        fmu_log(m, FMU_OK, "logEvents", msg);
    }
    return changed;
}

/* Allowed in Event Mode as well (more lenient than FMI 2.0.4 table 3.2.3),
 * so that an importer may place the state at a located event before it
 * enters Event Mode. */
static fmu_status fmu_set_states(FmuInstance *m, const char *fname, const real x[],
                                 size_t nx)
{
    if (!fmu_allowed(m, fname, MODE_EVENT | MODE_CONT))
        return FMU_ERROR;
    if (nx != N_STATES || x == NULL)
        return fmu_errorf(m, fname, "wrong number of states");
    memcpy(m->d.s, x, sizeof(m->d.s));
    return FMU_OK;
}

static fmu_status fmu_get_derivatives(FmuInstance *m, const char *fname,
                                      real derivatives[], size_t nx)
{
    if (!fmu_allowed(m, fname, MODE_AFTER_INSTANTIATED))
        return FMU_ERROR;
    if (nx != N_STATES || derivatives == NULL)
        return fmu_errorf(m, fname, "wrong number of states");
    fmu_update_calculated(m);
    model_derivatives(m->d.time, m->d.s, m->d.p, derivatives);
    return FMU_OK;
}

static fmu_status fmu_get_event_indicators(FmuInstance *m, const char *fname,
                                           real indicators[], size_t ni)
{
    if (!fmu_allowed(m, fname, MODE_AFTER_INSTANTIATED))
        return FMU_ERROR;
    if (ni != N_EVENT_INDICATORS || (ni > 0 && indicators == NULL))
        return fmu_errorf(m, fname, "wrong number of event indicators");
    fmu_update_calculated(m);
    model_event_indicators(m->d.time, m->d.s, m->d.p, indicators);
    return FMU_OK;
}

static fmu_status fmu_get_states(FmuInstance *m, const char *fname, real x[], size_t nx)
{
    if (!fmu_allowed(m, fname, MODE_AFTER_INSTANTIATED))
        return FMU_ERROR;
    if (nx != N_STATES || x == NULL)
        return fmu_errorf(m, fname, "wrong number of states");
    fmu_update_calculated(m);
    memcpy(x, m->d.s, sizeof(m->d.s));
    return FMU_OK;
}

/* nominal = the native problem's atol_scale, 1.0 for every state */
static fmu_status fmu_get_nominals(FmuInstance *m, const char *fname, real nominals[],
                                   size_t nx)
{
    size_t i;
    if (!fmu_allowed(m, fname, MODE_ANY))
        return FMU_ERROR;
    if (nx != N_STATES || nominals == NULL)
        return fmu_errorf(m, fname, "wrong number of states");
    for (i = 0; i < nx; i++)
        nominals[i] = 1.0;
    return FMU_OK;
}

#endif /* FMU_CORE_H */
