"""The model checks of ``ibench check-plugin PROBLEM``: derivatives against
difference quotients, and the consistent start, at one built problem.

Each function takes a built problem and returns ``(passed, detail)``: ``passed``
None when the check does not apply to the problem. They run the problem's code
and are called in a forked process
(:func:`integrator_bench.harness.checks.problem_check.check_problem`).

A derivative ``A = df/dx`` is compared with central differences ``D`` of ``f``
with steps ``h_j = s max(1, |x_j|)``, ``s`` each of :data:`STEPS` in turn until one agrees
(:func:`compare`): an entry fails when
``|A_ij - D_ij|`` exceeds ``RELATIVE * (|A_ij| + FLOOR * max|A|)`` (relative to
the entry, with a floor relative to the whole matrix so that a problem at small
scales is judged at its own) plus the quotient's own uncertainty: how far it
moves when the step is doubled (its truncation, large for a fast drive, and the
round-off of a function whose terms cancel) and the round-off of differencing
``f``, ``100 eps S_i / h_j`` with ``S_i = |f_i| + sum_j |A_ij x_j|`` (the size
of the terms ``f_i`` sums). Above
:data:`SAMPLED_COLUMNS` unknowns, that many columns are compared: the first and
last :data:`EDGE_COLUMNS` and the others drawn with a fixed seed (:func:`_cols`).
A sparse matrix is never made dense (at 100,000 links the chain drive's mass
matrix would be 720 GB), and each formulation is formulated once for all the
checks of a problem (:func:`formulated`).
"""

from __future__ import annotations

import weakref

import numpy as np
import scipy.sparse as sp

from integrator_bench.problems.mechanical import MechanicalProblem

#: the relative steps tried, in turn: a model with a kink (a contact that opens or
#: closes) within the first step of the state checked agrees at a smaller one
STEPS = (1e-7, 1e-8, 1e-9)
RELATIVE = 1e-5
FLOOR = 1e-3
SAMPLED_COLUMNS = 40
#: of the sampled columns, this many at each end (:func:`_cols`)
EDGE_COLUMNS = 5
SEED = 58


def _columns(analytic, cols) -> np.ndarray:
    """The columns ``cols`` of a dense or sparse matrix, dense."""
    if sp.issparse(analytic):
        return sp.csc_matrix(analytic)[:, cols].toarray()
    return np.asarray(analytic, float)[:, cols]


def _cols(n: int) -> np.ndarray:
    """Every column, or :data:`SAMPLED_COLUMNS` of them: the first and the last
    :data:`EDGE_COLUMNS` (where a model's index arithmetic wraps or ends: a closed
    chain's corner block, coordinates appended after the repeated ones) and the
    rest drawn from between them with a fixed seed."""
    if n <= SAMPLED_COLUMNS:
        return np.arange(n)
    inner = np.random.default_rng(SEED).choice(n - 2 * EDGE_COLUMNS,
                                               SAMPLED_COLUMNS - 2 * EDGE_COLUMNS,
                                               replace=False) + EDGE_COLUMNS
    return np.sort(np.concatenate([np.arange(EDGE_COLUMNS), inner,
                                   np.arange(n - EDGE_COLUMNS, n)]))


def compare(label: str, fun, x, analytic) -> str | None:
    """None when ``analytic`` is ``d fun / dx`` at ``x`` by the rule of the module
    docstring at one of :data:`STEPS`; else one phrase naming the worst entry at the
    first."""
    x = np.asarray(x, float)
    analytic = analytic if sp.issparse(analytic) else np.atleast_2d(np.asarray(analytic, float))
    f0 = np.atleast_1d(np.asarray(fun(x), float))
    shape = (f0.size, x.size)
    if tuple(analytic.shape) != shape:
        return f"{label}: shape {tuple(analytic.shape)}, expected {shape}"
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(f0))):
        return f"{label}: the function is not finite at the state checked"
    flaws = []
    for step in STEPS:
        flaws.append(_compare_at(label, fun, x, f0, analytic, step))
        if flaws[-1] is None:
            return None
    return flaws[0]


def _compare_at(label, fun, x, f0, analytic, step) -> str | None:
    """:func:`compare` at the relative step ``step``."""
    cols = _cols(x.size)
    steps = step * np.maximum(1.0, np.abs(x))
    quotient = np.column_stack([_quotient(fun, x, j, steps[j]) for j in cols])
    coarse = np.column_stack([_quotient(fun, x, j, 2 * steps[j]) for j in cols])
    given = _columns(analytic, cols)
    terms = np.abs(f0) + abs(analytic) @ np.abs(x)
    allowed = (RELATIVE * (np.abs(given) + FLOOR * _largest(analytic)) + np.abs(quotient - coarse)
               + 100 * np.finfo(float).eps * terms[:, None] / steps[cols][None, :])
    wrong = ~(np.abs(given - quotient) <= allowed)     # a NaN anywhere is wrong
    if not wrong.any():
        return None
    with np.errstate(divide="ignore", invalid="ignore"):
        excess = np.where(wrong, np.abs(given - quotient) / allowed, 0.0)
    excess[wrong & ~(excess > 1.0)] = np.inf
    i, j = np.unravel_index(np.argmax(excess), excess.shape)
    return (f"{label}: entry ({i}, {cols[j]}) is {given[i, j]:.6g}, its difference "
            f"quotient {quotient[i, j]:.6g}")


