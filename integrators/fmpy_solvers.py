"""fmpy's own solvers, for FMU problems: the FMU tool's answer beside the harness's.

fmpy (Dassault Systemes, https://github.com/CATIA-Systems/FMPy) simulates a
model-exchange FMU with ``fmpy.simulate_fmu(..., fmi_type="ModelExchange")``
and one of two solvers:

``fmpy-cvode``
    SUNDIALS CVODE (Hindmarsh et al., ACM TOMS 31, 2005) as fmpy configures it:
    BDF with Newton iteration on a dense finite-difference Jacobian,
    ``atol = rtol * nominal`` of each state, the step bounded by 1/50 of the
    span, re-initialized at every event and output point it stops at.
``fmpy-euler``
    the explicit Euler method at the fixed step ``h``; state events are acted
    on at the end of the step in which an indicator changed sign, not located.

Settings: none. ``simulate_fmu`` takes, for these solvers, only what the run
gives already: ``relative_tolerance`` (rtol) and ``output_interval`` for CVode
(its ``maxStep`` is fixed at 1/50 of the span, its other options not
reachable), ``step_size`` (h) for Euler.

Both take only the ``fmu`` kind (:class:`~integrator_bench.problems.system.FmuSystem`):
on a problem that is not an FMU they are ``unsupported``.

The segment runner. fmpy records a row at every return of its solver (an
output point or an event, ``record_events``); ``simulate_fmu``'s
``step_finished`` callback hands the rows recorded so far to the segment
runner (:class:`~integrator_bench.integrators.driver.Segments`, :class:`_Rows`),
and the rows of its result recorded after the last callback follow. Each row at a new time is a step
end: the runner fills the outputs (every output time is a row), stops the run
past its time budget (its exception leaves fmpy's loop from Python) and at a
non-finite state, and fails a run whose outputs end before ``t_end``. Two rows
at one time whose states differ are an event the FMU acted on, reported to the
runner as one of the system's ``event_name`` (:meth:`Segments.applied`: the
output at that time takes the state after it, as fmpy records it). What cannot
go through the runner: locating the events and updating the state at them.
fmpy's loop asks the FMU for its event indicators and calls the FMU's own
event update (``enterEventMode``, ``newDiscreteStates``/``updateDiscreteStates``),
which changes the state inside the FMU and re-initializes CVode; the harness's
event functions and resets are not the FMU's, so the runner's locator and
:func:`~integrator_bench.integrators.driver.act` have nothing to act on.

Counts: ``nfev`` is the number of the FMU's derivative calls
(``fmi2GetDerivatives``, ``fmi3GetContinuousStateDerivatives``), finite-difference
Jacobian columns included, counted on the FMU instance handed to
``simulate_fmu`` (the same calls fmpy's FMI call logger lists, without the
logger's cost: it formats every call's arguments, which doubled fmpy-cvode's
CPU time at rtol 1e-4 and more than tripled it at 1e-8 on the spring pendulum
FMU); ``nsteps`` (``fmpy-euler`` only) the number of steps taken; everything
else is unknown to fmpy's interface and left null.

Failures: fmpy raises an exception; a failing CVode call's flag is typed as
in :mod:`~integrator_bench.integrators.sundials` (:func:`failure`), any other
exception is ``solver_failure``; the segment runner makes a run that stops
before ``t_end`` without one ``solver_failure`` too, a non-finite row
``nonfinite_state``, and a run past its budget ``over_budget``. The outputs
reached before a failure are kept.

Timing: fmpy reports no counts of its own, so a case's one solve, counted and
timed, is :meth:`_Fmpy.solve` (``timing`` ``wrapper``): ``simulate_fmu`` with the
arguments of :meth:`_Fmpy.simulation` plus the counted FMU instance and the feed.
That costs up to a third more CPU than the plain call (bouncing ball and spring
pendulum FMUs, CVode at rtol 1e-6, Euler at h = 1e-3; docs/timing.md).
"""

from __future__ import annotations

import re
from functools import lru_cache
from importlib import metadata

import numpy as np

from integrator_bench.integrators import library_call
from integrator_bench.integrators.base import Integrator, Solution, Status, StepFailure
from integrator_bench.integrators.driver import Segments

