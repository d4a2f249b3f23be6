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
 *   MODEL_ARRAYS           optional, default 0; 1: a model with array
 *                          variables (FMI 3.0 only) whose sizes follow its
 *                          structural parameters; then N_STATES is the
 *                          largest number of states and the model gives its
 *                          own value references through model_variable()
 *                          and the current number of states through
 *                          model_n_states() (declared below)
 * and, after including it, START[N_STATES + N_PARAMS] (start values of the
 * states, then of the parameters) and the model hooks declared below.
 *
 * Variables are reached through their FmuVariable (fmu_variable()): a kind,
 * and where its elements lie in the instance's arrays. A scalar model's are
 * the fixed layout above; an array model's come from model_variable(), which
 * gives each variable its rows x cols elements in row-major order (FMI 3.0.1
 * chapter 2, "Serialization of Array Variables") at offset + i * stride + j.
 * Its structural parameters (kind VAR_STRUCT, FMI 3.0 causality
 * "structuralParameter", UInt64) are held in the parameter array and set in
 * Configuration Mode only (fmi3EnterConfigurationMode,
 * fmi3ExitConfigurationMode; FMI 3.0.1 chapter 2, "State Machine and
 * Semantics").
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
#ifndef MODEL_ARRAYS
#define MODEL_ARRAYS 0
#endif

/* A variable: its kind, and its elements (rows x cols, row-major) at
 * offset + i * stride + j of the array of its kind. */
enum { VAR_NONE, VAR_STATE, VAR_DER, VAR_PARAM, VAR_STRUCT, VAR_TIME, VAR_OUT };
typedef struct {
    int kind;
    size_t offset, rows, cols, stride;
} FmuVariable;

/* the position of element e (row-major) of v in the array of its kind */
static size_t fmu_element(const FmuVariable *v, size_t e)
{
    return v->offset + (e / v->cols) * v->stride + e % v->cols;
}

/* ---------------------------------------------------------- model hooks */
#if MODEL_ARRAYS
/* the variable of value reference vr with the structural parameters in p
 * (kind VAR_NONE: no such variable) */
static FmuVariable model_variable(FMU_VALUE_REFERENCE vr, const real *p);
/* the number of continuous states with the structural parameters in p */
static size_t model_n_states(const real *p);
#endif
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
    MODE_TERMINATED = 16, MODE_ERROR = 32, MODE_CONFIG = 64
};
#define MODE_ANY 127
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

#if MODEL_ARRAYS
#define fmu_variable(m, vr) model_variable((vr), (m)->d.p)
#define FMU_N_STATES(m) model_n_states((m)->d.p)
#else
/* a scalar model's variable: the fixed layout of value references above */
static FmuVariable fmu_scalar_variable(fmu_vr r)
{
    FmuVariable v = {VAR_NONE, 0, 1, 1, 1};
    if (r < VR_DER0) {
        v.kind = VAR_STATE; v.offset = r;
    } else if (r < VR_PAR0) {
        v.kind = VAR_DER; v.offset = r - VR_DER0;
    } else if (r < VR_TIME) {
        v.kind = VAR_PARAM; v.offset = r - VR_PAR0;
    } else if (r == VR_TIME) {
        v.kind = VAR_TIME;
    } else if (r < VR_END) {
        v.kind = VAR_OUT; v.offset = r - VR_OUT0;
    }
    return v;
}
#define fmu_variable(m, vr) fmu_scalar_variable(vr)
#define FMU_N_STATES(m) ((size_t)N_STATES)
#endif

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
#define NVALUES_DIFFER "nValues differs from the number of elements of the " \
                       "value references"

/* The Float64 (fmi2Real) variables vr, their elements in a row (FMI 2.0
 * passes nvalues = nvr: its variables are scalars). */
