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
on a problem that is not an FMU they are ``unsupported``. The FMU handles its
own events; every output row pair at one time whose states differ is reported
as an event of the system's ``event_name``.

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
exception is ``solver_failure``; a run that stops before ``t_end`` without
one is ``solver_failure`` too.
"""

from __future__ import annotations

import re
from functools import lru_cache

import numpy as np

from integrator_bench.integrators.base import Integrator, Solution, Status

#: fmpy's message for a failing CVode call, with SUNDIALS' flag
CVODE_ERROR = re.compile(r"CVode error \(code (-?\d+)\)")
#: the FMU instance's method (FMI 2.0, 3.0) whose calls are function evaluations
DERIVATIVES = {"2.0": "getDerivatives", "3.0": "getContinuousStateDerivatives"}


@lru_cache(maxsize=16)
def _model_description(unzipdir: str):
    from fmpy import read_model_description
    return read_model_description(unzipdir)


def _counted_instance(unzipdir: str):
    """A fresh model-exchange instance of the FMU whose derivative calls count
    themselves in the returned dict's ``"nfev"``."""
    from fmpy.simulation import instantiate_fmu

    md = _model_description(unzipdir)
    fmu = instantiate_fmu(unzipdir, md, fmi_type="ModelExchange")
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

    def _options(self, system, rtol, h) -> dict:
        raise NotImplementedError

    def solve(self, system, *, rtol=None, atol=None, h=None) -> Solution:
        from fmpy import simulate_fmu

        options = self._options(system, rtol, h)
        if isinstance(options, Solution):
            return options
        md, fmu, calls = _counted_instance(system.unzipdir)
        try:
            result = simulate_fmu(
                system.unzipdir, fmi_type="ModelExchange", solver=self.solver,
                model_description=md, fmu_instance=fmu,
                start_time=system.t0, stop_time=system.t_end,
                start_values=dict(system.start_values), output=list(system.variables),
                record_events=True, **options)
        except Exception as exc:  # fmpy raises plain Exceptions; CVODE's failures among them
            text = str(exc).strip().splitlines()
            return Solution(np.empty(0), np.empty((0, system.n)), status=failure(str(exc)),
                            message=f"fmpy: {text[0] if text else type(exc).__name__}",
                            counts=dict(calls))
        finally:
            fmu.freeInstance()
        times = np.asarray(result["time"], float)
        Y = np.column_stack([np.asarray(result[name], float) for name in system.variables])
        t, y = _at_output_times(system.t_eval, times, Y)
        counts = dict(calls)
        counts.update(self._step_counts(system, h, times))
        events = _events(times, Y, system.event_name)
        counts["nevents"] = len(events)
        status = Status.SUCCESS if len(t) == len(system.t_eval) else Status.SOLVER_FAILURE
        message = "" if status is Status.SUCCESS else \
            f"fmpy stopped at t = {times[-1]:g} before t_end = {system.t_end:g}"
        return Solution(t, y, status=status, message=message, counts=counts, events=events)

    def _step_counts(self, system, h, times) -> dict:
        return {}


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


def _at_output_times(t_eval, times, Y):
    """The rows of fmpy's result at the output times: at an event time the
    row after the event; stops at the first output time not reached."""
    tol = 1e-9 * max(abs(t_eval[-1] - t_eval[0]), 1.0)
    rows = []
    for t in t_eval:
        hit = np.flatnonzero(np.abs(times - t) <= tol)
        if hit.size == 0:
            break
        rows.append(Y[hit[-1]])
    n = len(rows)
    return np.asarray(t_eval[:n], float), np.asarray(rows, float).reshape(n, Y.shape[1])


def _events(times, Y, name):
    """``(t, name, y_after)`` for each pair of consecutive rows at one time whose
    states differ: fmpy records the state before and after each event."""
    same = np.flatnonzero((np.diff(times) == 0.0) & np.any(Y[1:] != Y[:-1], axis=1))
    return [(float(times[i + 1]), name, Y[i + 1].copy()) for i in same]


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

    def _options(self, system, rtol, h):
        spacing = (system.t_end - system.t0) / (len(system.t_eval) - 1)
        ratio = spacing / h
        if abs(ratio - round(ratio)) > 1e-9 * ratio or round(ratio) < 1:
            return Solution(np.empty(0), np.empty((0, system.n)), status=Status.METHOD_LIMIT,
                            message=f"fmpy's Euler samples at multiples of its step: h = {h:g} "
                                    f"does not divide the output spacing {spacing:g}")
        # fmpy's Euler steps from one output point to the next: sample every step
        return {"step_size": h, "output_interval": h}

    def _step_counts(self, system, h, times):
        return {"nsteps": len(np.unique(times)) - 1}
