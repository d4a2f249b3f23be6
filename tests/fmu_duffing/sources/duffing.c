/*
 * duffing.c -- a forced, damped Duffing oscillator as an FMI 2.0 model-exchange
 * FMU, a model that is not one of the project's problems (the tests of
 * `ibench advise` build it):
 *
 *   x' = v,  v' = -d v - a x - b x^3 + F cos(w t),  x(0) = 1, v(0) = 0.
 *
 * No directional derivatives: integrators difference the right-hand side.
 */
#define N_STATES 2
#define N_PARAMS 5
#define N_EVENT_INDICATORS 0
#define STATES_CALCULATED 0
#define PROVIDES_DIRECTIONAL_DERIVATIVE 0

#include <math.h>
#define MODEL_GUID "{0d7e2c61-3a4f-4b8e-9c15-7f2a1e6b4d31}"
#include "fmu_common.h"

enum { X, V };              /* states */
enum { D, A, B, F, W };     /* parameters */

static const real START[N_STATES + N_PARAMS] = {
    1.0, 0.0,                    /* x, v */
    0.2, 1.0, 0.5, 0.4, 1.2      /* d, a, b, F, w */
};

static void model_initial(real *s, const real *p) { (void)s; (void)p; }

static void model_derivatives(real t, const real *s, const real *p, real *dx)
{
    dx[X] = s[V];
    dx[V] = -p[D] * s[V] - p[A] * s[X] - p[B] * s[X] * s[X] * s[X] + p[F] * cos(p[W] * t);
}
