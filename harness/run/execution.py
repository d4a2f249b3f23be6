"""Executing one case in this process: count, solve, measure, and always a record.

:func:`execute` builds the case's system, wraps the callables the harness
counts (:func:`~integrator_bench.harness.measure.counting.counted`), solves it
once with the integrator's ``timed_solve`` (the library's own loop wherever it
can), counting and timing that one solve (the timed region holds the solve
alone; :func:`samples` adds samples when asked), compares the integrator's own
counts with the harness's (:func:`count_mismatch`) and measures the errors
against the stored reference (:mod:`integrator_bench.harness.measure.metrics`). A run that changed
what it was handed (:meth:`~integrator_bench.harness.measure.counting.Counters.changed_inputs`,
or the driver's :class:`~integrator_bench.integrators.base.InputModified`) is
``failed`` with reason ``input_modified`` and not timed. It never raises: an exception
becomes an ``error`` (or ``failed``) record. :func:`finish` sets a record's
:class:`~integrator_bench.harness.matrix.record.CaseStatus` and a typed ``reason``
beside its message (the codes of :mod:`integrator_bench.harness.matrix.record`): a
failed run's is the
:class:`~integrator_bench.integrators.base.Status` of its Solution, never a
guess from the message text, except that a run that failed, raised or ended
with non-finite values after its model returned NaN (or an infinite value)
last is ``failed`` with reason
``nonfinite_state`` and a message naming the model's NaN
(:func:`model_nonfinite`). A solve that ends but whose final-time error
exceeds :data:`~integrator_bench.harness.measure.metrics.DIVERGENCE_BOUND` is
``failed`` with reason ``diverged``, its errors kept. The warnings raised while
the case runs are counted, not printed (:func:`warnings_counted`): a summary
ends the record's message (ok records too), e.g. ``warnings: RuntimeWarning:
overflow encountered in multiply (x3)``.

No process is created here; :mod:`integrator_bench.harness.run.isolation` runs
:func:`execute` in a forked worker.
"""

from __future__ import annotations

import collections
import contextlib
import json
import math
import statistics
import time
import warnings
from datetime import datetime, timezone

import numpy as np

from integrator_bench.harness.measure import references, tripwire, unit_costs

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.cases import Case, converted
from integrator_bench.harness.measure.counting import counted
from integrator_bench.harness.errors import StepFailure
from integrator_bench.harness.measure.metrics import (divergence, event_measures, first_nonfinite, measure,
                                              monitor_error, energy_variation)
from integrator_bench.harness.matrix.record import (BUDGET_EDGE, BUILD_FAILED, EXCEPTION,
                                             INPUT_MODIFIED, NONFINITE_OUTPUT, OUT_OF_MEMORY,
                                             TIME_MISMATCH, UNSUPPORTED, CaseStatus, Record,
                                             status_value)
from integrator_bench.harness.run.streams import silenced
from integrator_bench.harness.version import code_version
from integrator_bench.integrators.base import COUNTERS, InputModified, Solution, Status
from integrator_bench.integrators.driver import Budget, budgeted
from integrator_bench.problems.system import convert

MESSAGE_CHARS = 500  # the longest message a record keeps
MIN_CPU_S = 0.2      # a case's timed solves stop once they add up to this much CPU ...
MAX_SAMPLES = 10     # ... or at this many (``--repeat N`` sets it), whichever first
IQR_SAMPLES = 4      # the fewest samples an interquartile range is given for
WARNING_KINDS = 3    # the most frequent warnings named in a message; the others are counted
#: the fields a run stopped at its budget leaves null: what it counted up to a point
#: that depends on the CPU's speed
PARTIAL_FIELDS = (*COUNTERS, "nevents", "solver_counts", "count_mismatch")


def now() -> str:
    """The current UTC time, ISO 8601 to the second (the record's ``created``)."""
    return datetime.now(timezone.utc).isoformat(timespec="seconds")


