"""The budgeted search: successive halving with each line's rtol calibrated to the target.

Measured, never predicted: every point of a line is a run of the run engine
(:meth:`integrator_bench.harness.run.runner.Session.run`), a record in the store, and
a record of the same case and code version already in the store is reused
instead of run again (so an interrupted search goes on where it stopped).

Round 0 runs every candidate at a loose tolerance (:func:`start_rtol`). After
each round every line still in the search is ranked by its CPU to the target:
measured where the line has reached it (the report's crossing,
:func:`integrator_bench.harness.ranking.reach.reach_line`: interpolated
between the points either side, or the CPU of its first point below the target
as an upper bound), extrapolated otherwise along the line's own slope of log
CPU against log error between its two tightest points (:data:`DEFAULT_SLOPE`
with one point). The most promising half stays (at least :data:`KEEP_AT_LEAST`
lines, and the best line of each family, so that every family has its
alternative), the rest leaves the search with its rank as the reason. Each
line that stays proposes its next tolerance (:func:`next_rtol`): tighter,
extrapolated along its slope of log error against log rtol, until its errors
bracket the target; then the tolerance its bracket calls for, interpolated
(log-log, aiming at :data:`AIM` times the target); a line whose cheapest run
below the target lies within :data:`CLOSE` of it, or whose bracket is within a
factor :data:`NARROW` in rtol, is calibrated and runs no more. A line whose runs
all failed (diverged at a loose rtol, say), or ended ``ok`` having missed or
added an event (a bounce stepped over), tries once more :data:`RETRY_FACTOR`
tighter, whatever its rank; one that timed out leaves. The search ends
when no line proposes a run, or when the budget is spent: then the answer is
partial.

The error of a record is the chosen measure (``max``: ``err_max``, the largest
mixed error over the output times; ``final``: ``10^-mescd``), as the report reads
it (:func:`integrator_bench.harness.ranking.reach.error_values`); a run that
missed or added an event has an infinite error.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from integrator_bench.harness.advise.candidates import Candidate
from integrator_bench.harness.matrix.line import FAMILY_WORDS
from integrator_bench.harness.ranking import reach
from integrator_bench.harness.run.runner import process_cpu

RTOL_LOOSEST, RTOL_TIGHTEST = 1e-1, 1e-13
DEFAULT_SLOPE = -0.25  # d log CPU / d log error of a line with one point (order ~4)
AIM = 0.7              # a calibrated tolerance aims at this fraction of the target
CLOSE = 1 / 3          # a run at or below the target and above CLOSE * target is calibrated
NARROW = 2.0           # a bracket within this factor in rtol is calibrated
KEEP_AT_LEAST = 2      # lines kept by a halving, at the least
MAX_RUNS = 8           # runs of one line, at most
RETRIES = 1            # a line whose runs all failed (diverged, ...) tries again this often ...
RETRY_FACTOR = 100.0   # ... at this much tighter an rtol
CASE_TIMEOUT = (2.0, 120.0)  # the per-case timeout of a round, least and most (seconds)


@dataclass
class Line:
    """A candidate's course through the search."""

    candidate: Candidate
    out: str | None = None       # why it left the search (None: still in, or kept to the end)
    calibrated: bool = False     # its rtol is calibrated to the target: no more runs

    @property
    def key(self) -> tuple:
        return self.candidate.key


@dataclass
class SearchResult:
    """What the search found: its lines, all their records, its cost, and the cases
    it ran (``ran``: those of the records, which the contenders' rounds time again)."""

    lines: list
    records: pd.DataFrame
    target: float
    measure: str
    rounds: int = 0
    partial: str | None = None   # why the search stopped before it was done
    wall_s: float = 0.0
    cpu_s: float = 0.0
    cases: int = 0
    ran: list = field(default_factory=list)


def start_rtol(target: float) -> float:
    """The first tolerance of every line: ``10^floor(log10(target) / 2)`` within
    1e-8 ... 1e-2 (1e-3 for a target of 1e-6 or 1e-5, 1e-2 for 1e-3)."""
    return min(1e-2, max(1e-8, 10.0 ** math.floor(math.log10(target) / 2)))


