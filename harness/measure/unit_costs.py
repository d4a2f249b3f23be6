"""Unit costs of a system, and the work of a case: what the method costs without its code's overhead.

A case's CPU (``cpu_s``) is what the code costs in this Python stack: the model's
evaluations plus the code's own interpreter overhead, which on the cheap
benchmark models is most of it. The **work** of a case is what the same counted
evaluations cost at the model and in the linear algebra alone, each at its
**unit cost** measured on this machine:

``work = nfev * rhs + njev_model * jac + nlu * lu + nsolve * solve + sum(calls * cost)``

* ``rhs``: one right-hand side (ODE ``fun``), residual (DAE ``residual``) or force
  (mechanical ``force``): the calls the harness counts as ``nfev``, the
  finite-difference calls of a code's own Jacobian included.
* ``jac``: one analytic Jacobian (ODE/DAE ``jac``, mechanical ``tangent``): only
  the calls the harness counted at the model (``njev_model``); a code that
  forms its Jacobian by differences pays for it in ``nfev``, so its ``njev``
  adds nothing here.
* ``lu``: one LU factorization of the iteration matrix at the system's size
  and sparsity (LAPACK ``getrf``, timed over a stack of copies in one numpy
  call, for a dense matrix; SuperLU through :func:`scipy.sparse.linalg.splu`
  for a sparse one, as the codes use them), times the record's ``nlu``.
* ``solve``: one solve with those factors, times ``nsolve``, the Newton
  iterations the code reports (``nniter``: one linear solve each).
* ``others``: one call of each other model callable the harness counts and can
  call at the initial state without changing the system (``project``, each
  event function ``events[i].value``; the second-order form's ``mass``,
  ``constraint``, ``constraint_jac`` and ``accel_term``), times its calls in the
  case (the record's ``model_calls``). An event's ``reset`` is not timed (it
  may switch the problem's mode): its calls add nothing.

A counter the code does not report (null) adds nothing, so the work of such a
code is a lower bound (docs/record.md lists what each family reports: the
in-house implicit steppers and scikit-sundae's CVODE and IDA both ``nlu`` and
``nniter``; scipy's implicit codes, the in-house W-methods and Assimulo's
RADAU5 and RODAS ``nlu`` only; Assimulo's CVODE and IDA ``nniter`` only; LSODAR neither). The iteration matrix is the one of the
system's kind: ``I - gamma J`` of an ODE (gamma = 0.05), ``dF/dy + cj dF/dy'``
of a DAE (cj = 20), ``[[M + K + C, G^T], [G, 0]]`` of the second-order form
(HHT-type methods); its numbers do not matter to the cost, only its size and
pattern (a made-up dense matrix where the system gives neither a Jacobian nor
a pattern: a code's finite differences give a dense one). Radau IIA's complex 2x2 block system and a Krylov solver's iterations
are not modelled (they are counted as one real factorization and solve).

Each unit cost is the median over :data:`BATCHES` batches of calls, a batch
long enough (:data:`BATCH_S`) for the process clock to time it, on the
system the integrator is handed (its kind: ODE, DAE or second-order form) at
its initial state. They are measured once per problem, parameter set,
formulation and kind in a process (:func:`costs_of`: each worker of a run
measures them in its first case of the kind, never the command's own
process, where a model's code does not run) and kept
in every record (``unit_costs``). ``ibench reference -p PROBLEM --unit-costs``
measures and prints them.

``overhead = cpu_s / work``: how many times the method's own cost the code took
(1 for a code whose every cycle is the model and the linear algebra).
"""

from __future__ import annotations

import contextlib
import functools
import json
import statistics
import time
import warnings
from dataclasses import asdict, dataclass, field

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from integrator_bench.problems.system import DENSE_JACOBIAN_LIMIT

