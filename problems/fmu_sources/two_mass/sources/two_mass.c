/*
 * two_mass.c -- FMI 2.0 and 3.0 model exchange FMU of integrator-bench's native
 * problem `two_mass` (problems/models/two_mass.py): two unit masses in series,
 * ground -(k1, c1)- m1 -(k2, c2)- m2, forced by sin(t) on mass 1 (MSC.ADAMS
 * seminar, seeds 000 and 001):
 *
 *   x' = v,  v' = -K x - C v + (sin t, 0),
 *   K = [[k1 + k2, -k2], [-k2, k2]],  C = [[c1 + c2, -c2], [-c2, c2]],
 *   start x = (1, 1.01), v = (0, 0).
 *
 * The Jacobian is the native `jac`: [[0, I], [-K, -C]].
 */
#define N_STATES 4
#define N_PARAMS 4
#define N_EVENT_INDICATORS 0
#define STATES_CALCULATED 0
#define PROVIDES_DIRECTIONAL_DERIVATIVE 1

#include <math.h>
/* FMI_VERSION=3 (sources/buildDescription.xml of the FMI 3.0 FMU) selects
 * the FMI 3.0 function set; MODEL_GUID is the guid of modelDescription.xml,
 * resp. the instantiationToken of modelDescription3.xml. */
#if defined(FMI_VERSION) && FMI_VERSION == 3
#define MODEL_GUID "{5b0f3a52-6c1e-4d0b-9a43-2f7e8c1d0b02}"
#include "fmu_common3.h"
#else
#define MODEL_GUID "{5b0f3a52-6c1e-4d0b-9a43-2f7e8c1d0a02}"
#include "fmu_common.h"
#endif

enum { X1, X2, V1, V2 };    /* states */
enum { K1, C1, K2, C2 };    /* parameters */

static const real START[N_STATES + N_PARAMS] = {
    1.0, 1.01, 0.0, 0.0,    /* x1, x2, v1, v2 */
    10.0, 0.1, 1e4, 0.1     /* k1, c1, k2, c2 */
};

static void model_initial(real *s, const real *p) { (void)s; (void)p; }

static void model_jacobian(real t, const real *s, const real *p,
                           real J[N_STATES][N_STATES])
{
    (void)t; (void)s;
    memset(J, 0, sizeof(real) * N_STATES * N_STATES);
    J[X1][V1] = 1.0;
    J[X2][V2] = 1.0;
    J[V1][X1] = -(p[K1] + p[K2]);
    J[V1][X2] = p[K2];
    J[V2][X1] = p[K2];
    J[V2][X2] = -p[K2];
    J[V1][V1] = -(p[C1] + p[C2]);
    J[V1][V2] = p[C2];
    J[V2][V1] = p[C2];
    J[V2][V2] = -p[C2];
}

static void model_derivatives(real t, const real *s, const real *p,
                              real *dx)
{
    real J[N_STATES][N_STATES];
    int i, j;
    model_jacobian(t, s, p, J);
    for (i = 0; i < N_STATES; i++) {
        dx[i] = 0.0;
        for (j = 0; j < N_STATES; j++)
            dx[i] += J[i][j] * s[j];
    }
    dx[V1] += sin(t);
}

