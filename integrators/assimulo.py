"""Assimulo's solvers: SUNDIALS CVODE and IDA with every counter, RODAS, DOPRI5,
RungeKutta34 and ODEPACK's LSODAR (RADAU5 in :mod:`.assimulo_radau5`).

Assimulo (Modelon AB, LGPL-3.0; Andersson, Fuehrer, Akesson, "Assimulo: A unified
framework for ODE solvers", Math. Comput. Simul. 116 (2015) 26-43) wraps these
codes behind one interface: a problem (``Explicit_Problem(rhs, y0, t0)`` for
``y' = f(t, y)``, ``Implicit_Problem(res, y0, yd0, t0)`` for ``F(t, y, y') = 0``)
and a solver whose ``simulate(t_end)`` runs it. Modelon publishes its current
releases as the distribution ``assimulo-testing`` (the optional extra
``[assimulo]``; 3.9.0b2 bundles SUNDIALS 2.7.0, where scikit-sundae has 7.9);
without it this module does not import and the registry lists these integrators
as absent.

How a system is handed over (:func:`_callbacks`, one hand-over for both solves): an
ODE as ``Explicit_Problem`` with ``rhs = fun`` and, when the system has one and the
code uses it, ``jac`` (dense); a DAE as ``Implicit_Problem`` with ``res = residual``
and ``jac(c, t, y, yd) = dF/dy + c dF/dy'``, the system's iteration matrix. A system above
:data:`~integrator_bench.integrators.sparse.DENSE_LIMIT` states with a sparse
Jacobian is declined (``METHOD_LIMIT``): the dense linear solvers used here would
densify it (base.py rule 6).

How a run is fed to the segment runner
(:class:`~integrator_bench.integrators.driver.Segments`): with
``report_continuously`` Assimulo hands every accepted step to the problem's
``handle_result``, which passes it on with the solver's own interpolant
(:meth:`Segments.step`: outputs, their interpolation); the roots Assimulo finds
(SUNDIALS' and ODEPACK's root finding, Assimulo's locator on the dense output
of the Hairer codes) reach ``handle_event``, which passes them to
:meth:`Segments.roots` (``directions=False``: Assimulo's roots carry no direction,
so the runner keeps those crossed in each event's ``direction``; then the one
action rule: record, stop, reset). The runner also ends the run at a step to a
non-finite state (``finite=True``: RODAS accepts a NaN error estimate and runs
on). A stop or a reset ends ``simulate`` by the runner's exception, raised
from Python (never through a Fortran callback); after a reset a fresh solver
starts from the reset state, a DAE's ``y'`` and algebraic variables made
consistent by IDACalcIC (``make_consistent``), which only IDA offers.

IDA on index-2 and 3 DAEs runs with ``suppress_alg`` and ``algvar`` set to the
system's ``error_mask`` (``IDASetSuppressAlg``, ``IDASetId``): the variables
outside it (index-3 velocities, multipliers) are left out of the local error
test, not out of the Newton convergence test as the large absolute tolerance
of the scikit-sundae wrapper leaves them (:mod:`integrator_bench.integrators.sundials`).

Counters: Assimulo's ``statistics`` are mapped by :data:`STATS`; ``nfev`` is
``nfcns`` plus ``nfcnjacs`` (the calls of difference-quotient Jacobians, also
kept as ``nfev_jac``). A key a solver does not keep stays out (``nreject`` of
RungeKutta34, ``nniter`` of RODAS). CVODE's ``nlsred`` (order reductions by
its stability-limit detection, STALD) is kept beside them.

Timing: :meth:`AssimuloIntegrator.timed_solve` runs ``simulate`` over the
output times on the bare system, without the feed (rule 8 of
:mod:`~integrator_bench.integrators.base`). Both solves take their callbacks from
:func:`_callbacks` and their solver from :meth:`AssimuloIntegrator.configured`,
so they cannot differ in settings, tolerances or Jacobian.

Assimulo prints to standard output: ``verbosity`` 50 and no progress display
silence it (the Fortran codes' own lines on a failure, such as "EXIT OF
RADAU5", are written by the Fortran runtime and not reached). Failures are
typed from the flags its exceptions carry (:func:`_status`).
"""