def base_record(case: Case) -> Record:
    """A record of ``case`` with its identity (:meth:`Case.identity`) and code
    version, nothing measured."""
    return Record(**case.identity(), code_version=code_version())


def finish(record: dict, status: CaseStatus, message: str = "", reason: str | None = None) -> dict:
    """Set the outcome of ``record``: status (stored as its string value), message,
    the fixed ``reason`` code, time."""
    record.update(status=status_value(status), message=message or None, reason=reason,
                  created=now())
    return record


def model_nonfinite(counters) -> str | None:
    """``"the model returned NaN (fun at t=0.31)"`` when the last value a counted
    callable of the system returned was not finite, else None.

    Read once a run has failed: an integrator that gives up right after the
    model's NaN (rejecting and shrinking the step until it underflows, say)
    ended because of it, whatever its own status says.
    """
    for key, what in (("nfev", "function"), ("njev", "Jacobian")):
        counter = counters.get(key)
        if counter is None or counter.last is None:
            continue
        t, out = counter.last
        try:
            values = np.asarray(out.toarray() if hasattr(out, "toarray") else out, float)
        except (TypeError, ValueError):
            continue
        if not np.all(np.isfinite(values)):
            kind = "NaN" if np.isnan(values).any() else "an infinite value"
            at = f" at t={t:.6g}" if isinstance(t, (int, float)) else ""
            return f"the model returned {kind} ({what}{at})"
    return None


def execute(case: Case, reference_dir=None, repeat: int = MAX_SAMPLES,
            memory_mb: float | None = None, budget_s: float | None = None) -> dict:
    """Run one case here and return its record; never raises.

    One solve, counted and timed (:func:`_timed_solves`): the integrator's
    ``timed_solve`` (rule 8 of :mod:`integrator_bench.integrators.base`, the
    library's own loop wherever it honours the system) on the system whose
    callables count their calls gives the counts, errors, events and the first
    timing sample; a successful one is sampled again until ``repeat`` samples
    or :data:`MIN_CPU_S` CPU seconds, whichever
    first (:func:`samples`), within ``budget_s`` CPU seconds (the case's
    budget): ``cpu_s`` and ``wall_s`` are the medians, ``cpu_s_min`` the least,
    ``cpu_s_iqr`` the interquartile range (:func:`sample_record`), ``timing``
    the loop that ran and ``timing_mismatch`` where a later sample's own counts
    differ from the first one's. ``memory_mb`` is the per-case memory limit in force (set by
    the isolating worker), named in an out-of-memory message. The warnings
    raised meanwhile are summarized at the end of the message. ``cpu_s_around``
    is the CPU this process spent on the case outside its timed solves.
    """
    record = base_record(case)
    record["budget_s"] = budget_s
    if case.unsupported:
        return finish(record, CaseStatus.UNSUPPORTED, case.unsupported, UNSUPPORTED)
    if case.fault:   # its problem failed to build (raised, crashed or hung) in its trial
        status, why = case.fault
        return finish(record, CaseStatus(status), f"not run: {why}"[:MESSAGE_CHARS],
                      BUILD_FAILED)
    cpu0, solved0 = time.process_time(), tripwire.solved()
    with warnings_counted() as seen:
        try:
            record = _run(case, record, reference_dir, repeat, budget_s)
        except Exception as exc:  # any exception is a record, never a crash of the run
            record = _exception_record(record, exc, memory_mb)
    record["budget_edge"] = budget_edge(record)
    record["cpu_s_around"] = (time.process_time() - cpu0) - (tripwire.solved() - solved0)
    return add_to_message(record, warnings_summary(seen))


def budget_edge(record) -> int | None:
    """1 when ``record`` is ``ok`` but its first solve (the one its status rests on)
    took more than ``1 -`` :data:`~integrator_bench.harness.matrix.record.BUDGET_EDGE`
    of its ``budget_s``: a slower run of the same case would be a ``timeout``. 0
    for another ok record with a budget; None otherwise."""
    if record.get("status") != CaseStatus.OK or not record.get("budget_s") \
            or not record.get("cpu_samples"):
        return None
    first = json.loads(record["cpu_samples"])[0]
    return int(first > (1 - BUDGET_EDGE) * record["budget_s"])


