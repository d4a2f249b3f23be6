"""A mechanical model written once, as sympy expressions; derivatives by sympy.

A problem deriving from :class:`SymbolicMechanics` implements only
:meth:`SymbolicMechanics.model`, returning M(q), f(t, q, v) and g(q) as sympy
matrices in the symbols it is handed. Everything else the formulations and
implicit integrators need (G = dg/dq, d(G v)/dq, d(M a)/dq, d(G^T lam)/dq,
df/dq, df/dv) is differentiated symbolically once per class and compiled with
``sympy.lambdify`` into numpy functions (common subexpressions shared). The
derivatives are exact, not finite differences.

A constraint that uses the time symbol ``t`` makes the problem driven
(:attr:`~integrator_bench.problems.mechanical.MechanicalProblem.driven`, read
from the expressions): its constraint functions are compiled with the time as
their last argument, with ``g_t``, ``G_t = d(g_t)/dq`` and the acceleration term
``(d(G v)/dq) v + 2 G_t v + g_tt``, all differentiated symbolically.
"""

from __future__ import annotations

import dataclasses
import functools
import types

import numpy as np
import sympy as sym

from integrator_bench.problems.linalg import solve
from integrator_bench.problems.mechanical import MechanicalProblem


class _Driven:
    """``driven`` of a :class:`SymbolicMechanics` class, on the class and its
    instances alike: whether its constraint expressions hold the time symbol."""

    def __get__(self, obj, cls):
        if "_driven_cache" not in cls.__dict__:
            cls._driven_cache = bool(cls.coordinates) and _expressions(cls)[5]
        return cls._driven_cache