from __future__ import annotations

import re

from collections import Counter
from importlib import metadata

import numpy as np
from assimulo import solvers
from assimulo.exception import AssimuloException
from assimulo.problem import Explicit_Problem, Implicit_Problem
from assimulo.solvers.sundials import CVodeError, IDAError

from integrator_bench.integrators.base import Integrator, Solution, Status, TimedCall, StepFailure
from integrator_bench.integrators.driver import Segments, ended_short, nonfinite
from integrator_bench.integrators import library_call
from integrator_bench.integrators import settings as _settings
from integrator_bench.integrators.settings import MAX_STEP, MAX_STEPS, Setting, max_order
from integrator_bench.integrators.sparse import DENSE_LIMIT, dense
from integrator_bench.integrators.sundials import CVODE_FAILURES, IDA_FAILURES

SILENT = 50               # Assimulo's verbosity: nothing printed
FIRST_STEP = 1e-3         # IDA's first step after a failed start, relative to the span
#: Assimulo's statistics -> the record's counters
STATS = {"nsteps": "nsteps", "nerrfails": "nreject", "nniters": "nniter",
         "nnfails": "nnfail", "nlus": "nlu", "njacs": "njev", "nlsred": "nlsred"}
#: Hairer's IDID (RADAU5's, DOPRI5's, RODAS's) -> Status
HAIRER_FLAGS = {-2: Status.MAX_STEPS, -3: Status.STEP_SIZE_UNDERFLOW,
                -4: Status.NEWTON_FAILURE}


def _status(exc, solver) -> Status:
    """The :class:`Status` of an Assimulo failure of ``solver``: ``MAX_STEPS`` when it
    has taken its ``maxsteps``, else from the flag the exception carries
    (``CVodeError``/``IDAError``: SUNDIALS' return flag, typed by the tables of
    :mod:`~integrator_bench.integrators.sundials`; ``Radau5Error``: RADAU5's
    IDID); any other is ``SOLVER_FAILURE``."""
    if "maxsteps" in solver.options and solver.statistics["nsteps"] >= solver.maxsteps:
        return Status.MAX_STEPS
    flag = getattr(exc, "value", None)
    table = {CVodeError: CVODE_FAILURES, IDAError: IDA_FAILURES,
             solvers.radau5.Radau5Error: HAIRER_FLAGS}.get(type(exc), {})
    if type(exc) is Exception:   # RODAS, DOPRI5: the IDID only in "... failed with flag -3"
        match = re.search(r"failed with flag (-?\d+)", str(exc))
        flag, table = (int(match.group(1)) if match else None), HAIRER_FLAGS
    return table.get(flag, Status.SOLVER_FAILURE)


def _same(a, b) -> bool:
    """Whether two of Assimulo's option values are equal (arrays element-wise)."""
    try:
        return bool(np.array_equal(np.asarray(a), np.asarray(b)))
    except (TypeError, ValueError):
        return a == b


def counts_of(statistics) -> dict:
    """The record's counters from an Assimulo ``Statistics`` (keys it never used
    hold -1 there and are left out)."""
    raw = {k: int(v) for k, v in statistics.statistics.items() if v != -1}
    counts = {STATS[k]: v for k, v in raw.items() if k in STATS}
    if "nfcns" in raw:
        counts["nfev"] = raw["nfcns"] + raw.get("nfcnjacs", 0)
    if "nfcnjacs" in raw:
        counts["nfev_jac"] = raw["nfcnjacs"]   # of them, for difference-quotient Jacobians
    return counts


