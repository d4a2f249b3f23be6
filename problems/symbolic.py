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
import types

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

    @classmethod
    def _compiled_many(cls):
        if "_compiled_many_cache" not in cls.__dict__:
            cls._compiled_many_cache = {key: _stacking(fn) for key, fn in cls._compiled().items()}
        return cls._compiled_many_cache

    def evaluate_many(self, name, *args):
        """All the points in one call of the compiled model (see
        :meth:`MechanicalProblem.evaluate_many`)."""
        key, shape = {"mass": ("M", (self.nq, self.nq)), "force": ("f", (self.nq,)),
                      "constraint": ("g", (self.nc,)),
                      "constraint_jac": ("G", (self.nc, self.nq)),
                      "accel_term": ("gamma", (self.nc,))}[name]
        columns = []
        for a in args:
            a = np.asarray(a, dtype=float)
            columns += [a] if a.ndim == 1 else list(a.T)
        n_points = len(columns[0])
        out = self._compiled_many()[key](*columns, *self._pvalues)
        return np.broadcast_to(out, (n_points,) + out.shape[-2:]).reshape((n_points,) + shape)

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


def _stacked(rows, *args, **kwargs):
    """Stand-in for ``numpy.array`` in a compiled model called with one column
    per variable: the matrix entries (arrays over the points, or constants)
    broadcast to one another and stacked into shape (points..., rows, columns)."""
    entries = np.broadcast_arrays(*(np.asarray(e, dtype=float) for row in rows for e in row))
    n_rows = len(rows)
    n_cols = len(rows[0]) if n_rows else 0
    if not entries:
        return np.zeros((n_rows, n_cols))
    return np.stack(entries, axis=-1).reshape(entries[0].shape + (n_rows, n_cols))


def _stacking(fn):
    """``fn`` (made by ``sympy.lambdify``, whose code builds its matrix with the
    global ``array``) with :func:`_stacked` in place of ``numpy.array``: the same
    expressions, evaluated at all the points of its array arguments at once."""
    return types.FunctionType(fn.__code__, dict(fn.__globals__, array=_stacked), fn.__name__,
                              fn.__defaults__, fn.__closure__)
