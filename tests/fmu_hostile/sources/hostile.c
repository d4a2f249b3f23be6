/*
 * hostile.c -- exponential decay x' = -k x, x(0) = 1, k = 1, as an FMI 2.0
 * model-exchange FMU whose variable names (modelDescription.xml) are path
 * traversals: the tests check that opening it writes nothing outside the
 * data directory.
 */
#define N_STATES 1
#define N_PARAMS 1
#define N_EVENT_INDICATORS 0
#define STATES_CALCULATED 0
#define PROVIDES_DIRECTIONAL_DERIVATIVE 0

#define MODEL_GUID "{9d3c2b1a-4e5f-4a6b-8c7d-0e1f2a3b4c5d}"
#include "fmu_common.h"

static const real START[N_STATES + N_PARAMS] = {
    1.0,                         /* x */
    1.0                          /* k */
};

static void model_initial(real *s, const real *p) { (void)s; (void)p; }

static void model_derivatives(real t, const real *s, const real *p, real *dx)
{
    (void)t;
    dx[0] = -p[0] * s[0];
}