class _Feed:
    """The problem's callbacks that feed the segment runner.

    ``handle_result`` (called by Assimulo after every accepted step, with
    ``report_continuously``) hands the step ``[t_last, t]`` and the solver's
    interpolant to :meth:`Segments.step` (which ends the run at a non-finite
    state); ``handle_event`` hands the roots that Assimulo found to
    :meth:`Segments.roots`, which keeps those crossed in their event's
    ``direction``, acts on them and ends the segment at a stop or a reset (its
    exception leaves ``simulate`` from Python code, never through a Fortran
    callback).
    """

    def __init__(self, system, segments):
        self.system, self.segments, self.calls = system, segments, Counter()
        self.error = None       # the model's exception since the last accepted step
        self.stop_on_nonfinite = False
        self.start(system.t0, system.y0)

    def call(self, fn, *args):
        """``fn(*args)`` inside a model callback, noting the exception it raises
        before Assimulo turns it into a solver error of its own (CVODE and IDA
        first retry it as recoverable): when the run then fails, the solve
        raises the model's own exception instead, as every other family does.
        (Called from the callbacks, not wrapping them: Assimulo reads their
        signatures; a plain call, not a context manager, which costs more per
        callback.)"""
        try:
            return fn(*args)
        except Exception as exc:
            self.error = exc
            raise

    def start(self, t, y):
        """A segment starts at ``(t, y)``."""
        self.t_last = t

    def handle_result(self, solver, t, y, yd=None):
        t = float(t)
        # the start, and the state after an event, come again; a step to a NaN time
        # (RungeKutta34's last, once its step size turned NaN) goes on to the runner,
        # which ends the run there
        if not t <= self.t_last:
            self.error = None
            self.segments.step(self.t_last, t, np.array(y, dtype=float), solver.interpolate)
            self.t_last = t

    def state_events(self, t, y, *rest):
        return np.array([float(e.value(t, y)) for e in self.system.events])

    def handle_event(self, solver, event_info):
        """The roots in ``event_info[0]`` (non-zero entries, without a direction:
        the segment runner keeps those crossed in their event's direction)."""
        t_root = float(solver.t)
        self.segments.roots(t_root, solver.y, np.flatnonzero(event_info[0]),
                            solver.interpolate, t_root - self.t_last)


def _callbacks(system, jac):
    """``(function, jacobian)``: the system's function (``rhs(t, y)`` or ``res(t,
    y, yd)``) and, when ``jac``, its Jacobian as Assimulo takes it (``jac(t, y)``,
    ``jac(c, t, y, yd) = dF/dy + c dF/dy'``): a dense array in C order, as
    Assimulo's callbacks require (a CSC matrix's dense copy is in Fortran order,
    which IDA refuses); else None. The one hand-over of the system, for the
    counted and the timed solve alike."""
    if system.kind == "dae":
        jacobian = (lambda c, t, y, yd: np.ascontiguousarray(dense(system.jac(t, y, yd, c))))
        return system.residual, (jacobian if jac else None)
    jacobian = (lambda t, y: np.ascontiguousarray(dense(system.jac(t, y))))
    return system.fun, (jacobian if jac else None)


def _problem(system, t, y, yd, function, jacobian):
    """The Assimulo problem of ``system`` from ``(t, y, yd)`` with these callbacks."""
    if system.kind == "dae":
        problem = Implicit_Problem(function, y, yd, t)
    else:
        problem = Explicit_Problem(function, y, t)
    if jacobian is not None:
        problem.jac = jacobian
    return problem


def _fed_problem(system, feed, t, y, yd, jac):
    """The problem of the counted solve: :func:`_callbacks` through ``feed`` (whose
    ``calls`` counts them, for the calls Assimulo's statistics do not see,
    IDACalcIC's; a model exception noted), the steps and roots fed to the
    segment runner; with ``feed.stop_on_nonfinite`` the run ends at the model's
    first non-finite value."""
    function, jacobian = _callbacks(system, jac)
    calls = feed.calls
    if system.kind == "dae":
        def fn(t, y, yd, *sw):  # with state events Assimulo passes its switches: ignored
            calls["nfev"] += 1
            return feed.call(function, t, y, yd)

        def jac_fn(c, t, y, yd, *sw):
            calls["njev"] += 1
            return feed.call(jacobian, c, t, y, yd)
    else:
        def fn(t, y, *sw):
            calls["nfev"] += 1
            f = feed.call(function, t, y)
            if feed.stop_on_nonfinite:
                failed = nonfinite(t, f, "the model returned a non-finite value")
                if failed is not None:
                    feed.error = failed
                    raise failed
            return f

        def jac_fn(t, y, *sw):
            calls["njev"] += 1
            return feed.call(jacobian, t, y)
    problem = _problem(system, t, y, yd, fn, jac_fn if jacobian is not None else None)
    problem.handle_result = feed.handle_result
    if system.events:
        problem.state_events = feed.state_events
        problem.handle_event = feed.handle_event
    return problem


