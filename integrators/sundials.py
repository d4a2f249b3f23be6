"""SUNDIALS CVODE (BDF and Adams) and IDA through scikit-sundae.

The solvers are advanced one internal step at a time (``step(..., 'onestep')``)
so that accepted steps are counted exactly; output times are then reached in
``'normal'`` mode, which interpolates with the method's own Nordsieck array or
divided differences without stepping past the last internal step. A ``tstop``
at the final time keeps the solvers from evaluating beyond it.

scikit-sundae 1.2 exposes ``nfev`` and ``njev`` only (SUNDIALS' nfev leaves out
finite-difference Jacobian calls, which the harness counts itself); rejected
steps, LU factorizations and Newton statistics are left unknown.

Sparse systems. A system that names its Jacobian structure
(``jac_sparsity``), or one larger than
:data:`~integrator_bench.integrators.sparse.DENSE_LIMIT` whose ``jac``
returns a ``scipy.sparse`` matrix (one evaluation at the start, counted in
``njev``, shows its structure), runs with SUNDIALS' sparse direct solver
SuperLU_MT (``linsolver="sparse"``, one thread; the installed scikit-sundae
1.2.0 is built against SUNDIALS 7.9.0 with SuperLU_MT enabled) on that
structure plus the diagonal. ``jac`` then fills the ``nnz`` values of the
structure (never a dense array); without ``jac``, scikit-sundae's grouped
difference quotients on the structure are used. scikit-sundae's banded solver
is not used: with a Python ``jacfn`` it allocates a dense ``n x n`` array.
scikit-sundae 1.1.1 replaced a user ``jacfn`` by its difference quotients
when ``sparsity`` was given (scikit-sundae issue #46); 1.2.0 keeps the
user's ``jacfn`` (``_cy_cvode.pyx``/``_cy_ida.pyx`` set the quotients only
when ``jacfn`` is None) and warns, wrongly, that it ignores the quotients; the
warning is silenced here.

Large sparse systems (``KRYLOV_MIN`` states and more, with ``jac``) take
SPGMR instead, preconditioned with SuperLU's LU (COLAMD) of the Newton matrix
(:class:`_IdaKrylov`, :class:`_CvodeKrylov`; ``nlu`` and ``njev`` are then
those factorizations and their Jacobians): SuperLU_MT's fill on the chain's
matrices exceeds its preallocated storage and aborts the process (300 links),
and scikit-sundae sets neither its ordering nor its ``sp_ienv``.

Accepted steps are the distinct times of the ``'onestep'`` returns: after a
``'normal'`` return SUNDIALS hands the last internal step back once more
without taking one (``IDASolve``/``CVode`` in one-step mode), which was once
counted as a step.

State events go to SUNDIALS' root finding (``CVodeRootInit``/``IDARootInit``
through scikit-sundae's ``eventsfn``, with each event's direction; see
:class:`_Roots`). After a reset a fresh solver starts from the reset state; IDA
then computes the consistent ``y'`` (and algebraic variables) itself
(``calc_initcond="yp0"``, ``IDACalcIC``), which holds for index 0 and 1 only.

References: Hindmarsh et al., "SUNDIALS: Suite of nonlinear and
differential/algebraic equation solvers", ACM TOMS 31 (2005) 363-396;
Gardner et al., ACM TOMS 48 (2022) 31.
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.sparse as sp
from sksundae import cvode, ida

from integrator_bench.integrators.base import Integrator, Solution
from integrator_bench.integrators.driver import act
from integrator_bench.integrators.sparse import DENSE_LIMIT, factor, on_pattern, pattern
from integrator_bench.problems.base import dense

MAX_STEPS = 100_000  # per output interval
EXCLUDED_ATOL = 1e10  # absolute tolerance that keeps a variable out of IDA's error test
#: from this many states on, a sparse system with an analytic ``jac`` is solved by
#: SPGMR preconditioned with SuperLU's LU of the Newton matrix (:class:`_IdaKrylov`,
#: :class:`_CvodeKrylov`) instead of SuperLU_MT; below, SuperLU_MT as before
KRYLOV_MIN = 500


ROOT_RETURN = 2  # CV_ROOT_RETURN = IDA_ROOT_RETURN: the solver returned at a root of eventsfn


class _Roots:
    """SUNDIALS' root finding on ``system.events`` through scikit-sundae's
    ``eventsfn``, with each event's ``direction``, and the action at a root.

    scikit-sundae's ``terminal`` option acts in its ``solve`` only: in step
    mode the solver returns at every root (status 2, the state interpolated
    at the root; SUNDIALS locates it to about ``100 eps |t|`` by its Illinois
    iteration and returns the end past the sign change, and a function
    exactly zero at a (re)start is not a root there). So every ``terminal``
    is False here and the action is the driver's one rule
    (:func:`~integrator_bench.integrators.driver.act`):
    record a non-terminal event, stop at a terminal one without reset, and
    restart a fresh solver (``restart(t, y_after, res) -> (solver, first)``,
    set by the integrator) after a reset; a reset returning None ignores
    the root.
    """

    def __init__(self, events, dae):
        self.events, self.log, self.stopped, self.restart = tuple(events), [], False, None
        self.nfev = self.njev = 0         # of the solvers before a restart
        values = [e.value for e in self.events]
        if dae:
            def fn(t, y, yp, out):
                out[:] = [v(t, y) for v in values]
        else:
            def fn(t, y, out):
                out[:] = [v(t, y) for v in values]
        self.fn = fn

    def options(self) -> dict:
        self.fn.terminal = [False] * len(self.events)
        self.fn.direction = [int(e.direction) for e in self.events]
        return {"eventsfn": self.fn, "num_events": len(self.events)}

    def act(self, res):
        """``(t, y_after)`` for a root acted on (``y_after`` None: stop), or None
        (:func:`~integrator_bench.integrators.driver.act` for each event found)."""
        t, y = float(res.t), np.array(res.y, dtype=float)
        for i in np.flatnonzero(res.i_events[-1]):
            ends, y_after = act(self.events[i], t, y, self.log)
            if ends:
                self.stopped = y_after is None
                return t, y_after
        return None


def _interpolated(solver, tout, t_end, t_root):
    """The state at ``tout`` behind the solver's last step, by its interpolant.

    The first call after a root return may hand back the same root again
    (SUNDIALS checks the last root's neighbourhood before anything else; seen
    where the event function sits within round-off of zero at the root): that
    answer is not the output, so ask once more.
    """
    for _ in range(3):
        res = solver.step(tout, method="normal", tstop=t_end)
        if not (res.status == ROOT_RETURN and float(res.t) <= t_root):
            return res.y
    raise RuntimeError(f"the solver keeps returning the root at t = {t_root:.17g} "
                       f"when asked for the output at t = {tout:.17g}")


def _drive(solver, system, first, roots=None):
    """Step ``solver`` over ``system.t_eval``, acting on the roots of ``roots``
    (a :class:`_Roots`); return (ys, reached, nsteps, result, message)."""
    t_eval = system.t_eval
    ys = np.empty((t_eval.size, system.n))
    ys[0] = system.y0
    res = first
    if not res.success:
        return ys, 1, 0, res, res.message
    t = t_last = system.t0       # the time reached, the last internal step
    t_root = -np.inf             # the last root returned
    nsteps, i = 0, 1
    while i < t_eval.size:
        tout = t_eval[i]
        normal = t >= tout
        res = solver.step(tout, method="normal" if normal else "onestep", tstop=system.t_end)
        if not res.success:
            return ys, i, nsteps, res, res.message
        if roots is not None and res.status == ROOT_RETURN:
            t = max(t, float(res.t))
            if float(res.t) <= t_root:
                # handed back again: after a 'normal' output behind the root, SUNDIALS
                # searches (tout, tn] once more and finds the same root
                continue
            t_root = float(res.t)
            action = roots.act(res)
            if action is None:
                continue
            t_ev, y_after = action
            while i < t_eval.size and t_eval[i] <= t_ev:      # outputs up to the root
                ys[i] = res.y if t_eval[i] == t_ev else _interpolated(
                    solver, t_eval[i], system.t_end, t_root)
                i += 1
            if y_after is None:
                return ys, i, nsteps, res, ""
            if system.t_end - t_ev <= 1e-12 * (system.t_end - system.t0):  # reset at t_end
                ys[i:] = y_after
                return ys, t_eval.size, nsteps, res, ""
            roots.nfev, roots.njev = roots.nfev + int(res.nfev), roots.njev + int(res.njev)
            solver, res = roots.restart(t_ev, y_after, res)
            if not res.success:
                return ys, i, nsteps, res, res.message
            t = t_last = t_ev
            continue
        if normal:
            ys[i] = res.y
            i += 1
            continue
        t = float(res.t)
        if t > t_last:  # a new internal step, not the last one handed back again
            nsteps += 1
            t_last = t
    return ys, t_eval.size, nsteps, res, ""


def _structure(system, jac_at_start):
    """``(P, probes)``: the CSC structure (with the diagonal) for SUNDIALS' sparse
    solver, or None for the dense one, and the ``jac`` evaluations spent on it."""
    structure = getattr(system, "jac_sparsity", None)
    if structure is None and system.jac is not None and system.n > DENSE_LIMIT:
        J0 = jac_at_start()
        return (pattern(J0) if sp.issparse(J0) else None), 1
    return (None if structure is None else pattern(structure)), 0


def _sparse_options(options, P):
    """Switch ``options`` to SuperLU_MT on the structure ``P``."""
    options.update(linsolver="sparse", sparsity=P, nthreads=1)


def _krylov(system, P) -> bool:
    """Whether ``system`` (sparse structure ``P``, or None) takes the Krylov path."""
    return P is not None and system.jac is not None and system.n >= KRYLOV_MIN


class _IdaKrylov:
    """IDA's Newton systems by SPGMR with the exact preconditioner: SuperLU's LU.

    ``setup`` (IDA's preconditioner setup, called where the direct solvers
    would form and factor their matrix) evaluates ``J = dF/dy + cj dF/dy'``
    (one ``jac`` call, ``njev``) and factors it with
    :func:`~integrator_bench.integrators.sparse.factor` (SuperLU, COLAMD
    column order, ``nlu``). Between setups IDA's ``cj`` changes; its direct
    solvers then scale the correction by ``2 / (1 + cj / cj_setup)`` (IDA's
    ``idaLsSolve``, "scale the correction to account for change in cj"). The
    same is done here: the product ``jtimes`` applies ``(1 + r) / 2 J`` and
    the preconditioner ``2 / (1 + r) J^-1`` with ``r = cj / cj_setup``, so
    the preconditioned operator is the identity, SPGMR stops after one
    iteration, and the Newton iteration is that of IDA's direct solvers on
    the same matrix: no residual is spent on difference quotients, and
    SuperLU_MT, whose fill on these matrices exceeds its preallocated
    storage and aborts the process (chain_drive from 300 links), is not used.
    A singular ``J`` gives a NaN correction (the step is retried smaller).
    """

    def __init__(self, jac):
        self.jac, self.J, self.lu, self.cj = jac, None, None, 1.0
        self.njev = self.nlu = 0

    def setup(self, t, y, yp, res, cj):
        self.J = sp.csc_matrix(self.jac(t, y, yp, cj))
        self.njev += 1
        self.lu, self.cj = factor(self.J), cj
        self.nlu += 1

    def _ratio(self, cj):
        return 0.5 * (1.0 + cj / self.cj)

    def solve(self, t, y, yp, res, rvec, zvec, cj, delta):
        zvec[:] = self.lu(rvec) / self._ratio(cj)

    def jtimes(self, t, y, yp, res, v, Jv, cj):
        Jv[:] = self._ratio(cj) * (self.J @ v)

    def options(self):
        return dict(linsolver="gmres", krylov_dim=5,
                    precond=ida.IDAPrecond(self.setup, self.solve),
                    jactimes=ida.IDAJacTimes(None, self.jtimes))


class _CvodeKrylov:
    """CVODE's Newton systems ``(I - gamma J) x = b`` by SPGMR, preconditioned
    with SuperLU's LU of ``I - gamma J``.

    ``setup`` evaluates ``J`` (``njev``) unless CVODE allows the last one
    (``jok``), and factors ``I - gamma J`` (``nlu``); ``jtimes`` gives
    ``J v`` with that ``J``, so SPGMR solves the modified-Newton system of
    CVODE's direct solvers; where ``gamma`` has moved since the factorization,
    it takes a few iterations instead of one.
    """

    def __init__(self, jac, n):
        self.jac, self.n, self.J, self.lu = jac, n, None, None
        self.njev = self.nlu = 0

    def setup(self, t, y, yp, jok, jnew, gamma):
        if jok and self.J is not None:
            jnew[0] = 0
        else:
            self.J = sp.csc_matrix(self.jac(t, y))
            self.njev += 1
            jnew[0] = 1
        self.lu = factor((sp.identity(self.n, format="csc") - gamma * self.J).tocsc())
        self.nlu += 1

    def solve(self, t, y, yp, rvec, zvec, gamma, delta, lr):
        zvec[:] = self.lu(rvec)

    def jtimes(self, t, y, yp, v, Jv):
        Jv[:] = self.J @ v

    def options(self):
        return dict(linsolver="gmres", krylov_dim=5,
                    precond=cvode.CVODEPrecond(self.setup, self.solve),
                    jactimes=cvode.CVODEJacTimes(None, self.jtimes))


class _OnPattern:
    """``jacfn``'s values on the structure ``P``. A Jacobian with a non-zero
    outside ``P`` is not raised through SUNDIALS (an exception inside its
    callback left scikit-sundae's memory corrupt in our runs: ``munmap_chunk():
    invalid pointer`` at exit): the values are NaN, so the step fails, and
    :attr:`error` says why."""

    def __init__(self, P):
        self.P, self.error = P, ""

    def __call__(self, J, JJ):
        try:
            JJ[:] = on_pattern(J, self.P)
        except ValueError as exc:
            self.error = str(exc)
            JJ[:] = np.nan


def _counts(res, nsteps, probes, krylov):
    """The run's counters: SUNDIALS' ``nfev``, and ``njev`` plus the structure
    probes; on the Krylov path ``njev`` and ``nlu`` are the preconditioner's
    (SUNDIALS counts no Jacobian evaluation there)."""
    counts = {"nsteps": nsteps, "nfev": int(res.nfev), "njev": int(res.njev) + probes}
    if krylov is not None:
        counts.update(njev=krylov.njev + probes, nlu=krylov.nlu)
    return counts


def _solution(system, ys, reached, message, counts, roots):
    """The :class:`Solution`, with the events of ``roots`` (None: no events) and
    the counts of the solvers before the restarts."""
    done = reached == system.t_eval.size
    events = []
    if roots is not None:
        events = roots.log
        counts.update(nfev=counts["nfev"] + roots.nfev, nevents=len(events))
        if "nlu" not in counts:
            counts["njev"] += roots.njev
        if roots.stopped:
            done, message = True, (f"stopped by the terminal event {events[-1][1]!r} "
                                   f"at t={events[-1][0]:.9g}")
    return Solution(system.t_eval[:reached], ys[:reached], done, str(message or ""), counts,
                    events=events)


def _make(solver_class, fn, options):
    """The solver, without scikit-sundae's misleading warning that a user ``jacfn``
    replaces its sparse difference quotients (it does, as intended)."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Custom sparse Jacobian approximation")
        return solver_class(fn, **options)