def add_to_message(record: dict, note: str | None) -> dict:
    """Append ``note`` (when there is one) to ``record``'s message, ``"; "``-joined
    and cut at :data:`MESSAGE_CHARS`; return the record."""
    if note:
        record["message"] = "; ".join(filter(None, (record["message"], note)))[:MESSAGE_CHARS]
    return record


_SHOWN = ("default", "module", "once")  # filter actions that print a warning (at least once)


@contextlib.contextmanager
def warnings_counted():
    """Count the warnings raised inside the block instead of printing them.

    Every occurrence that the filters in force would print is counted (their
    ``default``, ``module`` and ``once`` act as ``always``); an ignored warning
    stays ignored and an ``error`` filter still raises. The filters, the
    default action and ``showwarning`` are restored on leaving.

    Yields
    ------
    collections.Counter
        ``"Category: first line of the message"`` -> occurrences.
    """
    counts = collections.Counter()

    def count(message, category, filename, lineno, file=None, line=None):
        text = str(message).strip().splitlines()
        counts[f"{category.__name__}: {text[0][:120]}" if text else category.__name__] += 1

    default = warnings.defaultaction
    with warnings.catch_warnings():  # restores the filters and showwarning
        warnings.filters[:] = [("always" if f[0] in _SHOWN else f[0], *f[1:])
                               for f in warnings.filters]
        warnings.defaultaction = "always"
        warnings.showwarning = count
        try:
            yield counts
        finally:
            warnings.defaultaction = default


def warnings_summary(counts: collections.Counter, title: str = "warnings") -> str | None:
    """``"warnings: RuntimeWarning: overflow encountered in multiply (x3); ..."``.

    The :data:`WARNING_KINDS` most frequent kinds with their counts, then how
    many other kinds there were; None when there were no warnings. ``title``
    names what was counted (the isolating worker summarizes the lines a case
    wrote to its standard output and error as ``"output"``).
    """
    if not counts:
        return None
    parts = [f"{text} (x{n})" for text, n in counts.most_common(WARNING_KINDS)]
    others = len(counts) - WARNING_KINDS
    if others > 0:
        parts.append(f"{others} other kind{'s' * (others > 1)}")
    return f"{title}: " + "; ".join(parts)