#: the settings' names in Assimulo (its solvers' options)
ASSIMULO_OPTIONS = {"max_step": "maxh", "first_step": "inith", "max_steps": "maxsteps",
                    "max_order": "maxord", "linear_solver": "linear_solver",
                    "stablimit": "stablimit"}
#: the options a recipe states even at Assimulo's default (where the solver has them):
#: the tolerances, the method, its iteration, the order, the Jacobian's use and the
#: one-step mode
STATED = ("rtol", "atol", "discr", "iter", "maxord", "usejac", "report_continuously",
          "suppress_alg")
#: CVODE's own settings beside the maximum order
CVODE_SETTINGS = (Setting("linear_solver", str, None, "SUNDIALS' linear solver of the Newton "
                          "systems", choices=("DENSE", "SPGMR")),
                  Setting("stablimit", int, None, "CVODE's BDF stability limit detection "
                          "(STALD): 1 on", low=0, high=1))


class AssimuloIntegrator(Integrator):
    """An Assimulo solver on an ODE or DAE (see the module docstring).

    Settings (:data:`settings`, named as the other codes' are and set on the
    solver under Assimulo's names, :data:`ASSIMULO_OPTIONS`; None: Assimulo's
    default): ``max_step`` (``maxh``; not RungeKutta34, which has none),
    ``first_step`` (``inith``; not LSODAR, which has none), ``max_steps``
    (``maxsteps``, Assimulo's step limit per run: 10,000 steps for
    RungeKutta34 and RODAS, 100,000 for DOPRI5, RADAU5 and LSODAR; CVODE's and
    IDA's apply per call, one step here), and for CVODE and IDA ``max_order``
    (``maxord``), for CVODE ``linear_solver`` (SUNDIALS' ``DENSE`` or
    ``SPGMR``) and ``stablimit`` (STALD, 0 or 1). A run that fails having taken
    ``maxsteps`` steps is ``MAX_STEPS`` whatever the exception.
    """

    solver_ode: str | None = None     # Assimulo's class for an ODE
    solver_dae: str | None = None     # and for a DAE
    settings = (MAX_STEP, _settings.FIRST_STEP, MAX_STEPS)
    adaptive = True
    dense_output = True
    #: Assimulo's own event location (its explicit and Radau5/Rodas codes); CVODE and
    #: IDA hand it to SUNDIALS' root finding, LSODAR to ODEPACK's
    event_locator = "assimulo"
    #: end the run at the model's first non-finite value (a code that would never
    #: return from a NaN otherwise); the others decide themselves, as CVODE retries
    stops_on_nonfinite_model = False
    extra_counters = {"nfev_jac": "right-hand sides spent on difference-quotient Jacobians "
                                  "(included in nfev)",
                      "nlsred": "CVODE's order reductions by its stability-limit detection "
                                "(STALD)"}

    def configure(self, solver, system, rtol, atol) -> None:
        """Tolerances, settings and silence; subclasses add their own."""
        solver.verbosity = SILENT
        solver.display_progress = False      # else "Integrator time: ..." after 10 s
        # RungeKutta34 takes float(atol) of a one-element array, which numpy 2 refuses
        solver.rtol, solver.atol = rtol, (float(atol[0]) if atol.size == 1 else atol)
        solver.report_continuously = True
        for name, value in self.setting_values.items():
            if value is not None:
                setattr(solver, ASSIMULO_OPTIONS[name], value)

    def declines(self, system) -> str | None:
        """Why this system is not run (a ``METHOD_LIMIT``), or None: the dense linear
        algebra used here would densify a large sparse system (base.py rule 6)."""
        if system.n > DENSE_LIMIT and (getattr(system, "jac_sparsity", None) is not None
                                       or system.jac is not None):
            return (f"{self.name}: {system.n} states with a sparse Jacobian; Assimulo's "
                    f"dense linear solvers would densify it (more than {DENSE_LIMIT})")
        return None

    def make_solver(self, system, problem):
        name = self.solver_dae if system.kind == "dae" else self.solver_ode
        return getattr(solvers, name)(problem)

    def second_start(self, system, t, status) -> float | None:
        """The first step of a second start after a failure at ``t`` before any step
        (None: no second start)."""
        return None

    def consistent(self, solver, system, t) -> None:
        """Make a DAE's ``y'`` and algebraic variables consistent after a reset at
        ``t``: IDACalcIC (``make_consistent``), which only IDA offers."""
        raise StepFailure(Status.METHOD_LIMIT, f"{self.name} cannot make a DAE consistent "
                          f"after the reset at t={t:.9g} (only IDA offers IDACalcIC)",
                          retry=False)

    def solve(self, system, *, rtol=None, atol=None, h=None):
        declined = self.declines(system)
        if declined:
            return Solution(system.t_eval[:1], system.y0[None, :], status=Status.METHOD_LIMIT,
                            message=declined)
        segments = Segments(system, degree=(self.order or 1) + 1, locate=False, finite=True,
                            directions=False)
        feed = _Feed(system, segments)
        feed.stop_on_nonfinite = self.stops_on_nonfinite_model
        jac = self.jacobian_used(system)
        counts, run = Counter(), {}

        def start(t, y, yd, reset, inith=None):
            solver = self.configured(system, _fed_problem(system, feed, t, y, yd, jac),
                                     rtol, atol, inith)
            if reset and system.kind == "dae":
                before = Counter(feed.calls)
                self.consistent(solver, system, t)
                counts.update(feed.calls - before)     # IDACalcIC's calls
            run["solver"], run["calls"] = solver, Counter(feed.calls)

        def advance(t, y):
            feed.start(t, y)
            solver = run["solver"]
            try:
                solver.simulate(system.t_end)
            except (AssimuloException, CVodeError, IDAError) as exc:
                if feed.error is not None:
                    raise feed.error from exc
                status, message = _status(exc, solver), f"{type(exc).__name__}: {exc}"
            except Exception as exc:  # Rodas and Dopri5: a plain Exception with their IDID
                if type(exc) is not Exception:
                    raise
                if feed.error is not None:
                    raise feed.error from exc
                status, message = _status(exc, solver), str(exc)
            else:
                return Status.SUCCESS, ""
            inith = self.second_start(system, t, status) if feed.t_last == t else None
            if inith is None or run.get("second"):
                return status, message
            run["second"] = True          # once, the failed start's calls counted
            counts.update(feed.calls - run["calls"])
            start(t, y, getattr(solver, "yd", None), reset=False, inith=inith)
            return advance(t, y)

        def restart(t, y_after):
            old = run["solver"]
            counts.update(self.counts(old))
            start(t, y_after, getattr(old, "yd", None), reset=True)
            return y_after

        start(system.t0, system.y0, getattr(system, "yp0", None), reset=False)
        status, message = segments.run(system.t0, system.y0, advance, restart)
        counts.update(self.counts(run["solver"]))
        return segments.solution(status, message, dict(counts))

    def timing_loop(self, system):
        """``library`` (``simulate`` over the output times) unless the system has
        events, whose action is the segment runner's: then ``wrapper``."""
        return "wrapper" if system.events else "library"

    def timed_call(self, system, *, rtol=None, atol=None, h=None):
        """Assimulo's solver built by :meth:`library_solver` and ``simulate(t_end,
        ncp_list=t_eval)``, as a user calls it (rule 8 of
        :mod:`~integrator_bench.integrators.base`), its counters read after the
        timed call; :meth:`solve` for a system with events or one it declines. A
        ``simulate`` that returns without an exception but with its outputs short
        of ``t_end`` failed (:func:`~integrator_bench.integrators.driver.ended_short`:
        RungeKutta34 on a stiff problem, whose step size collapses to NaN, leaves
        its loop saying it completed, at t = NaN). A
        start that fails before any step is made once more from
        :meth:`second_start`'s first step, as :meth:`solve` does (without it
        IDA's timed solve on the squeezer's ``ggl`` form gave up at t = 0 while
        the counted one ran)."""
        if self.timing_loop(system) != "library" or self.declines(system):
            return super().timed_call(system, rtol=rtol, atol=atol, h=h)

        def simulate(inith=None):
            """``(solver, (t, y) or None, the exception or None)``"""
            solver = self.library_solver(system, rtol, atol, inith)
            try:
                return solver, solver.simulate(system.t_end, ncp_list=system.t_eval)[:2], None
            except Exception as exc:  # typed in finish, as the counted solve types it
                return solver, None, exc

        def run():
            solver, out, exc = simulate()
            if exc is not None and solver.t == system.t0:
                inith = self.second_start(system, system.t0, _status(exc, solver))
                if inith is not None:  # the counted solve's second start (the same work)
                    solver, out, exc = simulate(inith)
            return solver, out, exc

        def finish(result):
            solver, out, exc = result
            if exc is not None:
                return Solution(system.t_eval[:1], system.y0[None, :], message=str(exc),
                                counts=self.counts(solver), status=_status(exc, solver))
            t, y = (np.asarray(a, float) for a in out)
            status, message = Status.SUCCESS, ""
            if t.size < system.t_eval.size:    # returned, without an exception, short of t_end
                status, message = ended_short(t[-1], float(solver.t))
            return Solution(t, y, message=message, counts=self.counts(solver), status=status)
        return TimedCall(run, finish)

    def library_solver(self, system, rtol, atol, inith=None):
        """The solver a user would build: the system's own callbacks
        (:func:`_callbacks`) in an Assimulo problem, :meth:`configured` as
        :meth:`solve` configures it, ``report_continuously`` included (so that it
        takes the same steps: without it CVODE runs to each output time in its
        normal mode and steps differently), with Assimulo's own
        ``handle_result``. ``inith``: the first step of a second start
        (:meth:`second_start`)."""
        function, jacobian = _callbacks(system, self.jacobian_used(system))
        problem = _problem(system, system.t0, system.y0, getattr(system, "yp0", None),
                           function, jacobian)
        return self.configured(system, problem, rtol, atol, inith)

    def library_call(self, system, rtol, atol):
        """Assimulo's solver as :meth:`library_solver` builds it and ``simulate`` over
        the output times (rule 11 of :mod:`~integrator_bench.integrators.base`): every
        option :meth:`configured` sets apart from the solver's defaults (those of a
        solver made on the same problem and left as made), ``report_continuously``
        among them, and those of :data:`STATED` always; None for a system it
        declines."""
        if self.declines(system):
            return None
        solver = self.library_solver(system, rtol, atol)
        default = self.make_solver(system, solver.problem).options
        options = {k: v for k, v in solver.options.items()
                   if k in STATED or k not in default or not _same(v, default[k])}
        problem = "Implicit_Problem(res, y0, yd0, t0)" if system.kind == "dae" else \
            "Explicit_Problem(rhs, y0, t0)"
        function = "system.residual" if system.kind == "dae" else "system.fun"
        jac = self.jacobian_used(system)
        # the library's class (RADAU5 on a DAE runs a subclass of Radau5DAE with its
        # variables' index counts: assimulo_radau5)
        method = next(c.__name__ for c in type(solver).__mro__
                      if c.__module__.startswith("assimulo"))
        return {"library": f"Assimulo {metadata.version('assimulo-testing')}",
                "call": f"assimulo.solvers.{method}({problem}), each option "
                        "set as an attribute, .simulate(t_end, ncp_list=output times)",
                "method": method, "function": function,
                "options": library_call.described(options),
                "callbacks": (f"{'res(t, y, yd)' if system.kind == 'dae' else 'rhs(t, y)'}: "
                              f"{function}" + ("; problem.jac = " + (
                                  "jac(c, t, y, yd): system.jac(t, y, yd, c)"
                                  if system.kind == "dae" else "jac(t, y): system.jac(t, y)")
                                  + " as a dense C-ordered array" if jac else "")),
                "jacobian": library_call.jacobian_source(self.uses_jacobian, jac)}

    def jacobian_used(self, system) -> bool:
        """Whether the system's Jacobian is handed to the code (``usejac``)."""
        return self.uses_jacobian and system.jac is not None

    def configured(self, system, problem, rtol, atol, inith=None):
        """The solver of ``problem`` as both solves run it, the one configuration:
        :meth:`configure` (tolerances, settings, silence), the first step ``inith``
        of a second start (None: the code's or the setting's), ``usejac``."""
        solver = self.make_solver(system, problem)
        self.configure(solver, system, rtol, np.array(np.broadcast_to(atol, (system.n,)),
                                                      dtype=float))
        if inith is not None:
            solver.inith = inith
        if hasattr(solver, "usejac"):
            solver.usejac = self.jacobian_used(system)
        return solver

    def counts(self, solver) -> dict:
        return counts_of(solver.statistics)


