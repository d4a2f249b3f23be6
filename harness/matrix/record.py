"""The result record: one per case (docs/record.md describes every field).

:class:`Record` is the record, one typed field per column; ``FIELDS`` maps each
field to its SQL type, and the store, the DataFrame and the JSON output all follow
it. :class:`CaseStatus` is the record's ``status``, and
the ``reason`` codes below type it further. A count an integrator cannot report
is None (null), never a made-up number. ``RUN_FIELDS`` is the store's ``runs``
table, one row per run of the matrix.

Timing. One solve on the counted system gives the counts, errors
and events; the CPU comes from separate solves of the bare system, nothing
wrapped, through the library's own loop where it has one (``timing``:
``library``, ``driver`` for the in-house steppers, ``wrapper`` where the
library's loop cannot honour the system; rule 8 of
:mod:`integrator_bench.integrators.base`). They are sampled until 0.2 s of
CPU or ``--repeat`` samples (10 by default), whichever first, within half the
case's timeout (:func:`integrator_bench.harness.run.execution.samples`).
``cpu_s`` is the **median** of the samples, ``cpu_s_min`` the least,
``cpu_s_iqr`` the interquartile range (the spread; null below four samples),
``repeat`` their number, ``cpu_samples`` the samples themselves. The median
is the ranking's figure, as asv keeps it (DiffEqDevTools keeps the least): it
does not favour a line that was lucky once. The records of the lines in
contention for an answer get more samples afterwards (``contended`` of them,
timed alternating with the other contenders: :mod:`integrator_bench.harness.contend`),
stored as a newer record of the case; the margins' intervals come from
``cpu_samples`` (:mod:`integrator_bench.harness.ranking.margin`). ``timing_mismatch`` names a
counter the integrator reports in both solves that differs, or the timed
solve's status and number of outputs where they differ from the counted
one's: such a case did not time the work it counted and is ``untimed``
(reason ``timed_solve_differs``), never ranked; a store without these
fields reads them as null. A failed run keeps the
counted solve's time, one sample, ``timing`` null; so does one whose counted
solve took more than half the timeout (its timed solve would be killed): a
``timeout`` with reason ``over_budget``, its errors and counts kept.
"""

from __future__ import annotations

import dataclasses
import enum
from dataclasses import dataclass


#: an ``ok`` case whose first solve took more than ``1 - BUDGET_EDGE`` of its budget is
#: at the budget's edge (``budget_edge``): another run may time it out
BUDGET_EDGE = 0.1


class CaseStatus(str, enum.Enum):
    """How a case ended: the record's ``status``.

    A string enum: each member equals its value (``CaseStatus.OK == "ok"``), and
    a record holds the value itself (:func:`status_value`), so stores, JSON lines
    and DataFrames carry plain strings and stores written before the enum read
    the same.
    """

    #: the integrator reached the final time and the errors were measured
    OK = "ok"
    #: the counted solve succeeded and its errors and counts are kept, but a timed
    #: solve did not do the same work (it failed, stopped early or ended with other
    #: outputs): no CPU to rank by (reason ``timed_solve_differs``; ``cpu_s`` is the
    #: counted solve's); in no table of CPU to a target, profile or answer
    UNTIMED = "untimed"
    #: the integrator gave up (``reason``: its typed ``Status``), or its result is
    #: unusable: non-finite values, or a final-time mixed error above
    #: ``metrics.DIVERGENCE_BOUND`` (``reason`` diverged, the errors kept)
    FAILED = "failed"
    #: no record within the timeout: the worker was killed; or the counted solve took
    #: more than its half of it (reason ``over_budget``; harness/run/execution.py)
    TIMEOUT = "timeout"
    #: the worker (or the Dask workers running it) died without a record
    CRASHED = "crashed"
    #: an exception in the integrator or the problem (out of memory included), or
    #: output times that are not the problem's
    ERROR = "error"
    #: the integrator cannot take this formulation, step mode or tolerance; nothing ran
    UNSUPPORTED = "unsupported"
    #: not run: what its line already showed (a timeout at a looser tolerance, a
    #: divergence at a smaller step, a larger step's CPU scaled to this step over the
    #: budget) or the stiffness analysis makes it hopeless
    #: (harness/run/schedule.py; ``reason`` says which, ``decided_by`` names the case
    #: that decided it, ``skip_policy`` the rules); ``--no-skip`` runs it
    SKIPPED = "skipped"
    #: raced out (harness/ranking/racing.py): stopped at its race bound, ``race_bound_s``
    #: CPU seconds, tau times the least CPU a line of its problem and parameter set
    #: (``race_line``) needed to reach the race target (reason ``race_bound``), or not
    #: run after a looser case of its line was so stopped (reason ``after_dominated``,
    #: ``decided_by`` that case); never an answer, beyond tau in the profiles;
    #: ``--exhaustive`` runs every case to its budget
    DOMINATED = "dominated"

    def __str__(self) -> str:
        return self.value

    __format__ = str.__format__


