"""A library call described for a user: the reproduction recipe's part that an
integrator gives (:meth:`~integrator_bench.integrators.base.Integrator.library_call`,
rule 11 of :mod:`~integrator_bench.integrators.base`).

The description is JSON-ready: numbers and strings as they are, arrays as lists,
and each callable the wrapper hands the library named by the system's function it
calls (``"system.fun"``, ``"system.jac"``), in the form the library takes it (the
call's ``callbacks`` say how: scikit-sundae's ``rhsfn(t, y, yp)`` writes
``system.fun(t, y)`` into ``yp``). A user passes the same options, with the same
functions of their own model, to the plain library and gets the same steps.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

#: the Jacobian's source, as a recipe states it
ANALYTIC = "analytic: the model's Jacobian, handed to the code"
DIFFERENCES = "the code's own difference quotients (no Jacobian handed over)"
NONE = "none: an explicit method"


def jacobian_source(uses_jacobian: bool, handed: bool) -> str:
    """The Jacobian's source of a call: :data:`ANALYTIC` when the system's Jacobian
    is handed to a code that uses one, :data:`DIFFERENCES` when such a code gets
    none, :data:`NONE` for an explicit method."""
    if not uses_jacobian:
        return NONE
    return ANALYTIC if handed else DIFFERENCES


def value(v, callables: dict | None = None):
    """``v`` as JSON: a callable by its name in ``callables`` (id -> name; else
    ``"a callable of the wrapper"``), an array as a list, a sparse structure as its
    size and non-zeros, a numpy scalar as a number."""
    callables = callables or {}
    if callable(v):
        return callables.get(id(v), "a callable of the wrapper")
    if sp.issparse(v):
        return f"sparse structure {v.shape[0]} x {v.shape[1]}, {v.nnz} non-zeros"
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, np.generic):
        return v.item()
    if isinstance(v, (list, tuple)):
        return [value(x, callables) for x in v]
    if isinstance(v, dict):
        return {str(k): value(x, callables) for k, x in v.items()}
    return v


def described(options: dict, callables: dict | None = None) -> dict:
    """Every option of ``options`` as JSON (:func:`value`), sorted by name."""
    return {k: value(options[k], callables) for k in sorted(options)}