#: timed batches per unit cost (their median is the cost)
BATCHES = 9
#: CPU seconds a batch lasts at least (the number of calls in it is grown to it)
BATCH_S = 2e-4
#: a matrix of more states than this with a sparse Jacobian is factorized as sparse
SPARSE_FROM = 50
#: matrices factorized per timed call of a small dense factorization (no Python call each)
STACK = 64
#: right-hand sides a solve is timed with (against one: the difference is their cost)
COLUMNS = 65
#: a call slower than this is timed in 3 batches only
SLOW_CALL_S = 5e-3
#: bytes the stack of copies of a dense matrix may take (fewer copies of a large one)
STACK_BYTES = 16e6
#: gamma of the ODE iteration matrix I - gamma J and cj of the DAE's dF/dy + cj dF/dy'
ODE_GAMMA, DAE_CJ = 0.05, 20.0


@dataclass(frozen=True)
class UnitCosts:
    """CPU seconds of one call of each kind, and the iteration matrix they were taken at."""

    rhs: float                 # one right-hand side / residual / force evaluation
    jac: float | None          # one analytic Jacobian (None: the system has none)
    lu: float | None           # one factorization of the iteration matrix (None: see measure)
    solve: float | None        # one solve with its factors
    n: int                     # size of the iteration matrix
    nnz: int                   # its stored non-zeros (n * n when dense)
    sparse: bool               # factorized by SuperLU (True) or LAPACK (False)
    #: one call of each other counted model callable, by its counter's name
    others: dict = field(default_factory=dict)

    def to_json(self) -> str:
        def short(v):
            if isinstance(v, dict):
                return {k: short(x) for k, x in v.items()}
            return float(f"{v:.4g}") if isinstance(v, float) else v
        return json.dumps({k: short(v) for k, v in asdict(self).items()}, sort_keys=True)


def per_call(fn, batches: int = BATCHES, batch_s: float = BATCH_S) -> float:
    """Median CPU seconds of one call of ``fn()`` over ``batches`` timed batches,
    each of as many calls as last ``batch_s`` at least (doubled until they do)."""
    calls, clock = 1, time.process_time
    while True:
        start = clock()
        for _ in range(calls):
            fn()
        spent = clock() - start
        if spent >= batch_s or calls >= 1 << 20:
            break
        calls *= 2
    if spent / calls > SLOW_CALL_S:   # a large system's factorization: a few calls say enough
        batches = min(batches, 3)
    times = [spent / calls]
    for _ in range(batches - 1):
        start = clock()
        for _ in range(calls):
            fn()
        times.append((clock() - start) / calls)
    return statistics.median(times)


def _dense(m) -> np.ndarray:
    return np.asarray(m.toarray() if sp.issparse(m) else m, float)


def _made_up(n: int) -> np.ndarray:
    """A dense, well-conditioned n x n matrix: a code without a Jacobian forms a
    dense one by differences (the calls are in ``nfev``); its factorization
    costs what any dense matrix of its size costs."""
    return np.eye(n) + 0.01 * np.random.default_rng(0).standard_normal((n, n)) / np.sqrt(n)


def _pattern(sparsity, n):
    """A sparse matrix of the structure ``sparsity`` with made-up values (or None)."""
    if sparsity is None:
        return None
    pattern = sp.csc_matrix(sparsity, dtype=float, shape=(n, n))
    pattern.data[:] = 0.01
    return pattern


def _ode(system):
    t, y, n = system.t0, system.y0.copy(), system.n
    rhs = lambda: system.fun(t, y)                                     # noqa: E731
    jac = (lambda: system.jac(t, y)) if system.jac is not None else None   # noqa: E731
    if jac is not None:
        J = jac()
    elif system.jac_sparsity is not None:
        J = _pattern(system.jac_sparsity, n)
    elif n > DENSE_JACOBIAN_LIMIT:   # no code may form it (problems/system.py convert)
        return rhs, jac, None
    else:
        J = _made_up(n)
    identity = sp.identity(n, format="csc") if sp.issparse(J) else np.eye(n)
    return rhs, jac, identity - ODE_GAMMA * J


def _dae(system):
    t, y, yp, n = system.t0, system.y0.copy(), system.yp0.copy(), system.n
    rhs = lambda: system.residual(t, y, yp)                            # noqa: E731
    jac = (lambda: system.jac(t, y, yp, DAE_CJ)) if system.jac is not None else None  # noqa: E731
    if jac is not None:
        A = jac()
    elif system.jac_sparsity is not None:
        A = _pattern(system.jac_sparsity, n) + sp.identity(n, format="csc")
    elif n > DENSE_JACOBIAN_LIMIT:
        return rhs, jac, None
    else:
        A = _made_up(n)
    return rhs, jac, A