class Cvode(Integrator):
    """CVODE: variable-order, variable-step linear multistep methods."""

    method = "BDF"
    accepts = frozenset({"ode"})
    events = True

    def solve(self, system, *, rtol=None, atol=None, h=None):
        fun, jac = system.fun, system.jac

        def rhsfn(t, y, yp):
            yp[:] = fun(t, y)

        options = dict(method=self.method, rtol=rtol, atol=np.broadcast_to(atol, (system.n,)),
                       max_num_steps=MAX_STEPS)
        P, probes = _structure(system, lambda: jac(system.t0, system.y0))
        fill = krylov = None
        if _krylov(system, P):
            krylov = _CvodeKrylov(jac, system.n)
            options.update(krylov.options())
        elif P is not None:
            _sparse_options(options, P)
        if krylov is None and self.uses_jacobian and jac is not None:
            if P is None:
                def jacfn(t, y, yp, JJ):
                    JJ[:, :] = dense(jac(t, y))
            else:
                fill = _OnPattern(P)

                def jacfn(t, y, yp, JJ):
                    fill(jac(t, y), JJ)
            options["jacfn"] = jacfn
        roots = None
        if system.events:
            roots = _Roots(system.events, dae=False)
            options.update(roots.options())

            def restart(t, y, res):
                new = _make(cvode.CVODE, rhsfn, options)
                return new, new.init_step(t, y)

            roots.restart = restart
        solver = _make(cvode.CVODE, rhsfn, options)
        first = solver.init_step(system.t0, system.y0)
        ys, reached, nsteps, res, message = _drive(solver, system, first, roots)
        if fill is not None and fill.error:
            message = f"{fill.error}: {message}"
        counts = _counts(res, nsteps, probes, krylov)
        return _solution(system, ys, reached, message, counts, roots)