class _Cvode(AssimuloIntegrator):
    settings = AssimuloIntegrator.settings + (max_order(5),) + CVODE_SETTINGS

    """CVODE through Assimulo: Newton iteration with the dense (or SPGMR) solver."""

    accepts = frozenset({"ode"})
    solver_ode = "CVode"
    discr = "BDF"
    implicit = uses_jacobian = events = True
    event_locator = "sundials"
    reference = ("Hindmarsh et al., ACM TOMS 31 (2005) 363-396; Andersson, Fuehrer, "
                 "Akesson, Math. Comput. Simul. 116 (2015) 26-43")

    def configure(self, solver, system, rtol, atol):
        solver.discr, solver.iter = self.discr, "Newton"
        super().configure(solver, system, rtol, atol)


class CvodeBDF(_Cvode):
    name = "assimulo-cvode-bdf"
    code = "SUNDIALS CVODE (BDF)"
    description = "SUNDIALS CVODE through Assimulo, variable-order BDF (1-5), every counter"


class CvodeAdams(_Cvode):
    name = "assimulo-cvode-adams"
    code = "SUNDIALS CVODE (Adams)"
    settings = AssimuloIntegrator.settings + (max_order(12),) + CVODE_SETTINGS
    description = "SUNDIALS CVODE through Assimulo, variable-order Adams-Moulton (1-12)"
    discr = "Adams"