static fmu_status fmu_get_real(FmuInstance *m, const char *fname, const fmu_vr vr[],
                               size_t nvr, real values[], size_t nvalues)
{
    real dx[N_STATES];
    real out[N_OUTPUTS + 1];        /* + 1: no empty array when N_OUTPUTS = 0 */
    size_t i, e, k = 0;
    if (!fmu_allowed(m, fname, MODE_AFTER_INSTANTIATED))
        return FMU_ERROR;
    if (nvr > 0 && (vr == NULL || values == NULL))
        return fmu_errorf(m, fname, "NULL argument");
    fmu_update_calculated(m);
    model_derivatives(m->d.time, m->d.s, m->d.p, dx);
    model_outputs(m->d.time, m->d.s, m->d.p, out);
    for (i = 0; i < nvr; i++) {
        FmuVariable v = fmu_variable(m, vr[i]);
        const real *from;
        switch (v.kind) {
        case VAR_STATE: from = m->d.s; break;
        case VAR_DER: from = dx; break;
        case VAR_PARAM: from = m->d.p; break;
        case VAR_TIME: from = &m->d.time; break;
        case VAR_OUT: from = out; break;
        default: return fmu_errorf(m, fname, "unknown value reference");
        }
        if (v.rows * v.cols > nvalues - k)
            return fmu_errorf(m, fname, NVALUES_DIFFER);
        for (e = 0; e < v.rows * v.cols; e++)
            values[k++] = from[fmu_element(&v, e)];
    }
    return k == nvalues ? FMU_OK : fmu_errorf(m, fname, NVALUES_DIFFER);
}

static fmu_status fmu_set_real(FmuInstance *m, const char *fname, const fmu_vr vr[],
                               size_t nvr, const real values[], size_t nvalues)
{
    size_t i, e, k = 0;
    if (!fmu_allowed(m, fname, MODE_INSTANTIATED | MODE_INIT))
        return FMU_ERROR;
    if (nvr > 0 && (vr == NULL || values == NULL))
        return fmu_errorf(m, fname, "NULL argument");
    for (i = 0; i < nvr; i++) {
        FmuVariable v = fmu_variable(m, vr[i]);
        real *to;
        if (v.kind == VAR_STATE && !STATES_CALCULATED)
            to = m->d.s;
        else if (v.kind == VAR_PARAM)
            to = m->d.p;
        else
            return fmu_errorf(m, fname, "the value reference is not a parameter "
                                        "or a state with an exact start value");
        if (v.rows * v.cols > nvalues - k)
            return fmu_errorf(m, fname, NVALUES_DIFFER);
        for (e = 0; e < v.rows * v.cols; e++)
            to[fmu_element(&v, e)] = values[k++];
    }
    return k == nvalues ? FMU_OK : fmu_errorf(m, fname, NVALUES_DIFFER);
}

/* The structural parameters vr (scalars, integer valued): read in any mode,
 * set in Configuration Mode only, each to 1 .. STRUCTURAL_MAX (a model
 * without structural parameters has none: only empty requests succeed). */
#ifndef STRUCTURAL_MAX
#define STRUCTURAL_MAX 0
#endif
static fmu_status fmu_structural(FmuInstance *m, const char *fname, const fmu_vr vr[],
                                 size_t nvr, unsigned long long values[], size_t nvalues,
                                 int set)
{
    size_t i;
    if (!fmu_allowed(m, fname, set ? MODE_CONFIG : MODE_ANY))
        return FMU_ERROR;
    if (nvalues != nvr)
        return fmu_errorf(m, fname, NVALUES_DIFFER);
    if (nvr > 0 && (vr == NULL || values == NULL))
        return fmu_errorf(m, fname, "NULL argument");
    for (i = 0; i < nvr; i++) {
        FmuVariable v = fmu_variable(m, vr[i]);
        if (v.kind != VAR_STRUCT)
            return fmu_errorf(m, fname, "the value reference is not a structural "
                                        "parameter");
        if (!set)
            values[i] = (unsigned long long)m->d.p[v.offset];
        else if (values[i] < 1 || values[i] > STRUCTURAL_MAX)
            return fmu_errorf(m, fname, "a structural parameter is out of its range");
        else
            m->d.p[v.offset] = (real)values[i];
    }
    return FMU_OK;
}

/* Configuration Mode, for the structural parameters: entered from and left
 * to the instantiated state (refused by a model without them). */