#: fmpy's message for a failing CVode call, with SUNDIALS' flag
CVODE_ERROR = re.compile(r"CVode error \(code (-?\d+)\)")
#: the FMU instance's method (FMI 2.0, 3.0) whose calls are function evaluations
DERIVATIVES = {"2.0": "getDerivatives", "3.0": "getContinuousStateDerivatives"}


@lru_cache(maxsize=16)
def _model_description(unzipdir: str):
    from fmpy import read_model_description
    return read_model_description(unzipdir)


class _Rows:
    """fmpy's recorded rows fed to the segment runner (module docstring), as
    ``simulate_fmu``'s ``step_finished(time, recorder)``, which returns True to
    go on. ``steps`` counts the rows at a new time."""

    def __init__(self, system, segments):
        self.system, self.segments = system, segments
        self.columns, self.done, self.last, self.steps = None, 0, None, 0

    def __call__(self, time, recorder) -> bool:
        if self.columns is None:
            names = [c[0] for c in recorder.cols]
            self.columns = [names.index(v) for v, _ in self.system.elements]
        rows = recorder.rows
        while self.done < len(rows):
            row = rows[self.done]
            self.done += 1
            self.row(float(row[0]), self.values([row[i] for i in self.columns]))
        return True

    def values(self, fields) -> np.ndarray:
        """The canonical components from their variables' recorded ``fields``
        (an array variable's field is its whole value)."""
        return np.array([field if index is None else np.ravel(field)[index]
                         for field, (_, index) in zip(fields, self.system.elements)],
                        dtype=float)

    def rest(self, result):
        """The rows of ``simulate_fmu``'s ``result`` recorded after the last callback
        (the one at ``t_end`` at least)."""
        for i in range(self.done, len(result)):
            self.row(float(result["time"][i]),
                     self.values([result[v][i] for v, _ in self.system.elements]))
        self.done = len(result)

    def row(self, t, y):
        """One row: a step end, the state after an event at the last row's time, or
        the start."""
        segments = self.segments
        if self.last is None or t == self.last[0]:
            if self.last is None:
                segments.reached(t, y)                   # the FMU's initial state
            elif np.any(y != self.last[1]):
                segments.applied(t, self.system.event_name, y)
        else:
            self.steps += 1
            segments.step(self.last[0], t, y, None)
        self.last = (t, y)


def _counted_instance(unzipdir: str):
    """A fresh model-exchange instance of the FMU whose derivative calls count
    themselves in the returned dict's ``"nfev"``."""
    from integrator_bench.problems.system import fmu_instance

    md = _model_description(unzipdir)
    fmu = fmu_instance(unzipdir, md)
    calls = {"nfev": 0}
    method = DERIVATIVES["3.0" if md.fmiVersion.startswith("3.") else "2.0"]
    original = getattr(fmu, method)

    def derivatives(*args):
        calls["nfev"] += 1
        return original(*args)
    setattr(fmu, method, derivatives)
    return md, fmu, calls