def _run(case: Case, record: dict, reference_dir, repeat, budget_s) -> dict:
    problem = case.spec.build(here=True)   # the case runs here: its model's code too
    icls = registry.get_integrator(case.integrator)
    formulated = problem.formulate(case.formulation)
    if formulated.kind != record.kind:  # a case built without its kind (outside expand)
        record.update(case.identity(formulated.kind))
    system, why = converted(formulated, icls, case.formulation, case.rtol, case.h)
    if why:
        return finish(record, CaseStatus.UNSUPPORTED, why, UNSUPPORTED)
    costs = unit_costs.costs_of(problem, case.formulation, system)  # on the bare system
    system, counters = counted(system)

    def fresh():   # a problem with modes (or an FMU) keeps them in its system
        return counted(convert(problem.formulate(case.formulation), icls))[0]

    try:
        sol, over_budget = _timed_solves(record, icls, system, case, repeat, counters,
                                         fresh, budget_s)
    except Exception as exc:
        changed = counters.changed_inputs(system)
        if changed and not isinstance(exc, InputModified):
            raise InputModified(f"{changed}; then {_why(exc)}") from exc
        nonfinite = model_nonfinite(counters)
        if nonfinite is None or isinstance(exc, InputModified):
            raise
        # the model's NaN ended the run, whatever the integrator raised about it
        return finish(record, CaseStatus.FAILED, f"{nonfinite}; {_why(exc)}"[:MESSAGE_CHARS],
                      Status.NONFINITE_STATE.value)
    if sol.status is Status.OVER_BUDGET:
        # where a run was stopped depends on how fast the CPU ran it: its partial
        # counts would make the record depend on the machine's load
        record.update(dict.fromkeys(PARTIAL_FIELDS))
        return finish(record, CaseStatus.TIMEOUT, sol.message[:MESSAGE_CHARS],
                      Status.OVER_BUDGET.value)
    record.update(work_fields(record, costs, counters))
    if sol.status is not Status.SUCCESS:
        message = sol.message or f"integrator gave up ({sol.status.value})"
        nonfinite = model_nonfinite(counters)
        if nonfinite:   # the model's NaN ended the run: say so, whatever the integrator says
            return finish(record, CaseStatus.FAILED, f"{nonfinite}; {message}"[:MESSAGE_CHARS],
                          Status.NONFINITE_STATE.value)
        return finish(record, CaseStatus.FAILED, message, sol.status.value)
    Y = np.asarray(system.output(sol.t, sol.y), float) if len(sol.t) else np.empty((0, 0))
    where = first_nonfinite(sol.t, Y, problem.components)
    if where:
        nonfinite = model_nonfinite(counters)
        if nonfinite:
            return finish(record, CaseStatus.FAILED, f"{nonfinite}; the integrator reported "
                          f"success with a {where}", Status.NONFINITE_STATE.value)
        return finish(record, CaseStatus.FAILED, f"the integrator reported success with a "
                      f"{where}", NONFINITE_OUTPUT)
    events = references.canonical_events(system, sol.events)
    record = _measured(record, problem, sol, Y, reference_dir, events)
    if over_budget and record["status"] == CaseStatus.OK:
        return finish(record, CaseStatus.TIMEOUT, over_budget, Status.OVER_BUDGET.value)
    return record


def work_fields(record, costs, counters) -> dict:
    """The record's ``njev_model``, ``model_calls``, ``work``, ``overhead`` and ``unit_costs`` of a
    solve whose counts and CPU it holds, at the unit costs ``costs``
    (:mod:`~integrator_bench.harness.measure.unit_costs`; all null without them)."""
    if costs is None:
        return {}
    jev = counters["njev"]
    njev_model = jev.n if jev is not None else 0
    counted_as = {id(counters[k]) for k in ("nfev", "njev") if counters[k] is not None}
    calls = {name: tally.n for name, tally in counters.calls.items()
             if id(tally) not in counted_as and tally.n}
    work = unit_costs.work(costs, record["nfev"], njev_model, record["nlu"], record["nniter"],
                           calls)
    return dict(njev_model=njev_model, work=work,
                overhead=unit_costs.overhead(record["cpu_s"], work),
                unit_costs=costs.to_json(), model_calls=json.dumps(calls, sort_keys=True))


def atol_of(system, rtol):
    """The absolute tolerance per state at ``rtol`` (None without a tolerance: a
    fixed step): computed once per case, for all its solves."""
    return system.atol(rtol) if rtol is not None else None