static fmu_status fmu_configuration(FmuInstance *m, const char *fname, int enter)
{
    if (STRUCTURAL_MAX == 0)
        return fmu_errorf(m, fname, "the model has no structural parameters");
    return fmu_enter(m, fname, enter ? MODE_INSTANTIATED : MODE_CONFIG,
                     enter ? MODE_CONFIG : MODE_INSTANTIATED);
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
 * FMI 3.0.1 chapter 2, partial derivatives); seed and sensitivity hold an
 * entry per element of the knowns and of the unknowns (FMI 2.0 passes
 * n_seed = n_known and n_sens = n_unknown: its variables are scalars). */
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
    size_t i, j, a, b, row = 0, col, seeds = 0;
    if (!fmu_allowed(m, fname, MODE_AFTER_INSTANTIATED))
        return FMU_ERROR;
    if ((n_unknown > 0 && (unknowns == NULL || dv_unknown == NULL))
        || (n_known > 0 && (knowns == NULL || dv_known == NULL)))
        return fmu_errorf(m, fname, "NULL argument");
    for (j = 0; j < n_known; j++) {
        FmuVariable k = fmu_variable(m, knowns[j]);
        if (k.kind != VAR_STATE)
            return fmu_errorf(m, fname, "the knowns must be states");
        seeds += k.rows * k.cols;
    }
    if (seeds != n_seed)
        return fmu_errorf(m, fname, "nSeed differs from the number of elements of "
                                    "the knowns");
    fmu_update_calculated(m);
    model_jacobian(m->d.time, m->d.s, m->d.p, J);
#if N_OUTPUTS
    model_output_jacobian(m->d.time, m->d.s, m->d.p, G);
#endif
    for (i = 0; i < n_unknown; i++) {
        FmuVariable u = fmu_variable(m, unknowns[i]);
        if (u.kind != VAR_DER && u.kind != VAR_STATE && u.kind != VAR_OUT)
            return fmu_errorf(m, fname, "the unknowns must be derivatives, states "
                                        "or computed outputs");
        for (a = 0; a < u.rows * u.cols; a++, row++) {
            size_t ui = fmu_element(&u, a);
            real sum = 0.0;
            if (row >= n_sens)
                return fmu_errorf(m, fname, "nSensitivity differs from the number of "
                                            "elements of the unknowns");
            for (j = 0, col = 0; j < n_known; j++) {
                FmuVariable k = fmu_variable(m, knowns[j]);
                for (b = 0; b < k.rows * k.cols; b++, col++) {
                    size_t ki = fmu_element(&k, b);
#if N_OUTPUTS
                    if (u.kind == VAR_OUT)
                        sum += G[ui][ki] * dv_known[col];
                    else
#endif
                    if (u.kind == VAR_DER)
                        sum += J[ui][ki] * dv_known[col];
                    else if (ui == ki)
                        sum += dv_known[col];
                }
            }
            dv_unknown[row] = sum;
        }
    }
    return row == n_sens ? FMU_OK
        : fmu_errorf(m, fname, "nSensitivity differs from the number of elements of "
                               "the unknowns");
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
    if (nx != FMU_N_STATES(m) || x == NULL)
        return fmu_errorf(m, fname, "wrong number of states");
    memcpy(m->d.s, x, nx * sizeof(real));
    return FMU_OK;
}

static fmu_status fmu_get_derivatives(FmuInstance *m, const char *fname,
                                      real derivatives[], size_t nx)
{
    if (!fmu_allowed(m, fname, MODE_AFTER_INSTANTIATED))
        return FMU_ERROR;
    if (nx != FMU_N_STATES(m) || derivatives == NULL)
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
    if (nx != FMU_N_STATES(m) || x == NULL)
        return fmu_errorf(m, fname, "wrong number of states");
    fmu_update_calculated(m);
    memcpy(x, m->d.s, nx * sizeof(real));
    return FMU_OK;
}

/* nominal = the native problem's atol_scale, 1.0 for every state */
static fmu_status fmu_get_nominals(FmuInstance *m, const char *fname, real nominals[],
                                   size_t nx)
{
    size_t i;
    if (!fmu_allowed(m, fname, MODE_ANY))
        return FMU_ERROR;
    if (nx != FMU_N_STATES(m) || nominals == NULL)
        return fmu_errorf(m, fname, "wrong number of states");
    for (i = 0; i < nx; i++)
        nominals[i] = 1.0;
    return FMU_OK;
}

#endif /* FMU_CORE_H */