class _Fmpy(Integrator):
    """``simulate_fmu`` with fmpy's solver ``solver``."""

    accepts = frozenset({"fmu"})
    events = True
    event_locator = "fmpy"           # simulate_fmu's own event handling
    solver = ""
    counts_steps = False     # nsteps: fmpy's rows at a new time (Euler: every step)

    def _options(self, system, rtol, h) -> dict:
        raise NotImplementedError

    def simulation(self, system, rtol, h) -> dict | Solution:
        """``simulate_fmu``'s arguments for ``system`` (its solver's :meth:`_options`
        among them), or the ``METHOD_LIMIT`` Solution of a run it cannot make: the
        one configuration of fmpy, which :meth:`solve` adds its counted FMU
        instance and its feed to."""
        options = self._options(system, rtol, h)
        if isinstance(options, Solution):
            return options
        return dict(filename=system.unzipdir, fmi_type="ModelExchange", solver=self.solver,
                    model_description=_model_description(system.unzipdir),
                    start_time=system.t0, stop_time=system.t_end,
                    start_values=dict(system.start_values),
                    output=list(dict.fromkeys(v for v, _ in system.elements)),
                    record_events=True, **options)

    def solve(self, system, *, rtol=None, atol=None, h=None) -> Solution:
        from fmpy import simulate_fmu

        arguments = self.simulation(system, rtol, h)
        if isinstance(arguments, Solution):
            return arguments
        md, fmu, calls = _counted_instance(system.unzipdir)
        segments = Segments(system, locate=False, finite=True)
        rows = _Rows(system, segments)

        def advance(t, y):
            try:
                result = simulate_fmu(fmu_instance=fmu, step_finished=rows, **arguments)
            except StepFailure:             # the runner's: past the budget, non-finite
                raise
            except Exception as exc:  # fmpy raises plain Exceptions; CVODE's failures among them
                return failure(str(exc)), _message(exc)
            finally:
                fmu.freeInstance()
            rows.rest(result)
            return Status.SUCCESS, ""

        status, message = segments.run(system.t0, system.y0, advance, None)
        counts = dict(calls)
        if self.counts_steps:
            counts["nsteps"] = rows.steps
        return segments.solution(status, message, counts)

    def library_call(self, system, rtol, atol):
        """``simulate_fmu`` with :meth:`simulation`'s arguments (rule 11 of
        :mod:`~integrator_bench.integrators.base`; fmpy's CVODE takes a relative
        tolerance only, and differences the FMU for its Jacobian); None at a fixed
        step (the advice calibrates a tolerance) or for a run it declines."""
        if not self.adaptive:
            return None
        arguments = self.simulation(system, rtol, None)
        if isinstance(arguments, Solution):
            return None
        arguments = {k: v for k, v in arguments.items() if k != "model_description"}
        arguments["filename"] = "the FMU file"
        return {"library": f"fmpy {metadata.version('fmpy')}",
                "call": "fmpy.simulate_fmu(**options)", "method": self.solver,
                "function": "the FMU's own equations", "options": library_call.described(arguments),
                "callbacks": "none: fmpy calls the FMU itself",
                "jacobian": library_call.jacobian_source(True, False)}

    def timing_loop(self, system):
        """``wrapper``: the case's one solve is :meth:`solve`, ``simulate_fmu`` with
        the counted instance and the feed, since fmpy reports no counts of its own
        (rule 8 of :mod:`~integrator_bench.integrators.base`)."""
        return "wrapper"


def _message(exc) -> str:
    """The record's message of an exception fmpy raised: its first line."""
    text = str(exc).strip().splitlines()
    return f"fmpy: {text[0] if text else type(exc).__name__}"


def failure(message: str) -> Status:
    """The :class:`Status` of an exception fmpy raised: its CVODE wrapper reports a
    failing ``CVode`` call as "CVode error (code FLAG) in module ..." (fmpy's
    ``sundials.CVodeSolver.step``), and the flag maps as for the SUNDIALS wrappers
    (:data:`~integrator_bench.integrators.sundials.CVODE_FAILURES`); anything
    else is ``SOLVER_FAILURE``."""
    from integrator_bench.integrators.sundials import CVODE_FAILURES

    match = CVODE_ERROR.search(message)
    if match is None:
        return Status.SOLVER_FAILURE
    return CVODE_FAILURES.get(int(match.group(1)), Status.SOLVER_FAILURE)




class FmpyCVode(_Fmpy):
    name = "fmpy-cvode"
    description = "fmpy's CVODE (BDF, dense FD Jacobian) on the FMU itself"
    reference = "fmpy simulate_fmu; Hindmarsh et al., ACM TOMS 31 (2005) 363-396"
    solver = "CVode"
    implicit = True
    adaptive = True
    fixed_step = False

    def _options(self, system, rtol, h):
        span = system.t_end - system.t0
        return {"relative_tolerance": rtol,
                "output_interval": span / (len(system.t_eval) - 1)}


class FmpyEuler(_Fmpy):
    name = "fmpy-euler"
    description = "fmpy's explicit Euler at fixed step h on the FMU itself"
    reference = "fmpy simulate_fmu; Euler (1768)"
    solver = "Euler"
    order = 1
    adaptive = False
    fixed_step = True
    counts_steps = True

    def _options(self, system, rtol, h):
        spacing = (system.t_end - system.t0) / (len(system.t_eval) - 1)
        ratio = spacing / h
        if abs(ratio - round(ratio)) > 1e-9 * ratio or round(ratio) < 1:
            return Solution(np.empty(0), np.empty((0, system.n)), status=Status.METHOD_LIMIT,
                            message=f"fmpy's Euler samples at multiples of its step: h = {h:g} "
                                    f"does not divide the output spacing {spacing:g}")
        # fmpy's Euler steps from one output point to the next: sample every step
        return {"step_size": h, "output_interval": h}