class CvodeBDF(Cvode):
    name = "cvode-bdf"
    description = "SUNDIALS CVODE, variable-order BDF (1-5) with Newton and dense LU"
    reference = "Hindmarsh et al., ACM TOMS 31 (2005) 363-396"
    method = "BDF"
    implicit = True
    uses_jacobian = True


class CvodeAdams(Cvode):
    name = "cvode-adams"
    description = "SUNDIALS CVODE, variable-order Adams-Moulton (1-12) with Newton"
    reference = "Hindmarsh et al., ACM TOMS 31 (2005) 363-396"
    method = "Adams"
    implicit = True
    uses_jacobian = True


class IDA(Integrator):
    """IDA on DAEs up to index 3, with the variables outside ``system.error_mask``
    kept out of the local error test.

    SUNDIALS' own switch for this, ``IDASetSuppressAlg``, is not exposed by
    scikit-sundae 1.2, and its C memory pointer is private to the Cython
    object, so the C library cannot be reached for it. Instead those variables
    get an absolute tolerance of ``EXCLUDED_ATOL``, so their error weight
    ``1 / (rtol |y| + atol)`` is negligible, the classic alternative the seed
    report used ("high ATOL"; Brenan, Campbell, Petzold 1996, sect. 5.4). The
    trade-off: IDA's Newton convergence test uses the same weights, so those
    variables (index-2/3 multipliers, index-3 velocities) converge only as far
    as the controlled ones need; their values carry larger errors, which the
    harness measures separately (err_vel, err_lambda).
    """

    name = "ida"
    description = "SUNDIALS IDA, variable-order BDF (1-5) for implicit DAEs up to index 3"
    reference = "Hindmarsh et al., ACM TOMS 31 (2005) 363-396; Brenan, Campbell, Petzold (1996)"
    accepts = frozenset({"dae"})
    max_index = 3
    implicit = True
    uses_jacobian = True
    events = True

    def solve(self, system, *, rtol=None, atol=None, h=None):
        residual, jac = system.residual, system.jac

        def resfn(t, y, yp, res):
            res[:] = residual(t, y, yp)

        atol = np.array(np.broadcast_to(atol, (system.n,)), dtype=float)
        atol[~system.error_mask] = EXCLUDED_ATOL
        options = dict(rtol=rtol, atol=atol, max_num_steps=MAX_STEPS)
        if system.algebraic.any():
            options["algebraic_idx"] = np.flatnonzero(system.algebraic)
        P, probes = _structure(system, lambda: jac(system.t0, system.y0, system.yp0, 1.0))
        fill = krylov = None
        if _krylov(system, P):
            krylov = _IdaKrylov(jac)
            options.update(krylov.options())
        elif P is not None:
            _sparse_options(options, P)
        if krylov is None and jac is not None:
            if P is None:
                def jacfn(t, y, yp, res, cj, JJ):
                    JJ[:, :] = dense(jac(t, y, yp, cj))
            else:
                fill = _OnPattern(P)

                def jacfn(t, y, yp, res, cj, JJ):
                    fill(jac(t, y, yp, cj), JJ)
            options["jacfn"] = jacfn
        roots = None
        if system.events:
            roots = _Roots(system.events, dae=True)
            options.update(roots.options())

            def restart(t, y, res):
                # y' after a reset is unknown: IDACalcIC finds it (and the algebraic
                # variables) from the reset state, with y' at the root as the guess
                new = _make(ida.IDA, resfn, dict(options, calc_initcond="yp0",
                                                 calc_init_dt=system.t_end - t))
                return new, new.init_step(t, y, np.array(res.yp, dtype=float))

            roots.restart = restart
        solver = _make(ida.IDA, resfn, options)
        first = solver.init_step(system.t0, system.y0, system.yp0)
        ys, reached, nsteps, res, message = _drive(solver, system, first, roots)
        if fill is not None and fill.error:
            message = f"{fill.error}: {message}"
        counts = _counts(res, nsteps, probes, krylov)
        return _solution(system, ys, reached, message, counts, roots)