class IDA(AssimuloIntegrator):
    """IDA with ``suppress_alg``: the variables outside ``error_mask`` out of the
    local error test (module docstring).

    A start that fails with Newton failures before any step is made once more
    from the first step ``FIRST_STEP`` times the span left (unless ``first_step`` is
    set; the calls of the failed start are counted: Assimulo keeps no
    statistics of a failed IDA run). IDA's own rule, ``h0 = min(0.001 span,
    0.5 / ||y'0||)`` in the error weights, gives 3e-11 s on the squeezer's
    ``ggl`` form (its accelerations, 1.4e4 rad/s^2, are in the error test),
    where the iteration matrix (``cj = 1/h``) leaves the multipliers' Newton
    corrections at the rounding level of ``cj``, above their tolerance: IDA
    gives up at t = 0 (``IDA_CONV_FAIL``). Without the ``y'`` term the rule is
    the step of the second start, the one IDA itself takes on the ``i3`` form
    (whose velocities are out of the test); the error test cuts it when needed.
    """

    name = "assimulo-ida"
    code = "SUNDIALS IDA"
    description = ("SUNDIALS IDA through Assimulo, variable-order BDF (1-5) for implicit "
                   "DAEs up to index 3 (suppress_alg)")
    reference = ("Hindmarsh et al., ACM TOMS 31 (2005) 363-396; Brenan, Campbell, "
                 "Petzold (1996), sect. 5.4")
    accepts = frozenset({"dae"})
    max_index = 3
    solver_dae = "IDA"
    settings = AssimuloIntegrator.settings + (max_order(5),)
    implicit = uses_jacobian = events = True
    event_locator = "sundials"

    def consistent(self, solver, system, t):
        """IDACalcIC from the reset state: ``algvar`` marks the algebraic variables
        for it, then the error test's set again."""
        algvar = solver.algvar
        solver.algvar = (~system.algebraic).astype(float)
        solver.tout1 = system.t_end
        solver.make_consistent("IDA_YA_YDP_INIT")
        solver.algvar = algvar

    def second_start(self, system, t, status):
        if self.first_step is None and status is Status.NEWTON_FAILURE:
            return FIRST_STEP * (system.t_end - t)
        return None

    def configure(self, solver, system, rtol, atol):
        super().configure(solver, system, rtol, atol)
        if not system.error_mask.all():
            solver.algvar = system.error_mask.astype(float)
            solver.suppress_alg = True


