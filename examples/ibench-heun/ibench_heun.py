"""Heun's method as an integrator-bench plugin.

Heun (1900): the explicit trapezoidal rule, a two-stage Runge-Kutta method of
order 2 (Hairer, Norsett, Wanner, Solving ODEs I, sect. II.1)::

    k1 = f(t, y),  k2 = f(t + h, y + h k1),  y_new = y + h (k1 + k2) / 2
"""

import numpy as np

from integrator_bench.integrators.base import Integrator, Solution


class Heun(Integrator):
    name = "heun"                       # must equal the entry-point name
    description = "Heun's method (explicit trapezoidal rule), fixed step"
    reference = "Hairer, Norsett, Wanner, Solving ODEs I, 2nd ed., sect. II.1"
    accepts = frozenset({"ode"})        # explicit ODEs y' = f(t, y)
    order = 2
    adaptive = False                    # driven by a step size h, not rtol/atol

    def solve(self, system, *, rtol=None, atol=None, h=None):
        f, t_eval = system.fun, system.t_eval
        ys = [system.y0]
        t, y, nsteps = system.t0, system.y0, 0
        for t_out in t_eval[1:]:
            n = max(1, int(np.ceil((t_out - t) / h - 1e-9)))  # land on each output time
            dt = (t_out - t) / n
            for _ in range(n):
                k1 = f(t, y)
                k2 = f(t + dt, y + dt * k1)
                y, t, nsteps = y + 0.5 * dt * (k1 + k2), t + dt, nsteps + 1
            if not np.all(np.isfinite(y)):
                return Solution(t_eval[:len(ys)], np.array(ys), False,
                                f"non-finite state at t={t:g}", {"nsteps": nsteps, "nfev": 2 * nsteps})
            t = t_out
            ys.append(y)
        return Solution(t_eval, np.array(ys), True, "", {"nsteps": nsteps, "nfev": 2 * nsteps})
