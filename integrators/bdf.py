"""Fixed-step BDF2, BDF3 and BDF4 with simplified Newton.

The k-step BDF method computes ``y_{m}`` from the polynomial ``p`` through
``(t_{m-j}, y_{m-j})``, ``j = 0..k``, with ``p'(t_m) = f(t_m, y_m)``:

    sum_j alpha_j y_{m-j} = f(t_m, y_m),   alpha_j = L_j'(t_m),

where ``L_j`` are the Lagrange basis polynomials on the nodes. On the uniform
grid these are the classical coefficients ``a_j / (h b)`` (PROBLEMS.md
sect. 9: BDF2 ``1, -4/3, 1/3; 2/3``, BDF3 ``1, -18/11, 9/11, -2/11; 6/11``,
BDF4 ``1, -48/25, 36/25, -16/25, 3/25; 12/25``); tests check that.

* Steps: ``t0 + m h``; when ``t_end - t0`` is not a multiple of ``h`` the last
  step is shortened to end exactly at ``t_end`` and uses the variable-step
  coefficients of the same formula on its actual nodes.
* Start: the first ``k - 1`` steps are taken with Alexander's L-stable SDIRK of
  order 3 (local error ``O(h^4)``, enough for global order ``k <= 4``); an
  explicit start such as RK4 would blow up on stiff problems at large ``h``.
* Output times inside a step are interpolated with the polynomial through the
  ``k + 1`` latest step values that enclose them (interpolation error
  ``O(h^{k+1})``, below the method's ``O(h^k)``); no extra evaluations.
* A non-finite state, or an ``OverflowError`` from ``f``, ends the run with
  ``success=False``.
* Newton: predictor from the polynomial through the ``k + 1`` previous values;
  simplified Newton as in :mod:`integrator_bench.integrators.newton`.

References: Curtiss and Hirschfelder, Proc. Natl. Acad. Sci. USA 38 (1952)
235-243; Hairer and Wanner, Solving ODEs II, 2nd ed. (1996), sect. V.1;
Gear, Numerical Initial Value Problems in ODEs (1971).
"""

from __future__ import annotations

from collections import deque

import numpy as np

from integrator_bench.integrators.base import Integrator, Solution
from integrator_bench.integrators.fixed_step import StepFailure, blow_up_message, sdirk3_step
from integrator_bench.integrators.newton import ImplicitSolver, NewtonFailure


def bdf_coefficients(nodes) -> np.ndarray:
    """``alpha_j = L_j'(nodes[0])`` for the Lagrange basis on ``nodes``."""
    x = np.asarray(nodes, float)
    k = x.size - 1
    alpha = np.empty(k + 1)
    alpha[0] = sum(1.0 / (x[0] - x[i]) for i in range(1, k + 1))
    for j in range(1, k + 1):
        num = np.prod([x[0] - x[i] for i in range(1, k + 1) if i != j])
        den = np.prod([x[j] - x[i] for i in range(k + 1) if i != j])
        alpha[j] = num / den
    return alpha


def lagrange(nodes, values, t) -> np.ndarray:
    """Value at ``t`` of the polynomial through ``(nodes[i], values[i])``."""
    out = 0.0
    for j, xj in enumerate(nodes):
        w = np.prod([(t - xi) / (xj - xi) for i, xi in enumerate(nodes) if i != j])
        out = out + w * values[j]
    return out


def step_times(t0: float, t_end: float, h: float) -> np.ndarray:
    """``t0 + m h`` up to ``t_end``; the last one is exactly ``t_end``."""
    if not (np.isfinite(h) and h > 0):
        raise ValueError(f"step size h={h!r} must be a positive finite number")
    n = int(np.floor((t_end - t0) / h + 1e-9))
    times = t0 + h * np.arange(n + 1)
    if t_end - times[-1] > 1e-9 * h:
        times = np.append(times, t_end)
    else:
        times[-1] = t_end
    return times