def _timed_solves(record, icls, system, case, repeat, counters, fresh, budget_s):
    """One solve, counted and timed: run the ``run`` of
    :meth:`~integrator_bench.integrators.base.Integrator.timed_call` (the
    library's own loop over the output times wherever it honours the system,
    else the segment runner or the shared driver: rule 8 of
    :mod:`integrator_bench.integrators.base`), timing it alone, on the counted ``system`` at
    the case's ``atol`` (:func:`atol_of`, recorded, the same for every sample), whose
    callables count their calls at the model
    (:func:`~integrator_bench.harness.measure.counting.counted`); record its
    counts (:func:`_fill_counts`: the harness's ``nfev``/``njev``, the code's own
    other counters) and its process CPU as the case's first timing sample.
    Return the solution, and a message when the case is over its budget.

    ``budget_s`` is the case's budget in CPU seconds of this process (the
    isolating worker's; None: none): a run fed through the segment runner or
    the driver is stopped at its first accepted step past it
    (:class:`~integrator_bench.integrators.driver.Budget` on
    ``time.process_time``, ``Status.OVER_BUDGET``), and any loop at the budget
    by the tripwire (:func:`solve_timed`); ``cpu_s_over`` is the CPU it ran past
    it. One that succeeds having used more than ``budget_s`` (between the budget
    and the tripwire's ring) is over it too: the message says so, and the case
    becomes a ``timeout`` with its errors and counts kept. So the outcome
    depends on the CPU the case used, not on the machine's load.

    More samples (``repeat`` at most, until they add up
    to :data:`MIN_CPU_S`) re-run the same loop on a fresh counted system from
    ``fresh()`` (a problem with modes, or an FMU, ends a run in its last
    mode), within what is left of the budget (:func:`samples`; each armed with
    it). A sample that
    ends otherwise than the first (:func:`different_work`) did other work: the
    record keeps the first solve's time alone and ``timing_mismatch`` says
    why; otherwise ``timing_mismatch`` names a counter the code reports
    differently from one run to the next (:func:`timing_mismatch`).
    """
    settings = case.settings_dict      # every solve with a fresh integrator so set
    atol = atol_of(system, case.rtol)
    record["atol"] = float(np.min(atol)) if atol is not None else None
    spent = [0.0]                      # CPU of the timed solves so far

    def solve(target, where=None):
        out = solve_timed(icls, settings, target, case, atol,
                          None if budget_s is None else budget_s - spent[0], where)
        spent[0] += out[1]
        return out

    def last_t():   # the time of the model's last call (where a stopped run was)
        tally = counters["nfev"]
        return tally.last[0] if tally is not None and tally.last is not None else None

    loop = icls(**settings).timing_loop(system)
    with budgeted(None if budget_s is None else Budget(budget_s, clock=time.process_time)):
        sol, cpu, wall = solve(system, last_t)
    _fill_counts(record, sol.counts, counters, icls)
    changed = counters.changed_inputs(system)
    if changed:            # the run's figures rest on inputs it changed
        raise InputModified(changed)
    record["timing"] = loop
    cpus, walls, over_budget = [cpu], [wall], None
    if budget_s is not None and (cpu > budget_s or sol.status is Status.OVER_BUDGET):
        record["cpu_s_over"] = max(cpu - budget_s, 0.0)
    if sol.status is Status.SUCCESS and budget_s is not None and cpu > budget_s:
        over_budget = (f"the solve took {cpu:.3g} s of CPU, past the case's budget of "
                       f"{budget_s:g} s; the errors and counts are kept")
    elif sol.status is Status.SUCCESS and repeat > 1 and cpu < MIN_CPU_S:
        again = []

        def run():
            target = fresh()    # formulated and counted outside the timed region
            out, cpu, wall = solve(target)
            again.append(out)
            return cpu, wall
        left = None if budget_s is None else budget_s - cpu
        with warnings.catch_warnings(), silenced():  # the first solve has said it all once
            warnings.simplefilter("ignore")
            more_cpus, more_walls = samples(run, repeat - 1, MIN_CPU_S - cpu, left)
        differs = next(filter(None, (different_work(sol, b) for b in again)), None)
        record["timing_mismatch"] = differs or timing_mismatch(sol, again[0])
        if not differs:
            cpus, walls = cpus + more_cpus, walls + more_walls
    record.update(sample_record(cpus, walls))
    return sol, over_budget


