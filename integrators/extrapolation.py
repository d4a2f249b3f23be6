"""Extrapolation methods at a fixed step: extrapolated explicit Euler and GBS.

One step of size ``H`` computes ``T_{j,1}``, ``j = 1..K``, with ``n_j``
substeps of a basic method and extrapolates with the Aitken-Neville tableau

    T_{j,k+1} = T_{j,k} + (T_{j,k} - T_{j-1,k}) / ((n_j / n_{j-k})^p - 1),

returning ``T_{K,K}``. The slope ``f(t_n, y_n)`` is shared by all rows.

* ``euler-extrap``: explicit Euler, harmonic sequence ``n_j = j``, ``p = 1``
  (error expansion in powers of ``h``), ``K = 4``: order 4, 10 evaluations.
* ``gbs``: Gragg-Bulirsch-Stoer, explicit midpoint rule with ``n_j = 2j``
  substeps (``z_1 = z_0 + h f(z_0)``, ``z_{i+1} = z_{i-1} + 2 h f(z_i)``) and
  Gragg's smoothing ``S = (z_{n-1} + z_n + h f(z_n)) / 2``, ``p = 2`` (expansion
  in ``h^2``), ``K = 3``: order 6, 13 evaluations. (With ``K = 4``, order 8,
  the observed order on smooth test problems stays pre-asymptotic, 7.0-7.6,
  until rounding error takes over, so the order could not be verified to
  within 0.3.)

The order is fixed (no order or step control); step grid and output times as
in :mod:`integrator_bench.integrators.fixed_step`.

References: Hairer, Norsett and Wanner, Solving ODEs I, 2nd ed. (1993),
sect. II.9 (tableau (9.10), GBS (9.13)-(9.16)); Gragg, SIAM J. Numer. Anal. 2
(1965) 384-403; Bulirsch and Stoer, Numer. Math. 8 (1966) 1-13.
"""

from __future__ import annotations

import numpy as np

from integrator_bench.integrators.fixed_step import FixedStep


def extrapolate(rows, seq, p):
    """``T_{K,K}`` of the Aitken-Neville tableau from ``T_{j,1} = rows[j]``."""
    T = [rows[0]]
    for j in range(1, len(rows)):
        new = [rows[j]]
        for k in range(1, j + 1):
            ratio = (seq[j] / seq[j - k]) ** p - 1.0
            new.append(new[k - 1] + (new[k - 1] - T[k - 1]) / ratio)
        T = new
    return T[-1]


class Extrapolation(FixedStep):
    columns = 4
    power = 1

    def sequence(self):
        raise NotImplementedError

    def basic(self, f, t, y, f0, H, n):
        raise NotImplementedError

    def step_function(self, system, counts):
        fun = system.fun
        seq = self.sequence()

        def f(t, y):
            return np.asarray(fun(t, y), float)

        def step(t, y, H):
            f0 = f(t, y)
            rows = [self.basic(f, t, y, f0, H, n) for n in seq]
            return extrapolate(rows, seq, self.power)
        return step


class EulerExtrapolation(Extrapolation):
    name = "euler-extrap"
    description = "Extrapolated explicit Euler (harmonic sequence, 4 columns, order 4), fixed step"
    reference = "Hairer, Norsett, Wanner, Solving ODEs I, 2nd ed., sect. II.9"
    order = 4
    power = 1

    def sequence(self):
        return [j for j in range(1, self.columns + 1)]

    def basic(self, f, t, y, f0, H, n):
        h = H / n
        z = y + h * f0
        for i in range(1, n):
            z = z + h * f(t + i * h, z)
        return z


class GBS(Extrapolation):
    name = "gbs"
    description = "Gragg-Bulirsch-Stoer extrapolation (n_j = 2j, 3 columns, order 6), fixed step"
    reference = "Hairer, Norsett, Wanner, Solving ODEs I, 2nd ed., sect. II.9; Bulirsch and Stoer (1966)"
    order = 6
    power = 2
    columns = 3

    def sequence(self):
        return [2 * j for j in range(1, self.columns + 1)]

    def basic(self, f, t, y, f0, H, n):
        h = H / n
        z_prev, z = y, y + h * f0
        for i in range(1, n):
            z_prev, z = z, z_prev + 2 * h * f(t + i * h, z)
        return 0.5 * (z_prev + z + h * f(t + H, z))