def case_timeout(seconds: float, parallel: int, cases: int) -> float:
    """The per-case timeout of a round of ``cases`` with ``seconds`` of the budget
    left on ``parallel`` workers: an equal share, within :data:`CASE_TIMEOUT` and
    never past what is left."""
    return min(max(seconds * parallel / max(cases, 1), CASE_TIMEOUT[0]), CASE_TIMEOUT[1],
               seconds)


def round_rtol(rtol: float) -> float:
    """Two significant digits, so that a repeated search asks for the same cases."""
    return float(f"{min(max(rtol, RTOL_TIGHTEST), RTOL_LOOSEST):.2g}")


#: the columns of a record that make a search line's key (:attr:`Candidate.key`): the
#: search's lines are all of one problem and adaptive
SEARCH_LINE = ["label", "formulation"]
#: the points of a line with none (:func:`points_by_line` has no entry for it)
NO_POINTS = pd.DataFrame({"err": [], "tol": [], "cpu_s": []})


def points(rows: pd.DataFrame, measure: str) -> pd.DataFrame:
    """The ok records of one line with a finite error and a positive CPU, loose to tight."""
    if rows.empty:
        return rows.assign(err=[], tol=[])
    pts = reach.line_points(rows, measure)
    return pts[np.isfinite(pts["err"])].sort_values("tol", ascending=False)


def _slope(x, y, default: float, low: float, high: float) -> float:
    """d log y / d log x between the last two points (``default`` when it cannot be
    had), clipped to [low, high]."""
    if len(x) >= 2 and x[-1] > 0 and x[-2] > 0 and y[-1] > 0 and y[-2] > 0 \
            and x[-1] != x[-2]:
        s = (math.log(y[-1]) - math.log(y[-2])) / (math.log(x[-1]) - math.log(x[-2]))
        if math.isfinite(s):
            return min(max(s, low), high)
    return default


def predicted_cpu(pts: pd.DataFrame, target: float) -> float:
    """The line's CPU to reach ``target`` (module docstring); inf without a point."""
    if pts.empty:
        return math.inf
    err, cpu = pts["err"].to_numpy(float), pts["cpu_s"].to_numpy(float)
    if (err <= target).any():
        return reach.reach_line(err, cpu, target)["cpu_s"]
    e, c = err[-2:], cpu[-2:]
    s = _slope(e, c, DEFAULT_SLOPE, -2.0, -0.05) if len(e) == 2 and e[1] < e[0] \
        else DEFAULT_SLOPE
    return float(c[-1] * (target / e[-1]) ** s)