class Rodas(AssimuloIntegrator):
    name = "assimulo-rodas"
    description = "RODAS through Assimulo: Rosenbrock method of order 4(3), stiffly accurate"
    reference = "Hairer and Wanner, Solving ODEs II (1996), sect. IV.7"
    solver_ode = "RodasODE"
    order = 4
    implicit = uses_jacobian = events = True
    stability = "L"
    #: RODAS's error test accepts a NaN estimate (``ERR > 1`` is false) and its
    #: step-size update then loops on a NaN step inside the Fortran code, never
    #: returning (seen on a right-hand side that turns NaN)
    stops_on_nonfinite_model = True

    def counts(self, solver):
        """``nfev`` with RODAS's difference quotient for ``df/dt`` (one call per
        Jacobian, ``IDFX = 0``), which its NFCN leaves out like the Jacobian's."""
        counts = super().counts(solver)
        if solver.usejac:
            counts["nfev"] = counts.get("nfev", 0) + counts.get("njev", 0)
        return counts


class Dopri5(AssimuloIntegrator):
    name = "assimulo-dopri5"
    description = "DOPRI5 through Assimulo: explicit Dormand-Prince 5(4), dense output"
    reference = "Hairer, Norsett and Wanner, Solving ODEs I (1993), sect. II.5"
    solver_ode = "Dopri5"
    order = 5
    events = True


