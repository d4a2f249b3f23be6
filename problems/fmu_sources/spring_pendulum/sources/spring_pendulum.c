/*
 * spring_pendulum.c -- FMI 2.0 and 3.0 model exchange FMU of integrator-bench's
 * native problem `spring_pendulum` (problems/models/spring_pendulum.py): a unit
 * point mass on a spring of natural length 1 and stiffness k under unit
 * gravity (Lund FMNN05 Project 1; Hairer, Lubich, Wanner, Geometric
 * Numerical Integration, 2nd ed., sect. I.5):
 *
 *   x' = vx,  y' = vy,  vx' = -x lam,  vy' = -y lam - 1,
 *   lam = k (r - 1) / r,  r = |(x, y)|,   start (1, 1, 0, 0).
 *
 * The Jacobian is the native `jac`: d lam / d x_i = (k / r^3) x_i.
 *
 * One computed output, energy (value reference 10), the native problem's
 * invariant (`invariants`; HLW sect. I.5, conserved by the exact flow):
 *
 *   E = (vx^2 + vy^2) / 2 + y + k (r - 1)^2 / 2,
 *
 * with gradient dE/d(x, y, vx, vy) = (x lam, y lam + 1, vx, vy).
 */
#define N_STATES 4
#define N_PARAMS 1
#define N_OUTPUTS 1
#define N_EVENT_INDICATORS 0
#define STATES_CALCULATED 0
#define PROVIDES_DIRECTIONAL_DERIVATIVE 1

#include <math.h>
/* FMI_VERSION=3 (sources/buildDescription.xml of the FMI 3.0 FMU) selects
 * the FMI 3.0 function set; MODEL_GUID is the guid of modelDescription.xml,
 * resp. the instantiationToken of modelDescription3.xml. */
#if defined(FMI_VERSION) && FMI_VERSION == 3
#define MODEL_GUID "{5b0f3a52-6c1e-4d0b-9a43-2f7e8c1d0b01}"
#include "fmu_common3.h"
#else
#define MODEL_GUID "{5b0f3a52-6c1e-4d0b-9a43-2f7e8c1d0a01}"
#include "fmu_common.h"
#endif

enum { X, Y, VX, VY };      /* states */
enum { K };                 /* parameters */

static const real START[N_STATES + N_PARAMS] = {
    1.0, 1.0, 0.0, 0.0,     /* x, y, vx, vy */
    100.0                   /* k */
};

static void model_initial(real *s, const real *p) { (void)s; (void)p; }

static void model_derivatives(real t, const real *s, const real *p,
                              real *dx)
{
    real r = hypot(s[X], s[Y]);
    real lam = p[K] * (r - 1.0) / r;
    (void)t;
    dx[X] = s[VX];
    dx[Y] = s[VY];
    dx[VX] = -s[X] * lam;
    dx[VY] = -s[Y] * lam - 1.0;
}

static void model_jacobian(real t, const real *s, const real *p,
                           real J[N_STATES][N_STATES])
{
    real r = hypot(s[X], s[Y]);
    real lam = p[K] * (r - 1.0) / r;
    real c = p[K] / (r * r * r);
    (void)t;
    memset(J, 0, sizeof(real) * N_STATES * N_STATES);
    J[X][VX] = 1.0;
    J[Y][VY] = 1.0;
    J[VX][X] = -lam - c * s[X] * s[X];
    J[VX][Y] = -c * s[X] * s[Y];
    J[VY][X] = -c * s[X] * s[Y];
    J[VY][Y] = -lam - c * s[Y] * s[Y];
}

static void model_outputs(real t, const real *s, const real *p, real *out)
{
    real r = hypot(s[X], s[Y]);
    (void)t;
    out[0] = 0.5 * (s[VX] * s[VX] + s[VY] * s[VY]) + s[Y]
             + 0.5 * p[K] * (r - 1.0) * (r - 1.0);
}

static void model_output_jacobian(real t, const real *s, const real *p,
                                  real G[N_OUTPUTS][N_STATES])
{
    real r = hypot(s[X], s[Y]);
    real lam = p[K] * (r - 1.0) / r;
    (void)t;
    G[0][X] = s[X] * lam;
    G[0][Y] = s[Y] * lam + 1.0;
    G[0][VX] = s[VX];
    G[0][VY] = s[VY];
}