def solve_timed(icls, settings: dict, system, case: Case, atol, budget_s: float | None = None,
                where=None):
    """One timed solve of ``case`` on ``system`` at ``atol`` (the case's,
    :func:`atol_of`) by a fresh ``icls(**settings)``:
    its :class:`~integrator_bench.integrators.base.Solution`, CPU and wall
    seconds. Only the library call is timed (the library's options made before
    it, its counters read after it: rule 8 of :mod:`integrator_bench.integrators.base`);
    every timed solve of a case, the matrix's and the contenders' rounds
    (:mod:`integrator_bench.harness.run.resample`), is this one.

    Within ``budget_s`` CPU seconds (None: none), whatever loop runs
    (:func:`~integrator_bench.harness.measure.tripwire.armed`): a solve whose
    budget was spent is ``Status.OVER_BUDGET``, however the library then ended,
    its message saying where it was stopped (``where()``: the time of the model's
    last call, or None) and after how much CPU."""
    call = icls(**settings).timed_call(system, rtol=case.rtol, atol=atol, h=case.h)
    wall0 = time.perf_counter()
    try:
        with tripwire.armed(budget_s) as trip:
            out, cpu, wall = timed(call.run)
    except tripwire.OverBudget:
        pass
    if trip.spent_at is None:
        return call.finish(out), cpu, wall
    cpu, wall = time.process_time() - trip.start, time.perf_counter() - wall0
    t = where() if where is not None else None
    message = (Budget(budget_s, trip.start, clock=time.process_time).verdict(
        system.t0, system.t_end, t) if t is not None else
        f"stopped after {cpu:.3g} s of CPU, past its budget of {budget_s:.3g} s")
    return Solution(np.empty(0), np.empty((0, 0)), message=message,
                    status=Status.OVER_BUDGET), cpu, wall


def timed(solve):
    """``(solve(), CPU seconds, wall seconds)`` of one call of ``solve``."""
    cpu0, wall0 = time.process_time(), time.perf_counter()
    out = solve()
    return out, time.process_time() - cpu0, time.perf_counter() - wall0


def samples(run, max_samples: int, min_cpu: float = 0.0, budget_s: float | None = None):
    """Time ``run`` until ``max_samples`` samples or ``min_cpu`` CPU seconds in all,
    whichever comes first, as pyperf calibrates (one sample at least).

    Parameters
    ----------
    run : callable
        ``run() -> (cpu_s, wall_s)``: one timed solve.
    max_samples : int
        The most samples (``--repeat``, :attr:`~integrator_bench.harness.run.limits.Limits.repeat`).
    min_cpu : float
        Stop once the samples add up to this much CPU (:data:`MIN_CPU_S`).
    budget_s : float, optional
        CPU seconds the samples may take: no sample is started that would
        end past it, at the last sample's pace (what the case's budget leaves
        after its first solve).

    Returns
    -------
    (list of float, list of float)
        CPU and wall seconds of each sample.
    """
    cpus, walls = [], []
    while True:
        cpu, wall = run()
        cpus.append(cpu)
        walls.append(wall)
        if len(cpus) >= max_samples or sum(cpus) >= min_cpu:
            return cpus, walls
        if budget_s is not None and sum(cpus) + cpu > budget_s:
            return cpus, walls


def sampled_cpu(cpu: float, repeat: int) -> float:
    """The CPU a case's timed solves add up to when each takes ``cpu`` seconds:
    :func:`samples`' rule as :func:`_timed_solves` applies it (one solve, then more
    until they add up to :data:`MIN_CPU_S` or number ``repeat``), what the plan and
    the scheduler predict a case to cost from the CPU of one solve."""
    if not cpu > 0 or cpu >= MIN_CPU_S or repeat <= 1:
        return cpu
    return cpu * min(repeat, math.ceil(MIN_CPU_S / cpu))


def sample_record(cpus, walls) -> dict:
    """The record's timing fields of the samples ``cpus``/``walls``: ``cpu_s``
    and ``wall_s`` their medians, ``cpu_s_min`` the least, ``cpu_s_iqr`` the
    interquartile range of the CPU (numpy's linear percentiles; null with fewer
    than :data:`IQR_SAMPLES` samples), ``repeat`` their number and
    ``cpu_samples`` the CPU samples themselves (JSON, in the order taken)."""
    iqr = (float(np.subtract(*np.percentile(cpus, [75, 25])))
           if len(cpus) >= IQR_SAMPLES else None)
    return dict(cpu_s=statistics.median(cpus), cpu_s_min=min(cpus), cpu_s_iqr=iqr,
                wall_s=statistics.median(walls), repeat=len(cpus),
                cpu_samples=json.dumps([float(c) for c in cpus]))