def next_rtol(pts: pd.DataFrame, rows: pd.DataFrame, target: float, first: float):
    """The line's next tolerance, or a reason it runs no more.

    Returns
    -------
    (float or None, str or None, bool)
        The tolerance to run (None: none), why the line leaves the search (None:
        it stays), and whether it is calibrated.
    """
    tried = set(pd.to_numeric(rows["rtol"], errors="coerce")) if len(rows) else set()
    if not len(rows):
        return first, None, False
    if pts.empty:
        rtol = pd.to_numeric(rows["rtol"], errors="coerce")
        last = rows.loc[rtol.idxmin()]
        events = _event_errors(last)
        if (len(rows) <= RETRIES and (last["status"] == "failed" or events)
                and float(last["rtol"]) / RETRY_FACTOR >= RTOL_TIGHTEST):
            return round_rtol(float(last["rtol"]) / RETRY_FACTOR), None, False
        if events:
            return None, f"{events} at rtol {float(last['rtol']):.2g}, the tightest tried", False
        return None, f"no usable run ({last['status']}: {str(last['message'] or '')[:80]})", False
    if len(rows) >= MAX_RUNS:
        return None, None, bool((pts["err"] <= target).any())
    tol, err = pts["tol"].to_numpy(float), pts["err"].to_numpy(float)
    slope = _slope(tol, np.maximum(err, 1e-300), 1.0, 0.3, 1.5)
    below = np.flatnonzero(err <= target)
    if not below.size:
        k = int(np.argmin(tol))
        if tol[k] <= RTOL_TIGHTEST * 1.01:
            return None, f"error {err[k]:.2g} at rtol {tol[k]:.2g}, the tightest tried", False
        if _stalled(tol, err):
            return None, (f"error does not fall with rtol ({err[k]:.2g} at rtol "
                          f"{tol[k]:.2g})"), False
        r = tol[k] * (AIM * target / err[k]) ** (1 / slope)
        r = round_rtol(min(max(r, tol[k] / 1e3), tol[k] / 3))
        return (None, "no tighter rtol to try", False) if r in tried else (r, None, False)
    b = int(below[np.argmax(tol[below])])          # the loosest run below the target
    if err[b] >= CLOSE * target:
        return None, None, True
    looser = [i for i in range(len(tol)) if tol[i] > tol[b] and err[i] > target]
    if not looser:
        if tol[b] >= RTOL_LOOSEST:
            return None, None, True
        r = round_rtol(min(tol[b] * (AIM * target / err[b]) ** (1 / slope), tol[b] * 1e3))
    else:
        a = min(looser, key=lambda i: tol[i])
        if tol[a] / tol[b] <= NARROW:
            return None, None, True
        w = math.log(AIM * target / err[a]) / math.log(err[b] / err[a])
        r = round_rtol(math.exp(math.log(tol[a]) + w * (math.log(tol[b]) - math.log(tol[a]))))
        if not tol[b] < r < tol[a]:
            return None, None, True
    return (None, None, True) if r in tried else (r, None, False)


def _stalled(tol: np.ndarray, err: np.ndarray) -> bool:
    """Whether a line's error has stopped falling as its rtol tightens: its two
    tightest runs give the same error (a code that does not respond to rtol), or
    its tightest is no better than 0.9 times the better of the two before it. One
    rise is not enough: a high-order code taking a few long steps has an error at
    the output times that need not fall monotonically (DOP853 on a Van der Pol
    oscillator: 1.1e-4 at rtol 1e-3, 4.8e-4 at 1e-4, 6.1e-6 at 1e-5)."""
    order = np.argsort(tol)
    if len(order) < 2:
        return False
    if err[order[0]] == err[order[1]]:
        return True
    return len(order) >= 3 and err[order[0]] >= 0.9 * min(err[order[1]], err[order[2]])


def _event_errors(record) -> str | None:
    """``"missed 2 events"``, ``"added 1 event"`` (or both) for a run that ended
    ``ok`` with other events than the reference's (it reaches no target, whatever
    its error); None otherwise."""
    if record.get("status") != "ok":
        return None
    words = []
    for field, verb in (("events_missed", "missed"), ("events_spurious", "added")):
        n = pd.to_numeric(record.get(field), errors="coerce")
        if pd.notna(n) and n > 0:
            words.append(f"{verb} {int(n)} event{'s' if n > 1 else ''}")
    return " and ".join(words) or None


def by_line(records: pd.DataFrame) -> dict:
    """``records`` split by line: ``(label, formulation)`` (a :attr:`Line.key`, the
    records' ``label``, which a session's records all have) -> its records."""
    if records.empty:
        return {}
    groups = records.groupby(SEARCH_LINE, sort=False).indices
    return {key: records.iloc[idx] for key, idx in groups.items()}


def points_by_line(records: pd.DataFrame, measure: str) -> dict:
    """:func:`points` of every line of ``records`` at once: key -> its points."""
    if records.empty:
        return {}
    pts = points(records, measure)
    return {key: group for key, group in pts.groupby(SEARCH_LINE, sort=False)}


def keep_half(ranked: list, target_cpu: dict, retrying: dict) -> set:
    """The keys of the lines that stay: the better half by predicted CPU (at least
    :data:`KEEP_AT_LEAST`), the best of each family, and those whose runs so far all
    failed that try a tighter rtol (``retrying``: key -> True)."""
    n = max(KEEP_AT_LEAST, math.ceil(len(ranked) / 2))
    keep = {line.key for line in ranked[:n]}
    keep |= {line.key for line in ranked if retrying.get(line.key)}
    for fam in FAMILY_WORDS.values():
        best = next((ln for ln in ranked if ln.candidate.family == fam
                     and math.isfinite(target_cpu[ln.key])), None)
        if best is not None:
            keep.add(best.key)
    return keep