def _mechanical(system):
    t = system.t0
    q, v, lam = (x.copy() for x in system.split(system.y0))
    a = np.asarray(system.a0, float).copy()
    rhs = lambda: system.force(t, q, v)                                # noqa: E731
    jac = (lambda: system.tangent(t, q, v, a, lam)) if system.tangent is not None else None  # noqa: E731
    M = system.mass(q)
    K, C = jac() if jac is not None else (0 * M, 0 * M)
    top = M + K + C
    if system.nc == 0:
        return rhs, jac, top
    G = system.constraint_jac(q, *system.at(t))
    if sp.issparse(top) or sp.issparse(G):
        S = sp.bmat([[sp.csc_matrix(top), sp.csc_matrix(G).T], [sp.csc_matrix(G), None]],
                    format="csc")
    else:
        G = np.asarray(G, float)
        S = np.block([[np.asarray(top, float), G.T], [G, np.zeros((G.shape[0],) * 2)]])
    return rhs, jac, S


_KINDS = {"ode": _ode, "dae": _dae, "mechanical": _mechanical}
#: the second-order form's other callables, with the parts of the state they take
_MECHANICAL_CALLS = {"mass": "q", "constraint": "q", "constraint_jac": "q", "accel_term": "qv"}


def other_calls(system) -> dict:
    """``{counter name: call()}`` of the other model callables of ``system`` that
    are timed (see the module docstring), each at the initial state."""
    t, y = system.t0, system.y0.copy()
    calls = {}
    if system.kind == "mechanical":
        q, v, _ = (x.copy() for x in system.split(y))
        for name, takes in _MECHANICAL_CALLS.items():
            fn = getattr(system, name, None)
            if fn is not None:
                args = (q,) if takes == "q" else (q, v)
                timed = system.at(t) if name != "mass" else ()   # driven constraints take t
                calls[name] = functools.partial(fn, *args, *timed)
    elif getattr(system, "project", None) is not None:
        calls["project"] = functools.partial(system.project, t, y)
    for i, event in enumerate(system.events):
        calls[f"events[{i}].value"] = functools.partial(event.value, t, y)
    return calls


def measure(system) -> UnitCosts | None:
    """The unit costs of ``system`` (an ODE, DAE or second-order form) at its
    initial state; None for a kind without a model the harness can call (an FMU).
    A system of more than ``DENSE_JACOBIAN_LIMIT`` states with neither a
    Jacobian nor a sparsity pattern has no iteration matrix (no code may form
    one, :func:`~integrator_bench.problems.system.convert`): its ``lu`` and
    ``solve`` are None."""
    parts = _KINDS.get(system.kind)
    if parts is None:
        return None
    rhs, jac, A = parts(system)
    costs = dict(rhs=per_call(rhs), jac=per_call(jac) if jac is not None else None,
                 others={name: per_call(call) for name, call in other_calls(system).items()})
    if A is None:   # a large system without a Jacobian: no iteration matrix is ever formed
        return UnitCosts(**costs, lu=None, solve=None, n=system.n, nnz=0, sparse=False)
    sparse = sp.issparse(A) and A.shape[0] > SPARSE_FROM
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")   # a singular made-up matrix still times its factorization
        lu, solve = (_sparse_lu if sparse else _dense_lu)(A)
    return UnitCosts(**costs, lu=lu, solve=solve, n=int(A.shape[0]),
                     nnz=int(A.nnz) if sparse else int(A.shape[0]) ** 2, sparse=sparse)


def _per_column(solve_with, n: int) -> float:
    """CPU seconds of one right-hand side of ``solve_with(B)``: the difference
    between solving for :data:`COLUMNS` columns and for one, per column, so the
    call's own fixed cost (Python's) cancels."""
    one, many = np.ones((n, 1)), np.ones((n, COLUMNS))
    return max(per_call(lambda: solve_with(many)) - per_call(lambda: solve_with(one)),
               0.0) / (COLUMNS - 1)


