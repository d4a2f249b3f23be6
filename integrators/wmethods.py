"""W-methods: linearly implicit one-step methods with a frozen Jacobian approximation.

A W-method uses an arbitrary matrix ``A`` in place of the Jacobian of a
Rosenbrock method and keeps its order for any ``A``, so ``A`` can be kept over
many steps and ``I - h d A`` refactorized only when ``A`` or ``h`` changes.
Here ``A`` is the system's Jacobian (analytic, or forward differences of
``f``), re-evaluated at the first step starting at or after each of the times
``t0 + i (t_end - t0) / jac_updates`` (``jac_updates = 50``), so ``A`` is kept
over ``N / 50`` steps of a run of ``N`` steps (and over every step when
``N < 50``); the LU factorization is reused in between (a step split at an
output time or a shortened last step changes ``h`` and costs one
factorization). Refreshing on a time grid rather than every so many steps
keeps the error constant independent of ``h``, so the observed order is the
method's (a step-count rule made ``A - J = O(h)`` and the observed order of
``sw2`` about 3 over practical step ranges).

* ``w1``: ``(I - h A)(y_{n+1} - y_n) = h f(t_n, y_n)``, first order for any
  ``A``; with ``A = J`` it is the linearly implicit Euler method,
  ``R(z) = 1/(1 - z)``: L-stable.
* ``sw2``: the second-order W-method of Steihaug and Wolfbrandt with
  ``d = 1/(2 + sqrt 2)``::

      (I - h d A) k1 = f(t_n, y_n)
      (I - h d A) k2 = f(t_n + 2h/3, y_n + (2/3) h k1) - (4/3) h d A k1
      y_{n+1} = y_n + (h/4)(k1 + 3 k2)

  second order for any ``A`` (the ``A`` terms cancel in the order-2
  condition); with ``A = J``, ``R(inf) = 1 - 1/d + (1/2 - d)/d^2 = 0``:
  L-stable.

A sparse system (``jac`` returning a ``scipy.sparse`` matrix, or
``jac_sparsity`` for grouped differences) keeps ``A`` and ``I - h d A`` sparse,
factored by SuperLU (:mod:`integrator_bench.integrators.sparse`); a dense one
takes LAPACK as before.

Step grid and output times as in :mod:`integrator_bench.integrators.fixed_step`.

References: Steihaug and Wolfbrandt, Math. Comp. 33 (1979) 521-534; Hairer
and Wanner, Solving ODEs II, 2nd ed. (1996), sect. IV.7 ("W-methods").
"""

from __future__ import annotations

import math

import numpy as np

from integrator_bench.integrators.fixed_step import FixedStep
from integrator_bench.integrators.newton import jacobian
from integrator_bench.integrators.sparse import GroupedDifferences, factor, identity_minus


class WMethod(FixedStep):
    """Shared frozen-Jacobian machinery; subclasses implement :meth:`w_step`."""

    implicit = True
    uses_jacobian = True
    stability = "L"
    jac_updates = 50
    d = 1.0

    def step_function(self, system, counts):
        counts.update(njev=0, nlu=0)
        fun, scale = system.fun, np.asarray(system.atol_scale, float)
        state = {"A": None, "next": system.t0, "lu": None, "hd": None}
        every = (system.t_end - system.t0) / self.jac_updates
        sparsity = getattr(system, "jac_sparsity", None)
        grouped = (GroupedDifferences(sparsity)
                   if system.jac is None and sparsity is not None else None)

        def solve(t, y, dt):
            if state["A"] is None or t >= state["next"]:
                state.update(A=jacobian(fun, system.jac, scale, t, y, counts, grouped), lu=None,
                             next=system.t0 + every * (np.floor((t - system.t0) / every) + 1))
            hd = dt * self.d
            if state["lu"] is None or state["hd"] != hd:
                state["lu"] = self._factor(state["A"], hd)
                state["hd"] = hd
                counts["nlu"] += 1
            return self.w_step(lambda t_, y_: np.asarray(fun(t_, y_), float),
                               state["lu"], state["A"], t, y, dt)
        return solve

    @staticmethod
    def _factor(A, hd):
        """``solve(b)`` with ``(I - hd A) x = b``: SuperLU for a sparse ``A``, else LAPACK."""
        return factor(identity_minus(hd, A))

    def w_step(self, f, solve, A, t, y, h):
        raise NotImplementedError


class W1(WMethod):
    name = "w1"
    description = "W1: linearly implicit Euler, Jacobian renewed 50 times per run, fixed step"
    reference = "Hairer and Wanner, Solving ODEs II, 2nd ed., sect. IV.7"
    order = 1

    def w_step(self, f, solve, A, t, y, h):
        return y + solve(h * f(t, y))


class SW2(WMethod):
    name = "sw2"
    description = "Steihaug-Wolfbrandt order-2 W-method, Jacobian renewed 50 times per run, fixed step"
    reference = "Steihaug and Wolfbrandt, Math. Comp. 33 (1979) 521-534"
    order = 2
    d = 1.0 / (2.0 + math.sqrt(2.0))

    def w_step(self, f, solve, A, t, y, h):
        k1 = solve(f(t, y))
        k2 = solve(f(t + 2 * h / 3, y + (2 * h / 3) * k1) - (4 / 3) * h * self.d * (A @ k1))
        return y + h / 4 * (k1 + 3 * k2)
