/*
 * chatty.c -- exponential decay x' = -k x, x(0) = 1, k = 1, as a model-exchange
 * FMU (FMI 2.0, or FMI 3.0 with FMI_VERSION=3) that talks: at the start time
 * each right-hand side call logs a warning through the importer's logger
 * callback and prints a line to the C library's standard output. The tests
 * check that neither reaches a command's data on standard output (--json).
 */
#define N_STATES 1
#define N_PARAMS 1
#define N_EVENT_INDICATORS 0
#define STATES_CALCULATED 0
#define PROVIDES_DIRECTIONAL_DERIVATIVE 0

#define MODEL_GUID "{3e1c6a0b-7d2f-4c85-9b1e-5a4d3c2b1f08}"
#if defined(FMI_VERSION) && FMI_VERSION == 3
#include "fmu_common3.h"
#else
#include "fmu_common.h"
#endif
#include <stddef.h>

static const real START[N_STATES + N_PARAMS] = {
    1.0,                         /* x */
    1.0                          /* k */
};

static void model_initial(real *s, const real *p) { (void)s; (void)p; }

static void model_derivatives(real t, const real *s, const real *p, real *dx)
{
    if (t == 0.0) {
        /* p is the instance's own parameter array (fmu_core.h's FmuData): its instance */
        FmuInstance *m = (FmuInstance *)((char *)p - offsetof(FmuInstance, d.p));
        fmu_log(m, FMU_WARNING, "logStatusWarning", "chatty: a warning at the start time");
        printf("chatty: printed to standard output at the start time\n");
        fflush(stdout);
    }
    dx[0] = -p[0] * s[0];
}