def different_work(counted, bare) -> str | None:
    """``"the timed solve ended newton_failure with 1 outputs, the counted one
    success with 101"`` when the timed (bare) solve ended with another status or
    another number of outputs than the counted one: it did not do the work
    counted, and its CPU ranks nothing. None when both end alike."""
    if bare.status is not counted.status or len(bare.t) != len(counted.t):
        return (f"the timed solve ended {bare.status.value} with {len(bare.t)} outputs, "
                f"the counted one {counted.status.value} with {len(counted.t)}")
    return None


def timing_mismatch(counted, bare) -> str | None:
    """Where the timed (bare) solve differs from the counted one: its status, its
    number of outputs (:func:`different_work`), or a counter both report
    (``"nfev: counted 120, timed 118"``); None when they agree. The
    integrator's own counters are compared (``Solution.counts``), never the
    harness's."""
    differs = different_work(counted, bare)
    if differs:
        return differs
    found = [f"{k}: counted {counted.counts[k]}, timed {bare.counts[k]}"
             for k in COUNTERS if counted.counts.get(k) is not None
             and bare.counts.get(k) is not None and counted.counts[k] != bare.counts[k]]
    return "; ".join(found) or None


def _measured(record, problem, sol, Y, reference_dir, events=()) -> dict:
    """Errors and drift against the stored reference; an ``ok`` record, or a
    ``failed`` one (reason ``diverged``) past the divergence bound.

    ``events`` are the Solution's events with canonical states
    (:func:`~integrator_bench.harness.measure.references.canonical_events`); when the
    reference records an event sequence (a problem with events), the record gets
    the event measures of :func:`~integrator_bench.harness.measure.metrics.event_measures`
    against it (they stay null otherwise)."""
    # the reference only after the solve: an integrator's own failure is never
    # hidden behind a missing reference
    ref = references.load(problem, reference_dir, compute_missing=False)
    if len(sol.t) != len(ref.t) or not np.allclose(sol.t, ref.t, rtol=0, atol=1e-12):
        return finish(record, CaseStatus.ERROR, "solution times do not match the output times",
                      TIME_MISMATCH)
    groups = {"error": problem.component_index(problem.error_components),
              "velocity": problem.component_index(problem.velocity_components),
              "lambda": problem.component_index(problem.lambda_components)}
    record.update(measure(Y, ref.Y, problem.atol_scale_vector(), groups))
    if ref.has_events:   # on the declared error components, whatever score= names
        record.update(event_measures(
            list(events), ref.events, problem.atol_scale_vector(),
            problem.component_index(problem.declared_error_components)))
    P = problem.monitor(sol.t, Y)
    if P is not None:
        t_start = problem.t_span[0] if problem.monitor_start is None else problem.monitor_start
        E = monitor_error(P, problem.monitor(ref.t, ref.Y), sol.t, t_start)
        record["monitor_err"] = E if np.isfinite(E) else None
    record["energy_var"] = energy_variation(problem, sol.t, Y)
    drift = problem.constraint_residuals(sol.t, Y)
    if drift is not None:
        record["drift_pos"], record["drift_vel"] = (float(np.max(d)) for d in drift)
    record["reference"] = ref.id
    diverged = divergence(record["mescd"])
    if diverged:
        return finish(record, CaseStatus.FAILED, diverged, Status.DIVERGED.value)
    return finish(record, CaseStatus.OK)