def _dense_lu(A) -> tuple[float, float]:
    """LAPACK's ``getrf`` and one ``getrs`` on the dense ``A``, timed in C loops:
    numpy's :func:`numpy.linalg.det` factorizes each matrix of a stack in one
    call (a code in C or Fortran pays no Python call per factorization), and a
    solve is the cost per column of :func:`scipy.linalg.lu_solve` (``getrs``)."""
    A = _dense(A)
    n = A.shape[0]
    copies = int(max(1, min(STACK, STACK_BYTES // (8 * n * n))))
    stack = np.broadcast_to(A, (copies, n, n)).copy()
    lu = per_call(lambda: np.linalg.det(stack)) / copies
    factors = la.lu_factor(A, check_finite=False)
    return lu, _per_column(lambda B: la.lu_solve(factors, B, check_finite=False), n)


def _sparse_lu(A) -> tuple[float, float]:
    """SuperLU's factorization (:func:`scipy.sparse.linalg.splu`) of the sparse
    ``A`` and its solve, per column."""
    A = sp.csc_matrix(A)
    A.sort_indices()
    factors = spla.splu(A)
    return per_call(lambda: spla.splu(A)), _per_column(factors.solve, A.shape[0])


# (class, name, params, formulation, kind) -> UnitCosts or None, measured once per process
_measured: dict = {}


@contextlib.contextmanager
def not_measured():
    """Inside the block :func:`costs_of` measures nothing and gives None (the
    records' work null): for runs of a model that counts its own calls, such as
    ``ibench check-plugin``'s faulty problems, which fail after a number of
    evaluations and must see the integrator's alone."""
    global _ENABLED
    before, _ENABLED = _ENABLED, False
    try:
        yield
    finally:
        _ENABLED = before


#: whether :func:`costs_of` measures (see :func:`not_measured`)
_ENABLED = True


def costs_of(problem, formulation: str, system) -> UnitCosts | None:
    """The unit costs of ``problem`` in ``formulation`` as the system ``system``
    (its kind: the form an integrator was handed), measured once in this process
    (:func:`measure`); None where they cannot be measured (an FMU, or a model
    that raises at its initial state), and inside :func:`not_measured`."""
    if not _ENABLED:
        return None
    key = (type(problem).__qualname__, problem.name,
           json.dumps(problem.params, sort_keys=True, default=str), formulation, system.kind)
    if key not in _measured:
        try:
            _measured[key] = measure(system)
        except Exception:   # noqa: BLE001  no costs is a null work, never a failed case
            _measured[key] = None
    return _measured[key]


def work(costs: UnitCosts | None, nfev, njev_model, nlu, nniter,
         calls: dict | None = None) -> float | None:
    """The CPU seconds of a case's counted evaluations at the unit costs ``costs``
    (the module's formula; a null count adds nothing; ``calls`` the other model
    callables' counts by name); None without costs or nfev."""
    if costs is None or not nfev:
        return None
    total = nfev * costs.rhs + sum(n * costs.others[name] for name, n in (calls or {}).items()
                                   if name in costs.others)
    if njev_model and costs.jac is not None:
        total += njev_model * costs.jac
    for count, cost in ((nlu, costs.lu), (nniter, costs.solve)):
        if count:
            if cost is None:   # factorizations of a matrix that was not measured
                return None
            total += count * cost
    return total


def overhead(cpu_s, work_s) -> float | None:
    """``cpu_s / work_s``: the code's CPU per unit of its method's work; None
    when either is missing or not positive."""
    if cpu_s is None or work_s is None or not (cpu_s > 0 and work_s > 0):
        return None
    return float(cpu_s) / float(work_s)


def case_work(record) -> float | None:
    """A case's work in CPU seconds (``record["work"]``), for a record, a store
    row or a DataFrame row; None (never a guess) when it was not measured: a
    record of code older than the field, a case that did not finish, an FMU.

    The figure to compare methods by where a source's claim is about the method
    rather than about the code that runs it; ``cpu_s`` stays the figure of what
    the code costs here, and ``record["overhead"]`` is their ratio."""
    try:
        value = record["work"]
    except (KeyError, IndexError):
        return None
    if value is None or value != value:   # null, or NaN in a DataFrame
        return None
    return float(value)