#: every status, in the order reports list them
STATUSES = tuple(s.value for s in CaseStatus)


def status_value(status: CaseStatus | str) -> str:
    """The string a record stores for ``status``; ValueError for anything else."""
    return CaseStatus(status).value

# The record's ``reason``: a fixed code beside the free-text message. A failed
# run's is the integrator's own typed outcome, ``Solution.status.value``
# (integrators/base.py ``Status``: newton_failure, error_test_failure,
# linear_solver_failure, nonfinite_state, diverged, step_size_underflow, max_steps,
# method_limit, solver_failure), or diverged when
# the run ended with an error past harness/measure/metrics.py DIVERGENCE_BOUND (mescd < 0);
# the harness decides the others with these codes; a skipped record's is one of
# harness/run/schedule.py SKIP_REASONS; a timeout the worker decided itself (a counted
# solve past its half of the timeout) has ``Status.OVER_BUDGET``'s over_budget. An
# ``ok`` record has none (null).
TIMEOUT = CaseStatus.TIMEOUT.value   # no record within the timeout: the worker was killed
CRASHED = CaseStatus.CRASHED.value   # the worker died without a record (signal, exit)
EXCEPTION = "exception"              # the integrator (or problem) raised
OUT_OF_MEMORY = "out_of_memory"      # MemoryError: the per-case memory limit was reached
UNSUPPORTED = CaseStatus.UNSUPPORTED.value  # the integrator cannot take this formulation or mode
NONFINITE_OUTPUT = "nonfinite_output"  # a "successful" solution with non-finite values
TIME_MISMATCH = "time_mismatch"      # the output times are not the problem's
INPUT_MODIFIED = "input_modified"    # the integrator changed what it was handed (arrays, state)
TIMED_SOLVE_DIFFERS = "timed_solve_differs"  # untimed: a timed solve ended otherwise than the counted one
NO_REFERENCE = "no_reference"        # the problem's reference could not be computed (within its limit): not run
RACE_BOUND = "race_bound"            # dominated: stopped at its race bound (harness/ranking/racing.py)
AFTER_DOMINATED = "after_dominated"  # dominated: not run, a looser case of its line was stopped at its race bound
BUILD_FAILED = "build_failed"        # the problem (a plugin's, an FMU) failed to build in its trial: not run
HARNESS_REASONS = (TIMEOUT, CRASHED, EXCEPTION, OUT_OF_MEMORY, UNSUPPORTED, NONFINITE_OUTPUT,
                   TIME_MISMATCH, INPUT_MODIFIED, TIMED_SOLVE_DIFFERS, NO_REFERENCE, RACE_BOUND,
                   AFTER_DOMINATED, BUILD_FAILED)