class BDF(Integrator):
    """k-step BDF at fixed step; subclasses set ``order`` (= k)."""

    adaptive = False
    implicit = True
    uses_jacobian = True

    def solve(self, system, *, rtol=None, atol=None, h=None):
        if h is None:
            raise ValueError(f"{self.name} is a fixed-step method and needs h")
        k = self.order
        counts = {"nsteps": 0, "nreject": 0}
        newton = ImplicitSolver(system, counts)
        times = step_times(system.t0, system.t_end, h)
        t_eval = system.t_eval
        ys = np.empty((t_eval.size, system.n))
        ys[0] = system.y0
        out = 1
        hist_t = deque([system.t0], maxlen=k + 1)
        hist_y = deque([np.array(system.y0, float)], maxlen=k + 1)
        uniform = None
        message = ""
        try:
            for m in range(1, times.size):
                t_new, t_old, y_old = times[m], hist_t[-1], hist_y[-1]
                if m < k:
                    y_new = sdirk3_step(newton, t_old, y_old, t_new - t_old)
                else:
                    nodes = [t_new, *list(reversed(hist_t))[:k]]
                    if m < times.size - 1 or np.isclose(t_new - t_old, h, rtol=1e-9, atol=0):
                        if uniform is None:
                            uniform = bdf_coefficients(nodes)
                        alpha = uniform
                    else:
                        alpha = bdf_coefficients(nodes)
                    c = 1.0 / alpha[0]
                    r = -c * sum(alpha[j] * hist_y[-j] for j in range(1, k + 1))
                    guess = lagrange(list(hist_t), list(hist_y), t_new)
                    y_new = newton.solve(t_new, guess, c, r)
                if not np.all(np.isfinite(y_new)):
                    raise StepFailure(f"non-finite state at t={t_new:.6g}")
                counts["nsteps"] += 1
                hist_t.append(t_new)
                hist_y.append(y_new)
                out = self._outputs(t_eval, ys, out, hist_t, hist_y, k, last=m == times.size - 1)
        except (StepFailure, NewtonFailure) as exc:
            message = str(exc)
        except OverflowError as exc:
            message = blow_up_message(hist_t[-1], exc)
        return Solution(t_eval[:out], ys[:out], not message, message, counts)

    @staticmethod
    def _outputs(t_eval, ys, out, hist_t, hist_y, k, last):
        """Fill outputs up to the latest step once ``k + 1`` values enclose them."""
        t_now = hist_t[-1]
        if len(hist_t) < k + 1 and not last:
            return out  # start phase: wait until the interpolant has k + 1 nodes
        nodes, values = list(hist_t), list(hist_y)
        while out < t_eval.size and t_eval[out] <= t_now:
            te = t_eval[out]
            hit = [i for i, tn in enumerate(nodes) if tn == te]
            ys[out] = values[hit[0]] if hit else lagrange(nodes, values, te)
            out += 1
        return out


class BDF2(BDF):
    name = "bdf2"
    description = "2-step BDF with simplified Newton, fixed step (SDIRK3 start)"
    reference = "Curtiss and Hirschfelder, PNAS 38 (1952) 235-243; Hairer and Wanner II, sect. V.1"
    order = 2
    stability = "L"


class BDF3(BDF):
    name = "bdf3"
    description = "3-step BDF (A(86.03 deg)-stable) with simplified Newton, fixed step (SDIRK3 start)"
    reference = "Curtiss and Hirschfelder, PNAS 38 (1952) 235-243; Hairer and Wanner II, sect. V.1"
    order = 3


class BDF4(BDF):
    name = "bdf4"
    description = "4-step BDF (A(73.35 deg)-stable) with simplified Newton, fixed step (SDIRK3 start)"
    reference = "Curtiss and Hirschfelder, PNAS 38 (1952) 235-243; Hairer and Wanner II, sect. V.1"
    order = 4