class SymbolicMechanics(MechanicalProblem):
    """Mixin base: give :meth:`model`, get the numeric model of MechanicalProblem."""

    driven = _Driven()

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

    @classmethod
    def _compiled_entries(cls):
        if "_compiled_entries_cache" not in cls.__dict__:
            cls._compiled_entries_cache = _compile(cls, entries=True)
            cls._compiled_many()   # both forms at once: a process that formulates the
            # problem (the runner, before it forks the case's worker) has both compiled
        return cls._compiled_entries_cache

    def _call(self, name, *arrays):
        """The matrix ``name`` at one point: its structural nonzeros evaluated
        (once per instance when they depend on the parameters only, as a
        constant mass matrix does) and scattered into a zero matrix."""
        entries = self._compiled_entries()[name]
        if entries.constant:
            cache = self.__dict__.setdefault("_constant_entries", {})
            if name not in cache:
                cache[name] = entries.matrix(entries.fn(*entries.dummy_args, *self._pvalues))
            return cache[name].copy()
        return entries.matrix(entries.fn(*_floats(arrays), *self._pvalues))

    @classmethod
    def _compiled_many(cls):
        if "_compiled_many_cache" not in cls.__dict__:
            cls._compiled_many_cache = {key: _stacking(fn) for key, fn in cls._compiled().items()}
        return cls._compiled_many_cache

    def evaluate_many(self, name, *args):
        """All the points in one call of the compiled model (see
        :meth:`MechanicalProblem.evaluate_many`)."""
        key, shape = {"mass": ("M", (self.nq, self.nq)), "force": ("f", (self.nq,)),
                      "constraint_t": ("g_t", (self.nc,)),
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

    def accelerations(self, t, q, v, extra=None):
        """:meth:`MechanicalProblem.accelerations` from one compiled call that gives
        the augmented matrix and its right-hand side together (their common
        subexpressions shared), solved by LAPACK's ``gesv``. A subclass that
        overrides one of the functions the augmented system is made of (the
        conformance check's faulty pendulum overrides ``force``) gets them called
        one by one, its override included."""
        if self.sparse or not _own_functions(type(self)):
            return super().accelerations(t, q, v, extra)
        kkt = self._compiled_entries()["kkt"]
        n = self.nq + self.nc
        # [K | rhs] in Fortran order, so LAPACK factors K and solves in place, no copy
        system = np.zeros((n, n + 1), order="F")
        system.T.put(kkt.transposed_index, kkt.fn(*_floats((t, q, v)), *self._pvalues))
        if extra is not None:
            system[self.nq:, n] -= extra
        x = solve(system[:, :n], system[:, n], overwrite=True)
        return x[:self.nq], x[self.nq:]

    def mass(self, q):
        return self._call("M", q)

    def force(self, t, q, v):
        return self._call("f", t, q, v).ravel()

    def constraint(self, q, *t):
        return self._call("g", q, *t).ravel()

    def constraint_jac(self, q, *t):
        return self._call("G", q, *t).reshape(self.nc, self.nq)

    def gv_q(self, q, v, *t):
        return self._call("Gv_q", q, v, *t).reshape(self.nc, self.nq)

    def accel_term(self, q, v, *t):
        return self._call("gamma", q, v, *t).ravel()

    def constraint_t(self, q, t):
        return self._call("g_t", q, t).ravel()

    def constraint_jac_t(self, q, t):
        return self._call("G_t", q, t).reshape(self.nc, self.nq)

    def force_q(self, t, q, v):
        return self._call("f_q", t, q, v).reshape(self.nq, self.nq)

    def force_v(self, t, q, v):
        return self._call("f_v", t, q, v).reshape(self.nq, self.nq)

    def mass_q(self, q, a):
        return self._call("Ma_q", q, a).reshape(self.nq, self.nq)

    def gt_q(self, q, lam, *t):
        return self._call("Gtl_q", q, lam, *t).reshape(self.nq, self.nq)


@functools.lru_cache(maxsize=None)
def _own_functions(cls) -> bool:
    """Whether ``cls`` evaluates the augmented system's parts with the compiled
    model itself (no override of them below :class:`SymbolicMechanics`)."""
    return all(getattr(cls, name) is getattr(SymbolicMechanics, name)
               for name in ("mass", "force", "constraint_jac", "accel_term"))


def _floats(arrays) -> list:
    """The scalars and vectors ``arrays`` as one flat list of Python floats (the
    compiled code's arguments; floats, not numpy scalars, keep its arithmetic fast).
    A numpy float scalar (the time scipy's solvers pass) is converted as a float,
    not through an array (which costs a tenth of a small model's call)."""
    out = []
    for a in arrays:
        if type(a) is np.ndarray and a.ndim == 1 and a.dtype == np.float64:
            out += a.tolist()
        elif isinstance(a, float):      # float and numpy.float64
            out.append(float(a))
        else:
            out += np.atleast_1d(np.asarray(a, dtype=float)).ravel().tolist()
    return out


@dataclasses.dataclass(frozen=True)
class _Entries:
    """A compiled matrix as its structural nonzeros: ``fn(*args, *params)`` gives
    their values (a list), :meth:`matrix` the dense matrix; ``constant`` when
    they depend on the parameters only (``dummy_args`` then stand for the rest)."""

    fn: object
    shape: tuple
    index: np.ndarray
    constant: bool
    dummy_args: tuple

    @functools.cached_property
    def transposed_index(self) -> np.ndarray:
        """The nonzeros' flat indices in the transpose (column-major positions)."""
        rows, cols = np.unravel_index(self.index, self.shape)
        return cols * self.shape[0] + rows

    def matrix(self, values) -> np.ndarray:
        out = np.zeros(self.shape)
        out.put(self.index, values)   # put: twice as fast as flat[index] = for a list
        return out


def _expressions(cls) -> tuple:
    """``(t, q, v, p, (M, f, g), driven)``: the model's sympy matrices in fresh
    symbols, and whether its constraints hold the time."""
    nq = len(cls.coordinates)
    t = sym.Symbol("t")
    q = list(sym.symbols(f"q0:{nq}"))
    v = list(sym.symbols(f"v0:{nq}"))
    p = {par.name: sym.Symbol(f"p_{par.name}") for par in cls.parameters}
    M, f, g = (sym.Matrix(x) for x in cls.model(cls, t, q, v, p))
    return t, q, v, p, (M, f, g), t in g.free_symbols


def _compile(cls, entries: bool = False) -> dict:
    """Name -> the compiled matrix: ``lambdify``'d whole (its array, for
    :func:`_stacking`), or with ``entries`` as :class:`_Entries` (the one-point
    path, which builds a mostly-zero matrix in a fraction of the time). The
    constraint functions of a driven model take the time last (``T``)."""
    nq, nc = len(cls.coordinates), cls.n_constraints
    t, q, v, p, (M, f, g), driven = _expressions(cls)
    a = list(sym.symbols(f"a0:{nq}"))
    lam = list(sym.symbols(f"l0:{nc}"))
    ps = list(p.values())
    qv, vv, av, lv = (sym.Matrix(x) for x in (q, v, a, lam))
    G = g.jacobian(qv)
    Gv_q = (G * vv).jacobian(qv)
    T = (t,) if driven else ()
    gamma = Gv_q * vv
    exprs = {
        "M": ((q,), M),
        "f": ((t, q, v), f),
        "g": ((q, *T), g),
        "G": ((q, *T), G),
        "Gv_q": ((q, v, *T), Gv_q),
        "f_q": ((t, q, v), f.jacobian(qv)),
        "f_v": ((t, q, v), f.jacobian(vv)),
        "Ma_q": ((q, a), (M * av).jacobian(qv)),
        "Gtl_q": ((q, lam, *T), (G.T * lv).jacobian(qv)),
    }
    if driven:     # g_t, G_t = d(g_t)/dq, and gamma = (d(G v)/dq) v + 2 G_t v + g_tt
        g_t = g.diff(t)
        G_t = g_t.jacobian(qv)
        gamma = gamma + 2 * G_t * vv + g_t.diff(t)
        exprs.update(g_t=((q, t), g_t), G_t=((q, t), G_t))
    exprs["gamma"] = ((q, v, *T), gamma)
    if entries:    # the augmented system [[M, G^T], [G, 0]] [a; lam] = [f; -gamma], whole
        kkt = sym.Matrix.vstack(sym.Matrix.hstack(M, G.T, f),
                                sym.Matrix.hstack(G, sym.zeros(nc, nc), -exprs["gamma"][1]))
        exprs["kkt"] = ((t, q, v), kkt)
    out = {}
    for name, (groups, expr) in exprs.items():
        args = []
        for grp in groups:
            args += list(grp) if isinstance(grp, list) else [grp]
        if not entries:
            out[name] = sym.lambdify(args + ps, expr, modules="numpy", cse=True)
            continue
        flat = list(expr)
        index = np.array([i for i, e in enumerate(flat) if e != 0], dtype=np.intp)
        values = [flat[i] for i in index]
        constant = not set().union(*(e.free_symbols for e in values)) - set(ps)
        out[name] = _Entries(_compile_entries_fn(args + ps, values), expr.shape, index,
                             constant, (0.0,) * len(args))
    return out


def _compile_entries_fn(args: list, values: list):
    """``values`` (sympy expressions in ``args``) compiled for one point: a function
    of Python floats returning their values as a list (:func:`_guarded`)."""
    return _guarded(sym.lambdify(args, values, modules="math", cse=True),
                    functools.partial(sym.lambdify, args, values, modules="numpy", cse=True))


def _guarded(fast, make_safe):
    """The one-point model: ``fast`` (compiled with Python's ``math``, on the Python
    floats of :func:`_floats`: about a third of the time of numpy's scalar functions
    on a mechanism, the same values), or, at a point where Python's float arithmetic
    raises (``math.sqrt`` of a negative, an overflow, a division by zero: a run
    gone astray), the same expressions with numpy's functions (compiled by
    ``make_safe()`` on first need), which give NaN or an infinite value for the
    integrator to fail on, as the model always did."""
    safe = []

    def fn(*args):
        try:
            return fast(*args)
        except (ValueError, OverflowError, ZeroDivisionError):
            if not safe:
                safe.append(make_safe())
            return safe[0](*args)
    fn.fast, fn.make_safe = fast, make_safe   # both forms, for the tests
    return fn


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