@dataclass(slots=True)
class Record:
    """One case's result record: every field of the store's ``records`` table, typed.

    The run engine builds and passes Records; they become rows at the store's
    boundary (:meth:`row`, :class:`~integrator_bench.harness.matrix.store.Store`) and
    JSON lines at the command line's (:meth:`to_dict`). The case's identity
    (``case_id``, ``problem``, ``params``, ``formulation``, ``integrator``,
    ``settings``, ``rtol``, ``h``) and what the report groups and draws it by
    (``mode``, ``line``, ``label``, ``kind``, ``family``) are set once, from the
    :class:`~integrator_bench.harness.matrix.cases.Case`
    (:meth:`~integrator_bench.harness.matrix.cases.Case.identity`), and stored, so a
    report draws what the record says rather than today's registry (a store written
    before these fields has them filled in when it is read:
    :func:`~integrator_bench.harness.matrix.line.backfill`).

    A field is read and written as an attribute; reading ``record["status"]`` and
    ``record.get("status")`` works too, and ``record["x"] = v`` or
    ``record.update(x=v)`` of a name that is not a field raises ``KeyError``, so a
    mistyped field can never become a column of its own.
    """

    case_id: str | None = None  # hash of the case key: problem, params, formulation, integrator, rtol, h (settings when given)
    problem: str | None = None
    params: str | None = None  # JSON object of every parameter value
    formulation: str | None = None
    integrator: str | None = None
    settings: str | None = None  # JSON object of the integrator's settings not at their default; null at the defaults
    origin: str | None = None  # built-in, or the plugin package and version
    rtol: float | None = None
    atol: float | None = None  # smallest component of the absolute tolerance vector
    h: float | None = None
    status: str | None = None  # CaseStatus value
    message: str | None = None
    reason: str | None = None  # fixed code: the Solution's status for failed runs, else HARNESS_REASONS
    scd: float | None = None
    mescd: float | None = None
    err_max: float | None = None  # largest mixed error over the output times (error components)
    err_vel: float | None = None
    err_lambda: float | None = None
    drift_pos: float | None = None
    drift_vel: float | None = None
    monitor_err: float | None = None  # Orlov's E of the problem's monitored history (problems/base.py monitor); null without one
    energy_var: float | None = None  # largest |E(t) - E(t0)| [J] of the mechanical energy over the output times, for a problem that conserves it (invariants()["energy"]); null otherwise
    cpu_s: float | None = None  # median CPU seconds of the timed solves (see Timing above)
    wall_s: float | None = None  # median wall seconds of the same solves
    nfev: int | None = None  # counted by the harness, finite-difference calls included
    njev: int | None = None  # the integrator's count if it reports one, else the harness's
    nlu: int | None = None
    nsteps: int | None = None
    nreject: int | None = None
    nniter: int | None = None
    nnfail: int | None = None
    nevents: int | None = None  # state events acted on (Solution.events), as the integrator reported
    # Event measures against the reference's event sequence (harness/measure/metrics.py
    # event_measures; events matched by kind and order); all null for a problem without events
    events_by_kind: str | None = None  # JSON {event name: count} of the run's events
    event_time_err: float | None = None  # largest |t - t_ref| over matched events (time units); null if none matched
    events_missed: int | None = None  # reference events the run has no match for
    events_spurious: int | None = None  # run events with no match in the reference
    event_state_err: float | None = None  # mixed error (max over error components) of the state right after the last matched event
    solver_counts: dict | str | None = None  # JSON (a dict until the store writes it): the integrator's own counters, as it reported them
    count_mismatch: str | None = None  # where solver_counts disagree with the harness: "nfev: own 120, harness 240"
    reference: str | None = None  # id of the reference the errors were measured against
    code_version: str | None = None
    created: str | None = None  # UTC ISO 8601
    cpu_s_min: float | None = None  # least CPU seconds of the `repeat` timed solves (cpu_s: their median)
    repeat: int | None = None  # how many timed solves (samples) cpu_s and wall_s are the median of
    cpu_s_iqr: float | None = None  # interquartile range of their CPU seconds; null below 4 samples
    timing: str | None = None  # the loop the timed solves ran (integrators/base.py TIMING_LOOPS); null when failed
    timing_mismatch: str | None = None  # where the timed solve's own counts differ from the counted solve's
    cpu_samples: str | None = None  # JSON list: the CPU seconds of every timed solve, in the order taken (cpu_s: their median)
    contended: int | None = None  # how many of cpu_samples are the contenders' alternating rounds (harness/contend), the last ones; null: none
    budget_s: float | None = None  # the case's budget of CPU seconds (its timeout)
    budget_edge: int | None = None  # 1: ok, but its first solve took more than 1 - BUDGET_EDGE of budget_s: its status may flip between runs, and no ranking rests on it
    cpu_s_over: float | None = None  # timeout: CPU seconds its solve ran past budget_s before it was stopped (in its worker, or by killing the worker)
    cpu_s_around: float | None = None  # CPU seconds its worker spent on the case outside the timed solves: the problem built, the reference read, the errors measured
    run_id: str | None = None  # the run that stored the record: its provenance is in the runs table
    decided_by: str | None = None  # skipped: case_id of the record that decided it (null: the stiffness bound)
    skip_policy: str | None = None  # skipped: the rules that skipped it (harness/run/schedule.py POLICY); dominated: the race's too
    # Racing (harness/ranking/racing.py); null unless the case ran under a race bound
    race_target: float | None = None  # the race's target error (the run's --race-target)
    race_cpu_s: float | None = None   # the least CPU a line of the problem and set needed to reach it, when the case started
    race_bound_s: float | None = None  # the case's race bound: tau times race_cpu_s (CPU seconds)
    race_line: str | None = None      # the line that needed race_cpu_s: "label (formulation)"
    # Errors over the output times (harness/measure/metrics.py trajectory_errors); null in older stores
    err_rms: float | None = None  # root-mean-square mixed error over the output times and error components
    err_max_rel: float | None = None  # largest |y - r| / max_t |r| (pure relative, no floor) over the output times
    err_rms_rel: float | None = None  # root-mean-square of the same
    err_floor: float | None = None  # the floor (absolute scale atol/rtol) of the mixed errors, least over the error components
    final_degenerate: int | None = None  # 1: the reference's final state is within the floor of zero on every error component
    events_matched: int | None = None  # run events matched with a reference event (null without events)
    # What the report groups and draws the case by, set once from the Case's line
    # (harness/matrix/line.py Line; cases.py Case.identity); a store that lacks them
    # has them filled in when it is read (harness/matrix/store.py)
    mode: str | None = None     # "rtol" (adaptive) or "h" (fixed step): mode_of(rtol, h)
    line: str | None = None     # the line the case is a point of: its identity but rtol and h, as JSON
    label: str | None = None    # the integrator as the report names it, with its settings: "cvode-bdf (max_order=2)"
    kind: str | None = None     # the kind of system the formulation gives: ode, dae, mechanical, fmu
    family: str | None = None   # the report's panel: explicit, implicit, dae (Line.family)
    # The method's work beside the CPU (harness/measure/unit_costs.py); null in older stores,
    # for an FMU and for a case whose counted solve did not end
    njev_model: int | None = None  # analytic Jacobians the harness counted at the model (finite-difference ones are in nfev)
    work: float | None = None      # CPU seconds of the counted evaluations at the unit costs: the method's cost without its code's overhead
    overhead: float | None = None  # cpu_s / work
    unit_costs: str | None = None  # JSON: the unit costs (seconds) and iteration matrix the work was taken at
    model_calls: str | None = None  # JSON {name: calls} of the other counted model callables (projection, event functions, mass, ...)

    def __getitem__(self, name: str):
        try:
            return getattr(self, name)
        except AttributeError:
            raise KeyError(name) from None

    def __setitem__(self, name: str, value) -> None:
        if name not in FIELDS:
            raise KeyError(f"{name!r} is not a field of the record")
        setattr(self, name, value)

    def __contains__(self, name: str) -> bool:
        return name in FIELDS

    def get(self, name: str, default=None):
        """The field ``name`` (null included), or ``default`` when it is not a field."""
        return getattr(self, name) if name in FIELDS else default

    def update(self, values=(), **more) -> None:
        """Set several fields (a mapping and/or keywords); ``KeyError`` on a name
        that is not a field."""
        for name, value in {**dict(values), **more}.items():
            self[name] = value

    def keys(self):
        return FIELDS.keys()

    def to_dict(self) -> dict:
        """The record as a plain dict of its fields, in :data:`FIELDS` order."""
        return {name: getattr(self, name) for name in FIELDS}

    def row(self) -> list:
        """The values in :data:`FIELDS` order, as the store writes them."""
        return [getattr(self, name) for name in FIELDS]