def search(problem, cands, target: float, measure: str, budget_s: float, session,
           log=None) -> SearchResult:
    """Run the search (module docstring) on ``problem`` (an instance) over ``cands``.

    Parameters
    ----------
    budget_s : float
        Wall seconds the search may take, a hard limit: a round is not started
        with less than the least per-case timeout left, and one still running
        when they are spent is stopped, its unfinished cases unrecorded (the
        answer is then partial).
    session : Session
        Where every round runs (:class:`~integrator_bench.harness.run.runner.Session`):
        its store, backend, references and resume policy.
    log : callable, optional
        Called with a line at the start of each round.
    """
    started, cpu0 = time.monotonic(), process_cpu()
    lines = [Line(c) for c in cands]
    records = pd.DataFrame()
    first = start_rtol(target)
    result = SearchResult(lines, records, target, measure)
    parallel = session.context.parallel
    while True:
        alive = [ln for ln in lines if ln.out is None]
        plans = {}
        rows_of, points_of = by_line(records), points_by_line(records, measure)
        none = records.iloc[:0]
        for ln in alive:
            rows = rows_of.get(ln.key, none)
            r, why, calibrated = next_rtol(points_of.get(ln.key, NO_POINTS), rows, target,
                                           first)
            ln.calibrated = calibrated
            if why is not None:
                ln.out = why
            elif r is not None:
                plans[ln.key] = r
        alive = [ln for ln in lines if ln.out is None]
        if result.rounds:
            cpu = {ln.key: predicted_cpu(points_of.get(ln.key, NO_POINTS), target)
                   for ln in alive}
            ranked = sorted(alive, key=lambda ln: cpu[ln.key])
            retrying = {ln.key: ln.key in plans and math.isinf(cpu[ln.key]) for ln in alive}
            keep = keep_half(ranked, cpu, retrying)
            for rank, ln in enumerate(ranked, 1):
                if ln.key not in keep and not ln.calibrated:
                    ln.out = (f"left in round {result.rounds}: ranked {rank} of {len(ranked)} "
                              f"by CPU to the target ({cpu[ln.key]:.3g} s"
                              f"{'' if ln.calibrated or math.isinf(cpu[ln.key]) else ', predicted'})")
            for ln in ranked:
                if ln.key not in keep and ln.calibrated:
                    ln.out = f"calibrated, ranked below the kept half in round {result.rounds}"
        todo = [ln for ln in lines if ln.out is None and ln.key in plans]
        if not todo:
            break
        left = budget_s - (time.monotonic() - started)
        if left < CASE_TIMEOUT[0]:
            result.partial = (f"the search stopped after round {result.rounds} with "
                              f"{len(todo)} lines still to run")
            break
        timeout = case_timeout(left, parallel, len(todo))
        cases = [ln.candidate.case(problem, plans[ln.key]) for ln in todo]
        deadline = time.monotonic() + left
        if log:
            log(f"advise: round {result.rounds + 1}: {len(cases)} cases, "
                f"{sum(ln.out is None for ln in lines)} lines in the search, "
                f"{timeout:.3g} s a case, {left:.0f} s left of the search's share")
        df = session.run(cases, budget_s=timeout, deadline=deadline)
        result.cases += len(cases)
        result.ran += cases
        records = df if records.empty else pd.concat([records, df], ignore_index=True)
        result.rounds += 1
        if len(df) < len(cases) and time.monotonic() >= deadline:  # cut at its share
            result.partial = (f"the search stopped in round {result.rounds} with "
                              f"{len(cases) - len(df)} of its {len(cases)} cases unfinished")
            break
    result.records = records
    result.wall_s, result.cpu_s = time.monotonic() - started, process_cpu() - cpu0
    return result