class RungeKutta34(AssimuloIntegrator):
    name = "assimulo-rk34"
    description = "Assimulo's RungeKutta34: explicit embedded Runge-Kutta 4(3), the seed report's"
    reference = "Andersson, Fuehrer, Akesson, Math. Comput. Simul. 116 (2015) 26-43"
    solver_ode = "RungeKutta34"
    order = 4
    events = True
    settings = (_settings.FIRST_STEP, MAX_STEPS)     # Assimulo's RungeKutta34 has no maxh

    def counts(self, solver):
        """Without ``nfev``: Assimulo's ``nfcns`` leaves out the first call of every
        segment (``runge_kutta.py``, ``_iter``); the harness's count stands. The
        method never rejects a step (its error estimate sets the next step only),
        so it keeps no ``nerrfails``."""
        counts = super().counts(solver)
        counts.pop("nfev", None)
        return counts


class LSODAR(AssimuloIntegrator):
    name = "assimulo-lsodar"
    code = "ODEPACK LSODA (LSODAR: with root finding)"
    description = ("ODEPACK LSODAR through Assimulo: Adams/BDF with automatic stiffness "
                   "switching and root finding")
    reference = "Hindmarsh, ODEPACK, IMACS Trans. Sci. Comput. 1 (1983) 55-64; Petzold (1983)"
    solver_ode = "LSODAR"
    implicit = uses_jacobian = events = True
    event_locator = "odepack"
    settings = (MAX_STEP, MAX_STEPS)     # Assimulo's LSODAR has no inith
