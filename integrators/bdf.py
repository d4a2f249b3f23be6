"""Fixed-step BDF2, BDF3 and BDF4 with simplified Newton.

The k-step BDF method computes ``y_{m}`` from the polynomial ``p`` through
``(t_{m-j}, y_{m-j})``, ``j = 0..k``, with ``p'(t_m) = f(t_m, y_m)``:

    sum_j alpha_j y_{m-j} = f(t_m, y_m),   alpha_j = L_j'(t_m),

where ``L_j`` are the Lagrange basis polynomials on the nodes. On the uniform
grid these are the classical coefficients ``a_j / (h b)`` (Hairer, Norsett
and Wanner, Solving ODEs I, 2nd ed., sect. III.1, the BDF formulas: BDF2
``1, -4/3, 1/3; 2/3``, BDF3 ``1, -18/11, 9/11, -2/11; 6/11``,
BDF4 ``1, -48/25, 36/25, -16/25, 3/25; 12/25``); tests check that.

* Steps: the shared driver (:mod:`integrator_bench.integrators.driver`) takes
  the steps ``t0 + m h``; when ``t_end - t0`` is not a multiple of ``h`` the
  last step is shortened to end exactly at ``t_end`` and uses the
  variable-step coefficients of the same formula on its actual nodes. The
  stepper keeps the ``k + 1`` latest accepted ``(t, y)`` and commits a step to
  them only when the driver accepts it. BDF is fixed-step only (no error
  estimate) and does not project (a projection would invalidate the history).
* Start: the first ``k - 1`` steps are taken with Alexander's L-stable SDIRK of
  order 3 (local error ``O(h^4)``, enough for global order ``k <= 4``); an
  explicit start such as RK4 would blow up on stiff problems at large ``h``.
* Dense output: a BDF step carries the method's own continuous extension, the
  polynomial through the ``k + 1`` latest step values including the new one
  (the polynomial the formula differentiates; interpolation error
  ``O(h^{k+1})``, below the method's ``O(h^k)``; no extra evaluations). The
  ``k - 1`` SDIRK start steps carry none: their output times are left to the
  driver's interpolation of degree ``k`` through the step values around them.
* Newton: predictor from the polynomial through the (up to) ``k + 1`` previous
  values; simplified Newton as in :mod:`integrator_bench.integrators.newton`,
  whose failure ends the run with status ``newton_failure``. A non-finite
  state or an overflow ends it as the driver says.

References: Curtiss and Hirschfelder, Proc. Natl. Acad. Sci. USA 38 (1952)
235-243; Hairer and Wanner, Solving ODEs II, 2nd ed. (1996), sect. V.1;
Gear, Numerical Initial Value Problems in ODEs (1971).
"""

from __future__ import annotations

from collections import deque

import numpy as np

from integrator_bench.integrators.base import Integrator, Step, Stepper
from integrator_bench.integrators.fixed_step import sdirk3_step
from integrator_bench.integrators.interpolation import hermite, lagrange
from integrator_bench.integrators.newton import NEWTON_SETTINGS, newton_solver

#: the angle alpha (degrees) of the A(alpha)-stability of the k-step BDF: stable in
#: the sector |arg(-h lambda)| < alpha (Hairer and Wanner II, sect. V.2, Table 2.3);
#: orders 1 and 2 are A-stable
A_ALPHA = {1: 90.0, 2: 90.0, 3: 86.03, 4: 73.35, 5: 51.84, 6: 17.84}


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


#: a step within this relative distance of the uniform step size uses its coefficients
UNIFORM_RTOL = 1e-9


def _start_dense(fun, t, y, h, y_new):
    """``dense(te)``: the cubic Hermite interpolant on ``[t, t + h]`` from the
    values and the slopes ``fun`` gives at both ends, evaluated at first use."""
    cache = []

    def dense(te):
        if not cache:
            cache.append(hermite(t, h, y, fun(t, y), y_new, fun(t + h, y_new)))
        return cache[0](te)
    return dense


class BDFStepper(Stepper):
    """One run of the ``k``-step BDF at the driver's constant step.

    Parameters
    ----------
    system : OdeSystem
        The system ``y' = f(t, y)``.
    counts : dict
        Counters updated in place by the Newton solver (``njev``, ``nlu``,
        ``nniter``, ``nnfail``).
    k : int
        Number of steps (the order).
    newton : ImplicitSolver
        The Newton solver of the steps (with the integrator's settings).
    """

    def __init__(self, system, counts, k: int, newton):
        super().__init__(system, counts)
        self.k = k
        self.dense_order = k
        self.newton = newton
        self.hist_t: deque = deque(maxlen=k + 1)
        self.hist_y: deque = deque(maxlen=k + 1)
        self.h = None         # the uniform step: the size of the first accepted step
        self.uniform = None   # alpha on the uniform grid, from the first BDF step's nodes

    def start(self, t0, y0):
        self.hist_t.append(t0)
        self.hist_y.append(np.array(y0, float))
        return y0

    def step(self, t, y, h):
        """SDIRK3 for the first ``k - 1`` steps, then one BDF step from the history.

        A starting step's dense output is the cubic Hermite interpolant of its
        ends, whose two slopes are evaluated on first use only: a state event
        crossed in a starting step (one acting both ways is crossed again just
        after each restart) is located on it, and an output time inside it
        takes it."""
        if len(self.hist_t) < self.k:
            y_new = sdirk3_step(self.newton, t, y, h)
            return Step(y_new, dense=_start_dense(self.system.fun, t, y, h, y_new))
        return self._bdf_step(t + h, h)

    def _bdf_step(self, t_new, h):
        k, hist_t, hist_y = self.k, self.hist_t, self.hist_y
        nodes = [t_new, *list(reversed(hist_t))[:k]]
        alpha = self._coefficients(nodes, h)
        c = 1.0 / alpha[0]
        r = -c * sum(alpha[j] * hist_y[-j] for j in range(1, k + 1))
        guess = lagrange(list(hist_t), list(hist_y), t_new)
        y_new = self.newton.solve(t_new, guess, c, r)
        dense_t = (list(hist_t) + [t_new])[-(k + 1):]
        dense_y = (list(hist_y) + [y_new])[-(k + 1):]
        return Step(y_new, dense=lambda te: lagrange(dense_t, dense_y, te))

    def _coefficients(self, nodes, h):
        """The uniform-grid ``alpha`` (computed once) for a step of the uniform
        size, else the variable-step ``alpha`` on ``nodes`` (a shortened last step)."""
        if not np.isclose(h, self.h, rtol=UNIFORM_RTOL, atol=0):
            return bdf_coefficients(nodes)
        if self.uniform is None:
            self.uniform = bdf_coefficients(nodes)
        return self.uniform

    def accept(self, t_new, y_new):
        if self.h is None:
            self.h = t_new - self.hist_t[-1]
        self.hist_t.append(t_new)
        self.hist_y.append(np.array(y_new, float))


class BDF(Integrator):
    """k-step BDF at fixed step; subclasses set ``order`` (= k)."""

    adaptive = False
    implicit = True
    uses_jacobian = True
    dense_output = True
    events = True          # located on the BDF polynomial by the driver
    settings = NEWTON_SETTINGS

    def stepper(self, system, counts, rtol=None, atol=None):
        return BDFStepper(system, counts, self.order, newton_solver(self, system, counts))


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