# One row per run of the matrix: where, with what and how it ran (harness/matrix/provenance.py).
RUN_FIELDS = {
    "run_id": "TEXT PRIMARY KEY",
    "started": "TEXT",          # UTC ISO 8601
    "finished": "TEXT",         # null while running or when the run was killed
    "status": "TEXT",           # finished, interrupted, failed; a killed run stays "running"
    "code_version": "TEXT",
    "python": "TEXT",
    "versions": "TEXT",         # JSON: numpy, scipy, scikit-sundae, fmpy (null if absent), ..., plugins
    "cpu_model": "TEXT",        # from /proc/cpuinfo
    "cpu_count": "INTEGER",
    "threads": "TEXT",          # JSON: thread environment variables, BLAS threads per worker
    "host": "TEXT",
    "loadavg": "TEXT",          # JSON: the host's 1, 5 and 15 minute load averages at the start
    "platform": "TEXT",
    "command": "TEXT",          # the command line, or the Python call
    "backend": "TEXT",          # JSON: local jobs, or the Dask scheduler and its workers
    "options": "TEXT",          # JSON: timeout, memory limit, repeat, resume, number of cases, integrators (with settings)
    "purpose": "TEXT",          # run (a matrix), or advise (an advice's cases, kept apart by the report)
}

_SQL_TYPES = {"str | None": "TEXT", "dict | str | None": "TEXT", "float | None": "REAL", "int | None": "INTEGER"}
#: every field of the record -> its SQL type, in the store's column order (from :class:`Record`)
FIELDS = {f.name: _SQL_TYPES[f.type] for f in dataclasses.fields(Record)}

def empty_record(**known) -> Record:
    """A :class:`Record` with the fields ``known`` and every other null."""
    return Record(**known)


def mode_of(rtol, h) -> str:
    """``"rtol"`` for an adaptive case (``rtol`` set and not NaN), else ``"h"``
    (fixed step): the one definition of a case's mode, which the Case, the
    schedule and the report use."""
    return "rtol" if rtol is not None and rtol == rtol else "h"
