/*
 * bouncing_ball.c -- FMI 2.0 and 3.0 model exchange FMU of integrator-bench's
 * native problem `bouncing_ball` (problems/models/bouncing_ball.py): a ball dropped
 * from rest at height h0 falls under gravity g,
 *
 *   y' = v,  v' = -g,   start (y, v) = (h0, 0)  (initial="calculated"),
 *
 * and at each impact on the floor y = 0 Newton's law v <- -e v applies
 * (Glocker, Set-Valued Force Laws, Springer 2001, sect. 7).
 *
 * One event indicator, z = y. fmi2NewDiscreteStates (FMI 3.0:
 * fmi3UpdateDiscreteStates) applies the impact law only to a falling ball on
 * the floor: v < 0 and y <= CONTACT_TOL h0. The
 * tolerance takes a crossing that an importer located a hair before y = 0
 * (its root finder stopped on the positive side, y ~ |v| dt = O(1e-13 h0));
 * a crossing located a hair after has y < 0 and needs none. The reset keeps
 * y, as the native reset does. A rising crossing (v >= 0, e.g. a ball reset
 * a hair below the floor climbing through y = 0) changes nothing. There are
 * no time events. No directional derivatives are provided.
 *
 * One computed output, energy (value reference 8), the mechanical energy per
 * unit mass E = v^2 / 2 + g y: constant in flight; at an impact (y = 0,
 * so E = v^2 / 2) the reset v <- -e v multiplies it by e^2.
 */
#define N_STATES 2
#define N_PARAMS 3
#define N_OUTPUTS 1
#define N_EVENT_INDICATORS 1
#define STATES_CALCULATED 1
#define PROVIDES_DIRECTIONAL_DERIVATIVE 0

/* FMI_VERSION=3 (sources/buildDescription.xml of the FMI 3.0 FMU) selects
 * the FMI 3.0 function set; MODEL_GUID is the guid of modelDescription.xml,
 * resp. the instantiationToken of modelDescription3.xml. */
#if defined(FMI_VERSION) && FMI_VERSION == 3
#define MODEL_GUID "{5b0f3a52-6c1e-4d0b-9a43-2f7e8c1d0b03}"
#include "fmu_common3.h"
#else
#define MODEL_GUID "{5b0f3a52-6c1e-4d0b-9a43-2f7e8c1d0a03}"
#include "fmu_common.h"
#endif

#define CONTACT_TOL 1e-10

enum { Y, V };              /* states */
enum { H0, G, E };          /* parameters */

static const real START[N_STATES + N_PARAMS] = {
    1.0, 0.0,               /* y, v: replaced by model_initial */
    1.0, 9.81, 0.8          /* h0, g, e */
};

static void model_initial(real *s, const real *p)
{
    s[Y] = p[H0];
    s[V] = 0.0;
}

static void model_derivatives(real t, const real *s, const real *p,
                              real *dx)
{
    (void)t;
    dx[Y] = s[V];
    dx[V] = -p[G];
}

static void model_event_indicators(real t, const real *s,
                                   const real *p, real *z)
{
    (void)t; (void)p;
    z[0] = s[Y];
}

static int model_event_update(real t, real *s, const real *p)
{
    (void)t;
    if (s[V] < 0.0 && s[Y] <= CONTACT_TOL * p[H0]) {
        s[V] = -p[E] * s[V];
        return 1;
    }
    return 0;
}

static void model_outputs(real t, const real *s, const real *p, real *out)
{
    (void)t;
    out[0] = 0.5 * s[V] * s[V] + p[G] * s[Y];
}
