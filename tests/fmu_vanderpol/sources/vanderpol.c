/*
 * vanderpol.c -- the Van der Pol oscillator with its damping fixed in the code
 * (mu = 1) as an FMI 2.0 model-exchange FMU without parameters: its only
 * inputs are its states' start values (initial="exact"), so the robustness
 * check of `ibench advise` perturbs those (the tests build it):
 *
 *   x' = v,  v' = mu (1 - x^2) v - x,  x(0) = 2, v(0) = 0.
 *
 * No directional derivatives: integrators difference the right-hand side.
 */
#define N_STATES 2
#define N_PARAMS 0
#define N_EVENT_INDICATORS 0
#define STATES_CALCULATED 0
#define PROVIDES_DIRECTIONAL_DERIVATIVE 0

#define MODEL_GUID "{5b1e9a0c-7d42-4c6f-8e13-2a9f0d6c3b57}"
#include "fmu_common.h"

enum { X, V };              /* states */
#define MU 1.0

static const real START[N_STATES + N_PARAMS] = {
    2.0, 0.0                     /* x, v */
};

static void model_initial(real *s, const real *p) { (void)s; (void)p; }

static void model_derivatives(real t, const real *s, const real *p, real *dx)
{
    (void)t; (void)p;
    dx[X] = s[V];
    dx[V] = MU * (1.0 - s[X] * s[X]) * s[V] - s[X];
}