def _quotient(fun, x, j, step) -> np.ndarray:
    e = np.zeros(x.size)
    e[j] = step
    return (np.atleast_1d(np.asarray(fun(x + e), float))
            - np.atleast_1d(np.asarray(fun(x - e), float))) / (2 * step)


def _largest(matrix) -> float:
    values = matrix.data if sp.issparse(matrix) else np.asarray(matrix, float)
    return float(np.max(np.abs(values), initial=0.0))


def _times(matrix, x) -> np.ndarray:
    """``matrix @ x`` for a dense or a sparse matrix, never densified (a sparse
    mechanism's mass matrix of 300,000 coordinates would not fit in memory)."""
    return np.asarray(matrix @ x, float).ravel()


def _verdict(flaws: list, passed_text: str) -> tuple[bool, str]:
    return (not flaws, "; ".join(flaws) or passed_text)


def _state(system, rng) -> tuple:
    """A time inside the span and a state (and derivative) near the start."""
    t = system.t0 + 0.3 * (system.t_end - system.t0)
    y = system.y0 * (1 + 0.01 * rng.standard_normal(system.n)) \
        + 0.01 * system.atol_scale * rng.standard_normal(system.n)
    yp = getattr(system, "yp0", None)
    if yp is not None:
        yp = yp + 0.01 * np.maximum(np.abs(yp), 1.0) * rng.standard_normal(system.n)
    return t, y, yp


def _form_jacobian(form, system, rng) -> str | None:
    t, y, yp = _state(system, rng)
    if system.kind == "ode":
        return compare(form, lambda x: system.fun(t, x), y, system.jac(t, y))
    cj = 7.0
    return compare(form, lambda x: system.residual(t, x, yp + cj * (x - y)), y,
                   system.jac(t, y, yp, cj))


#: each checked problem's systems, formulated once for all the checks of one problem
_SYSTEMS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def formulated(problem, form: str):
    """``problem.formulate(form)``, once per problem and formulation for all the
    checks (``jacobian`` and ``start`` both need every one: the chain drive's
    partitioning chooses its coordinates in a minute at 100,000 links)."""
    try:
        systems = _SYSTEMS.setdefault(problem, {})
    except TypeError:                        # a problem that is not hashable
        return problem.formulate(form)
    if form not in systems:
        systems[form] = problem.formulate(form)
    return systems[form]


def jacobian(problem) -> tuple[bool | None, str]:
    """Each formulation's analytic Jacobian (an ODE's ``jac(t, y)``, a DAE's
    ``jac(t, y, yp, cj)``) against difference quotients of its right-hand side
    or residual, at a state near the start."""
    flaws, checked = [], []
    for form in problem.formulations:
        system = formulated(problem, form)
        if system.unsupported or getattr(system, "jac", None) is None:
            continue
        checked.append(form)
        flaw = _form_jacobian(form, system, np.random.default_rng(SEED))
        flaws += [flaw] if flaw else []
    if not checked:
        return None, "no formulation gives an analytic Jacobian"
    return _verdict(flaws, f"{', '.join(checked)}: agree with difference quotients")


def _point(problem) -> tuple:
    """``(t, q, v, a, lam)`` near the consistent start, at a time inside the span."""
    rng = np.random.default_rng(SEED)
    q0, v0, _, _ = problem.consistent_start()
    t0, t1 = problem.t_span
    return (t0 + 0.3 * (t1 - t0),
            q0 + 0.01 * problem.position_scale * rng.standard_normal(problem.nq),
            v0 + 0.1 * problem.velocity_scale * rng.standard_normal(problem.nq),
            problem.velocity_scale * rng.standard_normal(problem.nq),
            problem.lambda_scale * rng.standard_normal(problem.nc))


def _not_constrained(problem) -> str | None:
    if not isinstance(problem, MechanicalProblem):
        return "not a constrained mechanical problem"
    return None if problem.nc else "no constraints"


def constraint_jac(problem) -> tuple[bool | None, str]:
    """G = dg/dq against difference quotients of g in q."""
    why = _not_constrained(problem)
    if why:
        return None, why
    t, q, *_ = _point(problem)
    at = problem.at(t)
    flaw = compare("G", lambda x: problem.constraint(x, *at), q, problem.constraint_jac(q, *at))
    return _verdict([flaw] if flaw else [], "G agrees with difference quotients of g in q")


