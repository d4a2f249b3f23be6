"""A mechanical model written once, as sympy expressions; derivatives by sympy.

A problem deriving from :class:`SymbolicMechanics` implements only
:meth:`SymbolicMechanics.model`, returning M(q), f(t, q, v) and g(q) as sympy
matrices in the symbols it is handed. Everything else the formulations and
implicit integrators need (G = dg/dq, d(G v)/dq, d(M a)/dq, d(G^T lam)/dq,
df/dq, df/dv) is differentiated symbolically once per class and compiled with
``sympy.lambdify`` into numpy functions (common subexpressions shared). The
derivatives are exact, not finite differences.
"""

from __future__ import annotations

import functools

import numpy as np
import sympy as sym

from integrator_bench.problems.mechanical import MechanicalProblem


class SymbolicMechanics(MechanicalProblem):
    """Mixin base: give :meth:`model`, get the numeric model of MechanicalProblem."""

    def model(self, t, q, v, p):
        """Return ``(M, f, g)`` as sympy Matrices.

        Parameters
        ----------
        t : sympy.Symbol
        q, v : list of sympy.Symbol
            Coordinates and velocities, in the order of ``coordinates``.
        p : dict
            Parameter name -> sympy Symbol, for every declared parameter.
        """
        raise NotImplementedError

    @classmethod
    def _compiled(cls):
        if "_compiled_cache" not in cls.__dict__:
            cls._compiled_cache = _compile(cls)
        return cls._compiled_cache

    def _call(self, name, *arrays):
        fn = self._compiled()[name]
        args = np.concatenate([np.atleast_1d(np.asarray(a, dtype=float)) for a in arrays]).tolist()
        return np.array(fn(*args, *self._pvalues), dtype=float)

    @functools.cached_property
    def _pvalues(self) -> list:
        """The parameter values in declaration order (a problem's parameters are fixed)."""
        return [self.params[p.name] for p in self.parameters]

    def mass(self, q):
        return self._call("M", q)

    def force(self, t, q, v):
        return self._call("f", t, q, v).ravel()

    def constraint(self, q):
        return self._call("g", q).ravel()

    def constraint_jac(self, q):
        return self._call("G", q).reshape(self.nc, self.nq)

    def gv_q(self, q, v):
        return self._call("Gv_q", q, v).reshape(self.nc, self.nq)

    def accel_term(self, q, v):
        return self._call("gamma", q, v).ravel()

    def force_q(self, t, q, v):
        return self._call("f_q", t, q, v).reshape(self.nq, self.nq)

    def force_v(self, t, q, v):
        return self._call("f_v", t, q, v).reshape(self.nq, self.nq)

    def mass_q(self, q, a):
        return self._call("Ma_q", q, a).reshape(self.nq, self.nq)

    def gt_q(self, q, lam):
        return self._call("Gtl_q", q, lam).reshape(self.nq, self.nq)


def _compile(cls) -> dict:
    nq, nc = len(cls.coordinates), cls.n_constraints
    t = sym.Symbol("t")
    q = list(sym.symbols(f"q0:{nq}"))
    v = list(sym.symbols(f"v0:{nq}"))
    a = list(sym.symbols(f"a0:{nq}"))
    lam = list(sym.symbols(f"l0:{nc}"))
    p = {par.name: sym.Symbol(f"p_{par.name}") for par in cls.parameters}
    ps = list(p.values())
    M, f, g = (sym.Matrix(x) for x in cls.model(cls, t, q, v, p))
    qv, vv, av, lv = (sym.Matrix(x) for x in (q, v, a, lam))
    G = g.jacobian(qv)
    Gv_q = (G * vv).jacobian(qv)
    exprs = {
        "M": ((q,), M),
        "f": ((t, q, v), f),
        "g": ((q,), g),
        "G": ((q,), G),
        "Gv_q": ((q, v), Gv_q),
        "gamma": ((q, v), Gv_q * vv),
        "f_q": ((t, q, v), f.jacobian(qv)),
        "f_v": ((t, q, v), f.jacobian(vv)),
        "Ma_q": ((q, a), (M * av).jacobian(qv)),
        "Gtl_q": ((q, lam), (G.T * lv).jacobian(qv)),
    }
    out = {}
    for name, (groups, expr) in exprs.items():
        args = []
        for grp in groups:
            args += list(grp) if isinstance(grp, list) else [grp]
        out[name] = sym.lambdify(args + ps, expr, modules="numpy", cse=True)
    return out