def _exception_record(record: dict, exc: Exception, memory_mb: float | None) -> dict:
    """The record of a solve that raised, typed by the exception's class.

    An :class:`~integrator_bench.integrators.base.InputModified` (the integrator
    changed what it was handed) is a ``failed`` run with reason
    ``input_modified``; a :class:`StepFailure` that escaped the integrator is a
    ``failed`` run with its status; arithmetic overflow in the problem's functions (OverflowError,
    FloatingPointError) a ``failed`` run that ``diverged``; MemoryError an
    ``error`` with reason ``out_of_memory``; anything else an ``error`` with
    reason ``exception``.
    """
    why = _why(exc)
    if isinstance(exc, InputModified):
        return finish(record, CaseStatus.FAILED, f"the integrator changed its inputs: {exc}"
                      [:MESSAGE_CHARS], INPUT_MODIFIED)
    if isinstance(exc, StepFailure):
        return finish(record, CaseStatus.FAILED, why[:MESSAGE_CHARS], exc.status.value)
    if isinstance(exc, (OverflowError, FloatingPointError)):
        return finish(record, CaseStatus.FAILED, f"diverged ({why})"[:MESSAGE_CHARS],
                      Status.DIVERGED.value)
    if isinstance(exc, MemoryError):
        limit = f" of {memory_mb:g} MB" if memory_mb else ""
        return finish(record, CaseStatus.ERROR, f"out of memory (per-case limit{limit}): {why}"
                      [:MESSAGE_CHARS], OUT_OF_MEMORY)
    return finish(record, CaseStatus.ERROR, why[:MESSAGE_CHARS], EXCEPTION)


def _why(exc: Exception) -> str:
    """``"ValueError: first line of the message"``."""
    return f"{type(exc).__name__}: {exc}".splitlines()[0] if str(exc) else type(exc).__name__


def _fill_counts(record, counts, counters, icls) -> None:
    """The counts of ``record``: ``nfev`` as counted by the harness, ``njev`` the
    integrator's if it reports one (else the harness's), the rest as reported;
    the integrator's own counters kept in ``solver_counts`` and a disagreement
    in ``count_mismatch``."""
    counts = {k: int(v) for k, v in counts.items() if v is not None}
    record["solver_counts"] = counts
    fev, jev = counters["nfev"], counters["njev"]
    # a system whose calls the harness cannot see (an FMU simulated by its tool)
    # has no counter: its integrator's own count stands
    record["nfev"] = fev.n if fev is not None else counts.get("nfev")
    if "njev" in counts:
        record["njev"] = counts["njev"]
    elif icls.uses_jacobian or not icls.implicit:
        record["njev"] = jev.n if jev is not None else 0
    for key in ("nlu", "nsteps", "nreject", "nniter", "nnfail", "nevents"):
        record[key] = counts.get(key)
    record["count_mismatch"] = count_mismatch(counts, counters, icls)


def count_mismatch(counts: dict, counters: dict, icls) -> str | None:
    """Where an integrator's own ``nfev``/``njev`` disagree with the harness's count.

    The harness counts every call of the system's callables. An integrator
    that evaluates no finite-difference Jacobian of its own (an explicit one,
    or one that uses the system's Jacobian, which is given) must report
    exactly the calls counted; otherwise its ``nfev`` may leave out the
    finite-difference calls, so it must not exceed the harness's. ``njev`` is
    compared, exactly, only for an integrator that uses the given Jacobian
    (another's counts finite-difference Jacobians, which the harness sees as
    ``nfev``).

    Returns
    -------
    str or None
        ``"nfev: own 120, harness 240"`` (``"; "``-joined when both
        disagree), or None when the counts agree or are not reported.
    """
    has_jac = counters["njev"] is not None
    exact_nfev = not icls.implicit or (icls.uses_jacobian and has_jac)
    checks = [("nfev", exact_nfev)] + ([("njev", True)] if icls.uses_jacobian else [])
    found = []
    for key, exact in checks:
        own, counter = counts.get(key), counters[key]
        if own is None or counter is None:
            continue
        if (own != counter.n) if exact else (own > counter.n):
            found.append(f"{key}: own {own}, harness {counter.n}")
    return "; ".join(found) or None