def constraint_t(problem) -> tuple[bool | None, str]:
    """g_t against difference quotients of g in t (a driven problem)."""
    why = _not_constrained(problem) or (None if problem.driven else
                                        "constraints do not depend on time (driven = False)")
    if why:
        return None, why
    t, q, *_ = _point(problem)
    flaw = compare("g_t", lambda s: problem.constraint(q, s[0]), np.array([t]),
                   np.asarray(problem.constraint_t(q, t), float)[:, None])
    return _verdict([flaw] if flaw else [], "g_t agrees with difference quotients of g in t")


def _model_pairs(p, t, q, v, a, lam) -> list[tuple]:
    """``(label, function, x, analytic derivative)`` of the mechanical model."""
    at = p.at(t)
    pairs = [("force_q", lambda x: p.force(t, x, v), q, p.force_q(t, q, v)),
             ("force_v", lambda x: p.force(t, q, x), v, p.force_v(t, q, v)),
             ("mass_q", lambda x: _times(p.mass(x), a), q, p.mass_q(q, a))]
    if p.nc:
        pairs += [("gv_q", lambda x: p.constraint_jac(x, *at) @ v, q, p.gv_q(q, v, *at)),
                  ("gt_q", lambda x: p.constraint_jac(x, *at).T @ lam, q, p.gt_q(q, lam, *at))]
    if p.nc and p.driven:
        pairs += [("G_t", lambda x: p.constraint_t(x, t), q, p.constraint_jac_t(q, t)),
                  ("accel_term", lambda s: p.velocity_constraint(t + s[0], q + s[0] * v, v),
                   np.zeros(1), np.asarray(p.accel_term(q, v, t), float)[:, None])]
    return pairs


def derivatives(problem) -> tuple[bool | None, str]:
    """The mechanical model's other derivatives against difference quotients:
    ``force_q``, ``force_v``, ``mass_q``, ``gv_q``, ``gt_q``; for a driven problem
    ``G_t`` (of g_t in q) and the acceleration term (the time derivative of
    ``G v + g_t`` along ``q' = v``, ``v' = 0``); otherwise ``accel_term`` equal
    to ``gv_q v``."""
    if not isinstance(problem, MechanicalProblem):
        return None, "not a mechanical problem"
    t, q, v, a, lam = _point(problem)
    pairs = _model_pairs(problem, t, q, v, a, lam)
    flaws = [f for f in (compare(*pair) for pair in pairs) if f]
    if problem.nc and not problem.driven:
        term, product = problem.accel_term(q, v), _times(problem.gv_q(q, v), v)
        if not np.allclose(term, product, rtol=1e-10, atol=1e-12 * max(1.0, _largest(product))):
            flaws.append("accel_term differs from gv_q v")
    return _verdict(flaws, f"{', '.join(p[0] for p in pairs)} agree with difference quotients")


def _tight(value, scale, tol=1e-9) -> bool:
    return bool(np.all(np.isfinite(value))) and float(np.max(np.abs(value), initial=0.0)) \
        <= tol * max(1.0, scale)


def _form_start(form, system) -> str | None:
    """Why ``system``'s start is not usable: not finite, or a DAE residual not zero."""
    if not np.all(np.isfinite(system.y0)):
        return f"{form}: the initial state is not finite"
    if system.kind == "ode":
        f = np.asarray(system.fun(system.t0, system.y0), float)
        return None if np.all(np.isfinite(f)) else f"{form}: f(t0, y0) is not finite"
    if system.kind != "dae":
        return None
    r = np.asarray(system.residual(system.t0, system.y0, system.yp0), float)
    scale = max(float(np.max(np.abs(system.y0), initial=0)),
                float(np.max(np.abs(system.yp0), initial=0)))
    return None if _tight(r, scale) else \
        f"{form}: residual at the start {float(np.max(np.abs(r))):.3g}"


def start(problem) -> tuple[bool | None, str]:
    """The initial state is consistent: every formulation's start finite, each
    DAE's residual zero there (to 1e-9 of the state's size), and the position and
    velocity constraint residuals of a constrained problem zero (to 1e-10)."""
    flaws, done = [], "finite in every formulation, DAE residuals zero"
    for form in problem.formulations:
        system = formulated(problem, form)
        flaw = None if system.unsupported else _form_start(form, system)
        flaws += [flaw] if flaw else []
    y0 = np.asarray(problem.initial_state(), float)
    drift = problem.constraint_residuals(np.array([problem.t_span[0]]), y0[None, :])
    if drift is not None:
        (pos,), (vel,) = drift
        done = f"constraint residuals {pos:.2g} (positions), {vel:.2g} (velocities); {done}"
        if not (_tight(pos, np.max(np.abs(y0)), 1e-10) and _tight(vel, np.max(np.abs(y0)), 1e-10)):
            flaws.append(f"constraint residuals at the start {pos:.3g} (positions), "
                         f"{vel:.3g} (velocities)")
    return _verdict(flaws, done)


#: the model checks, in the order of their lines
CHECKS = (("jacobian", jacobian), ("constraint_jac", constraint_jac),
          ("constraint_t", constraint_t), ("derivatives", derivatives), ("start", start))
