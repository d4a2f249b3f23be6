/*
 * state_space.c -- FMI 3.0 model-exchange FMU with array variables: the
 * linear time-invariant system
 *
 *   x' = A x + B u,   y = C x + D u,
 *
 * x the n states, u the m inputs (held constant: a parameter vector), y the
 * r outputs; A is n x n, B n x m, C r x n, D r x m. n, m and r are structural
 * parameters (FMI 3.0.1, causality "structuralParameter"): the Dimension
 * elements of modelDescription3.xml size every array by them, and they are
 * set in Configuration Mode (1 .. SS_MAX each). The Modelica Association's
 * Reference FMU "StateSpace" is the same equation; this one is written for
 * integrator-bench on its own function set (fmu_common3.h, fmu_core.h).
 *
 * Default: a mass-spring-damper (unit mass, stiffness 4, damping 0.4) pushed
 * by a unit force, x = (position, velocity), y = position:
 *   n = 2, m = 1, r = 1, A = [[0, 1], [-4, -0.4]], B = [[0], [1]],
 *   C = [[1, 0]], D = [[0]], u = (1), start x = (1, 0).
 * The elements of a larger size that the default does not give are 0.
 *
 * The Jacobian d x'/d x is A; d y/d x is C (directional derivatives).
 * Arrays are stored row-major at the largest size (stride SS_MAX); a
 * variable's elements are its leading block (model_variable()).
 */
#define SS_MAX 6
#define N_STATES SS_MAX
#define N_OUTPUTS SS_MAX
#define N_EVENT_INDICATORS 0
#define STATES_CALCULATED 0
#define PROVIDES_DIRECTIONAL_DERIVATIVE 1
#define MODEL_ARRAYS 1
#define STRUCTURAL_MAX SS_MAX

/* where the parameters lie in the parameter array: the structural
 * parameters m, n, r, then A, B, C, D (SS_MAX x SS_MAX each) and u */
enum {
    P_M = 0, P_N = 1, P_R = 2,
    P_A = 3,
    P_B = P_A + SS_MAX * SS_MAX,
    P_C = P_B + SS_MAX * SS_MAX,
    P_D = P_C + SS_MAX * SS_MAX,
    P_U = P_D + SS_MAX * SS_MAX,
    P_END = P_U + SS_MAX
};
#define N_PARAMS P_END

#define MODEL_GUID "{8d2c61f4-3b7a-4e19-a5c0-6f1e2d9b7a31}"
#include "fmu_common3.h"

/* value references of modelDescription3.xml */
enum { VR_SS_TIME, VR_M, VR_N, VR_R, VR_A, VR_B, VR_C, VR_D, VR_U, VR_X, VR_DER_X, VR_Y };

#define SS_AT(offset, i, j) (N_STATES + (offset) + (i) * SS_MAX + (j))
static const real START[N_STATES + N_PARAMS] = {
    [0] = 1.0,                                  /* x = (1, 0) */
    [N_STATES + P_M] = 1, [N_STATES + P_N] = 2, [N_STATES + P_R] = 1,
    [SS_AT(P_A, 0, 1)] = 1.0, [SS_AT(P_A, 1, 0)] = -4.0, [SS_AT(P_A, 1, 1)] = -0.4,
    [SS_AT(P_B, 1, 0)] = 1.0,
    [SS_AT(P_C, 0, 0)] = 1.0,
    [N_STATES + P_U] = 1.0
};

#define SS_M(p) ((size_t)(p)[P_M])
#define SS_N(p) ((size_t)(p)[P_N])
#define SS_R(p) ((size_t)(p)[P_R])

/* a rows x cols block at offset of an array of row stride `stride` */
static FmuVariable ss_block(int kind, size_t offset, size_t rows, size_t cols,
                            size_t stride)
{
    FmuVariable v;
    v.kind = kind; v.offset = offset; v.rows = rows; v.cols = cols; v.stride = stride;
    return v;
}

static FmuVariable model_variable(fmi3ValueReference vr, const real *p)
{
    size_t m = SS_M(p), n = SS_N(p), r = SS_R(p);
    switch (vr) {
    case VR_SS_TIME: return ss_block(VAR_TIME, 0, 1, 1, 1);
    case VR_M: return ss_block(VAR_STRUCT, P_M, 1, 1, 1);
    case VR_N: return ss_block(VAR_STRUCT, P_N, 1, 1, 1);
    case VR_R: return ss_block(VAR_STRUCT, P_R, 1, 1, 1);
    case VR_A: return ss_block(VAR_PARAM, P_A, n, n, SS_MAX);
    case VR_B: return ss_block(VAR_PARAM, P_B, n, m, SS_MAX);
    case VR_C: return ss_block(VAR_PARAM, P_C, r, n, SS_MAX);
    case VR_D: return ss_block(VAR_PARAM, P_D, r, m, SS_MAX);
    case VR_U: return ss_block(VAR_PARAM, P_U, 1, m, SS_MAX);
    case VR_X: return ss_block(VAR_STATE, 0, 1, n, SS_MAX);
    case VR_DER_X: return ss_block(VAR_DER, 0, 1, n, SS_MAX);
    case VR_Y: return ss_block(VAR_OUT, 0, 1, r, SS_MAX);
    default: return ss_block(VAR_NONE, 0, 1, 1, 1);
    }
}

static size_t model_n_states(const real *p) { return SS_N(p); }

static void model_initial(real *s, const real *p) { (void)s; (void)p; }

#define SS_P(p, offset, i, j) ((p)[(offset) + (i) * SS_MAX + (j)])

/* out = P x + Q u over `rows` rows, P (rows x n) and Q (rows x m) the
 * parameter matrices at offsets p_x and p_u */
static void ss_affine(const real *p, size_t p_x, size_t p_u, size_t rows,
                      const real *x, real *out)
{
    size_t i, j, m = SS_M(p), n = SS_N(p);
    for (i = 0; i < rows; i++) {
        out[i] = 0.0;
        for (j = 0; j < n; j++)
            out[i] += SS_P(p, p_x, i, j) * x[j];
        for (j = 0; j < m; j++)
            out[i] += SS_P(p, p_u, i, j) * p[P_U + j];
    }
}

/* M = the parameter matrix at offset (every element of the largest size) */
static void ss_matrix(const real *p, size_t offset, real M[SS_MAX][SS_MAX])
{
    size_t i, j;
    for (i = 0; i < SS_MAX; i++)
        for (j = 0; j < SS_MAX; j++)
            M[i][j] = SS_P(p, offset, i, j);
}

/* x' = A x + B u */
static void model_derivatives(real t, const real *s, const real *p, real *dx)
{
    (void)t;
    ss_affine(p, P_A, P_B, SS_N(p), s, dx);
}

/* d x' / d x = A */
static void model_jacobian(real t, const real *s, const real *p,
                           real J[N_STATES][N_STATES])
{
    (void)t; (void)s;
    ss_matrix(p, P_A, J);
}

/* y = C x + D u */
static void model_outputs(real t, const real *s, const real *p, real *out)
{
    (void)t;
    ss_affine(p, P_C, P_D, SS_R(p), s, out);
}

/* d y / d x = C */
static void model_output_jacobian(real t, const real *s, const real *p,
                                  real G[N_OUTPUTS][N_STATES])
{
    (void)t; (void)s;
    ss_matrix(p, P_C, G);
}
