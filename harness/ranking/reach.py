"""CPU to reach a target error: the measure the IFToMM multibody benchmarks use.

A *line* is one (integrator with its settings, formulation, mode) of one problem
and parameter set, grouped and named by its ``label``
(:data:`~integrator_bench.harness.ranking.records.LINE`): adaptive over its
tolerances (mode ``rtol``) or fixed-step over its step sizes (mode ``h``); an
integrator that runs both ways has two lines.

The error (:data:`ERRORS`, chosen with ``ibench report --error``; default
:data:`DEFAULT_ERROR`) is one of three **mixed** errors ``|y_i - r_i| /
(floor_i + |r_i|)`` of the problem's error components (its positions, for a
mechanical system), where the floor ``floor_i = atol/rtol`` is the problem's
absolute scale of that component (``atol_scale``; for a multibody problem its
``position_scale``; the record's ``err_floor``): ``final``, the largest at the
final time, ``10**-mescd`` (Mazzia and Magherini, IVP Test Set, sect. II);
``max``, the largest over the output times (``err_max``); ``rms``, their
root-mean-square (``err_rms``). Unlike the pure relative error it does not blow
up at a component whose reference is near zero, and it approaches the relative
error where the reference is large against the floor. The final-time error
can say nothing: where the reference's final state is within the floor of zero
on every error component (``final_degenerate``: a ball at rest on the ground,
a decayed oscillation) a run that ends there has no final error whatever its
path; such a problem is ranked by ``max`` instead, and the page says so
(:func:`effective_error`). A run that missed or added an event
(``events_missed``, ``events_spurious`` > 0) reaches no target, whatever its
error: its error counts as infinite.

A line's points are its ok records with a positive CPU. Of them only its own
**Pareto front** counts: a point that another point of the line beats in both
error and CPU (a looser tolerance that took more CPU than a tighter one, an
error that rises again at a tighter tolerance) is left out, so that the CPU
to reach a target never falls as the target tightens. The front is walked in
order of increasing CPU; the target is reached at its **first** point whose
error is at or below it:

* if that point is not the first of the front, its predecessor's error is above
  the target, and the CPU is interpolated linearly in log10(cpu_s) against
  log10(error) between the two ("interpolated"; "at a point" when the point's
  error equals the target), and the tolerance (rtol, or h) at the crossing
  with the same weight, geometrically;
* if it is the first point, the line's cheapest run is already below the
  target and its crossing lies outside the measured range: the CPU is not
  extrapolated; that point's CPU is given as an upper bound ("at most", shown
  ``≤``), and the line is **ranked by it**, in the table, the answer and the
  run's summary alike (a run that cost this much reached the target; a looser
  tolerance might have reached it for less);
* if no point gets there: "not reached", no CPU.

Beside the CPU, the counters ``nsteps``, ``nfev``, ``njev``, ``nlu`` are
interpolated with the same weight, geometrically (log-log) when both ends are
positive, linearly when one is zero, and rounded to integers; a counter that
either end cannot report stays null. With an upper bound they are the first
point's own counts.

Failed, timed-out, untimed and other non-ok cases are not points of the line.

Every function here takes records with every field of
:data:`integrator_bench.harness.matrix.record.FIELDS`, as
:func:`~integrator_bench.harness.ranking.records.clean_records` gives them (a
store's records, and ``Session.run``'s, have them all).

Ties. The CPU of a record is the median of its timed solves, ``cpu_s_iqr``
their interquartile range and ``cpu_samples`` the solves themselves
(:mod:`integrator_bench.harness.matrix.record`, "Timing"). The spread at the
target is interpolated with the same weight, as a share of the CPU (linearly;
the first point's with an upper bound), and so are the samples, sample by sample
(geometrically). Whether the cheapest line is the cheapest beyond the noise is
its margin over each contender, with its interval, from those samples
(:mod:`integrator_bench.harness.ranking.margin`; :func:`contest`): a winner when
every contender is clearly slower, else a tie with those that are not. The
table marks a line that ties with the cheapest, and the answer names them.

One answer: the report's table (:func:`target_table`), its answer line and the
end-of-run summary all name the first row of that table (:func:`cheapest`).

References: IFToMM Technical Committee for Multibody Dynamics, "Library of
Computational Benchmark Problems", https://www.iftomm-multibody.org/benchmark/
(CPU time to reach a given accuracy); F. Mazzia and C. Magherini, "Test Set for
Initial Value Problem Solvers", release 2.4 (2008), sect. II ("mescd");
DiffEqDevTools.jl's work-precision sets (final, l2 and L-infinity errors).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pandas as pd

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.ranking import margin
from integrator_bench.harness.ranking.records import LINE

#: the one default target: the error whose cheapest line the report's answers, the run's
#: summary and the coverage line name (a mixed error of the chosen measure, :data:`ERRORS`)
DEFAULT_TARGET = 1e-5
#: the errors of the report's table, loosest first, the last :data:`DEFAULT_TARGET`;
#: ``ibench report --target E`` puts E alone in their place
TARGETS = (1e-3, DEFAULT_TARGET)


def tag(target: float) -> str:
    """A target as the table's columns and the page name it: ``1e-05`` when one
    digit says it exactly, else three significant digits (``0.00025``)."""
    text = f"{target:.0e}"
    return text if float(text) == target else f"{target:.3g}"


@dataclasses.dataclass(frozen=True)
class ErrorMeasure:
    """One error a ranking may use: the record ``field`` holding it (``digits``:
    as ``-log10`` of the error) and how the page names it."""

    name: str
    field: str
    digits: bool
    words: str


#: the errors ``--error`` chooses from (module docstring)
ERRORS = {
    "final": ErrorMeasure("final", "mescd", True, "largest mixed error at the final time"),
    "max": ErrorMeasure("max", "err_max", False,
                        "largest mixed error over the output times"),
    "rms": ErrorMeasure("rms", "err_rms", False,
                        "root-mean-square mixed error over the output times"),
}
#: the default: the whole trajectory must be right, not only its end
DEFAULT_ERROR = "max"
#: the error a problem is ranked by when its final-time error is degenerate
TRAJECTORY_ERROR = "max"
#: the counters shown beside the CPU
COUNTS = ("nsteps", "nfev", "njev", "nlu")
#: the record field of the CPU's spread (interquartile range of the timed solves)
SPREAD = "cpu_s_iqr"
#: how a target was reached (see the module docstring)
HOW = ("interpolated", "at a point", "at most", "not reached")


def _column(rows: pd.DataFrame, name: str) -> pd.Series:
    """A numeric column of ``rows`` as floats (NaN where null or not a number)."""
    return pd.to_numeric(rows[name], errors="coerce").astype(float)


def degenerate(rows: pd.DataFrame) -> bool:
    """Whether the final-time error of these records' problem says nothing: a record
    measured it with the reference's final state within the floor of zero on every
    error component (``final_degenerate``)."""
    return bool((_column(rows, "final_degenerate") == 1).any())


def effective_error(rows: pd.DataFrame, measure: str = DEFAULT_ERROR) -> str:
    """The measure one problem's records are ranked by: ``measure``, but
    :data:`TRAJECTORY_ERROR` for the final-time error of a problem whose final
    error is degenerate (:func:`degenerate`)."""
    if measure in ("final", ERRORS["final"].field) and degenerate(rows):
        return TRAJECTORY_ERROR
    return measure


def error_values(rows: pd.DataFrame, measure: str = DEFAULT_ERROR) -> pd.Series:
    """The error of each record under ``measure``, per problem and parameter set as
    :func:`effective_error` says; infinite for a run that missed or added an event.

    Parameters
    ----------
    rows : pandas.DataFrame
        Result records.
    measure : str
        A key of :data:`ERRORS` (``final``, ``max``, ``rms``), or a record field
        in digits whose ``10**-value`` is the error (``mescd``, ``scd``, or a
        column a caller added, such as ``-log10(monitor_err)``).
    """
    out = pd.Series(math.nan, index=rows.index, dtype=float)
    read = ["final_degenerate", measure, *(spec.field for spec in ERRORS.values())]
    grouped = rows[["problem", "params", *dict.fromkeys(c for c in read if c in rows)]]
    for _, sub in grouped.groupby(["problem", "params"], sort=False):
        name = effective_error(sub, measure)
        spec = ERRORS.get(name)
        field, digits = (spec.field, spec.digits) if spec else (name, True)
        values = _column(sub, field)
        out[sub.index] = 10.0 ** -values if digits else values
    wrong = (_column(rows, "events_missed") > 0) | (_column(rows, "events_spurious") > 0)
    return out.mask(wrong & out.notna(), math.inf)


def line_points(rows: pd.DataFrame, measure: str = DEFAULT_ERROR) -> pd.DataFrame:
    """The ok records with an error and a positive CPU, in line order.

    Parameters
    ----------
    rows : pandas.DataFrame
        Result records (every field of :data:`integrator_bench.harness.matrix.record.FIELDS`).
    measure : str
        As in :func:`error_values`.

    Returns
    -------
    pandas.DataFrame
        Those rows, but those at the budget's edge (``budget_edge``: another run
        may time them out, so no ranking rests on them), with ``err``
        (:func:`error_values`: infinite for a run that
        missed or added an event), ``tol`` (rtol, else h) and ``mode`` added,
        sorted by problem, params, label, formulation, mode and then by
        decreasing tolerance (increasing work).
    """
    err = error_values(rows, measure)
    cpu = pd.to_numeric(rows["cpu_s"], errors="coerce").astype(float)
    edge = _column(rows, "budget_edge") == 1
    keys = rows.loc[(rows["status"] == "ok") & err.notna() & np.isfinite(cpu) & (cpu > 0)
                    & ~edge, LINE + ["rtol", "h"]]
    rtol = pd.to_numeric(keys["rtol"], errors="coerce").astype(float)
    h = pd.to_numeric(keys["h"], errors="coerce").astype(float)
    keys = keys.assign(tol=rtol.fillna(h))
    # sorted on the keys alone, then every field taken once in that order
    order = keys.sort_values(LINE + ["tol"], ascending=[True] * len(LINE) + [False],
                             na_position="last", kind="stable").index
    return rows.loc[order].assign(err=err[order], cpu_s=cpu[order], tol=keys["tol"][order])


def record_point(record, measure: str = DEFAULT_ERROR) -> tuple[float, float] | None:
    """``(error, cpu_s)`` of one record as a point of its line, as :func:`line_points`
    takes it (an ``ok`` record with an error and a positive CPU, not at the budget's
    edge; :func:`error_values`' error, infinite after a missed or added event), or
    None: what a race (:mod:`~integrator_bench.harness.ranking.racing`) reads of each
    record as it arrives, without a DataFrame."""
    def number(name):
        try:
            value = float(record.get(name))
        except (TypeError, ValueError):
            return math.nan
        return value
    cpu = number("cpu_s")
    if record.get("status") != "ok" or not (math.isfinite(cpu) and cpu > 0) \
            or number("budget_edge") == 1:
        return None
    name = measure
    if measure in ("final", ERRORS["final"].field) and number("final_degenerate") == 1:
        name = TRAJECTORY_ERROR
    spec = ERRORS.get(name)
    field, digits = (spec.field, spec.digits) if spec else (name, True)
    err = 10.0 ** -number(field) if digits else number(field)
    if math.isnan(err):
        return None
    if number("events_missed") > 0 or number("events_spurious") > 0:
        err = math.inf
    return err, cpu


def _count(c0, c1, w: float):
    if c0 is None or c1 is None or pd.isna(c0) or pd.isna(c1):
        return None
    c0, c1 = float(c0), float(c1)
    if c0 > 0 and c1 > 0:
        return int(round(_geometric(c0, c1, w)))
    return int(round(c0 + w * (c1 - c0)))


def _spread(cpu, spread, k0: int, k1: int, w: float) -> float:
    """The spread at the target: the two points' spreads as shares of their CPU,
    interpolated linearly with weight ``w``, times the interpolated ``cpu``."""
    if spread is None:
        return math.nan
    s0, s1 = (float(spread[k]) if spread[k] is not None else math.nan for k in (k0, k1))
    return s0 / cpu[k0] + w * (s1 / cpu[k1] - s0 / cpu[k0])


def pareto_front(err, cpu) -> np.ndarray:
    """Indexes of the points no other point beats in both error and CPU, by error
    (so by decreasing CPU); a point with an infinite or NaN error is on no front."""
    err, cpu = np.asarray(err, float), np.asarray(cpu, float)
    order = np.lexsort((err, cpu))          # by CPU, then error
    keep, best = [], np.inf
    for i in order:
        if err[i] < best:
            keep.append(i)
            best = err[i]
    return np.array(sorted(keep, key=lambda i: err[i]), int)


def _geometric(a, b, w: float) -> float:
    """``a`` to ``b`` with weight ``w`` in log (NaN when either is not positive)."""
    if not (a > 0 and b > 0):
        return math.nan
    return math.exp(math.log(a) + w * (math.log(b) - math.log(a)))


def reach_line(err, cpu, target: float, counts: dict | None = None, spread=None,
               tol=None, samples=None) -> dict:
    """Where one line reaches ``target``: its CPU, counters, tolerance and how.

    Parameters
    ----------
    err, cpu : sequence of float
        The line's errors and CPU seconds (any order; only the line's Pareto
        front counts, :func:`pareto_front`, walked by increasing CPU).
    target : float
        Error to reach (same measure as ``err``).
    counts : dict of str to sequence, optional
        Counters of the same points (``nsteps`` ...); None entries for counts
        the integrator cannot report.
    spread : sequence of float or None, optional
        The points' CPU spreads (``cpu_s_iqr``; None or NaN where unknown).
    tol : sequence of float, optional
        The points' tolerances (rtol, or h).
    samples : sequence, optional
        The points' ``cpu_samples`` (JSON text, a sequence, or None where unknown).

    Returns
    -------
    dict
        ``cpu_s`` (NaN when not reached), ``spread`` (the CPU's spread there,
        NaN when unknown or not reached), ``samples`` (the samples of the CPU
        to reach the target, :func:`~integrator_bench.harness.ranking.margin.crossing_samples`;
        None when unknown or not reached), ``points`` (the indexes of the
        points the crossing is read off: one, two, or none when not reached),
        one entry per counter (None when not
        reached or not reported), ``tol`` (the tolerance at the crossing,
        geometric with the same weight; NaN when not reached or not given),
        ``how`` (one of :data:`HOW`) and ``w``, the interpolation weight from
        the point before the crossing (1: at the point reaching the target;
        NaN when not interpolated).
    """
    err, cpu = np.asarray(err, float), np.asarray(cpu, float)
    tol = np.full(len(err), math.nan) if tol is None else np.asarray(tol, float)
    counts = counts or {}
    front = pareto_front(err, cpu)[::-1]             # by increasing CPU
    below = [i for i, k in enumerate(front) if err[k] <= target]
    if not below:
        return {"cpu_s": math.nan, "spread": math.nan, "samples": None, "points": (),
                **{k: None for k in counts}, "tol": math.nan, "how": "not reached",
                "w": math.nan}

    def samples_of(k):
        return None if samples is None else margin.samples(samples[k])
    i = below[0]
    k = int(front[i])
    if i == 0 or err[k] == target:        # exactly the point's own CPU and counts
        return {"cpu_s": float(cpu[k]), "spread": cpu[k] * _spread(cpu, spread, k, k, 0.0),
                "samples": samples_of(k), "points": (k,),
                **{n: _count(v[k], v[k], 0.0) for n, v in counts.items()},
                "tol": float(tol[k]), "how": "at most" if i == 0 else "at a point",
                "w": math.nan if i == 0 else 1.0}
    j = int(front[i - 1])
    e0, e1 = math.log(err[j]), math.log(err[k])
    w = (math.log(target) - e0) / (e1 - e0)
    c = _geometric(cpu[j], cpu[k], w)           # a line's CPUs are positive
    return {"cpu_s": c, "spread": c * _spread(cpu, spread, j, k, w),
            "samples": margin.crossing_samples(samples_of(j), samples_of(k), w),
            "points": (j, k),
            **{n: _count(v[j], v[k], w) for n, v in counts.items()},
            "tol": _geometric(tol[j], tol[k], w), "how": "interpolated", "w": w}


@dataclasses.dataclass(frozen=True)
class Contest:
    """Which lines contend for the cheapest at one target, and how sure the ranking is.

    Attributes
    ----------
    top : int
        Index (in the table given to :func:`contest`) of the cheapest line that
        reaches the target.
    margins : dict
        Index -> :class:`~integrator_bench.harness.ranking.margin.Margin` over the
        top line, for every other line within
        :data:`~integrator_bench.harness.ranking.margin.BAND` of its CPU (the
        contenders), cheapest first.
    verdict : str
        ``winner`` or ``tie``
        (:func:`~integrator_bench.harness.ranking.margin.verdict`).
    """

    top: int
    margins: dict
    verdict: str

    @property
    def tied(self) -> list:
        """Indexes of the lines that tie with the top line (not clearly slower:
        their interval reaches 1, or is unmeasured), the top line first; only the
        top line unless the verdict is a tie."""
        return [self.top] + [i for i, m in self.margins.items() if not m.clear]

    @property
    def settled(self) -> bool:
        """Whether more samples could change nothing: every contender is clearly
        slower or settled as equal (:attr:`Margin.settled`)."""
        return all(m.settled for m in self.margins.values())


def contest(table: pd.DataFrame, name: str) -> Contest | None:
    """The :class:`Contest` at the target tagged ``name`` of a :func:`target_table`
    (or one target's columns of it, before they are sorted): its lines that reach
    the target, by CPU (a stable sort, so the table's order among equals), the
    first the top line; None when no line reaches it. Only the lines' own
    samples of the CPU to reach the target (``samples_T``) decide the margins,
    so the report, the summary and the advice, all built on the same records,
    say the same."""
    how, cpu = table[f"how_{name}"], table[f"cpu_{name}"].astype(float)
    reached = [i for i in np.argsort(cpu.to_numpy(), kind="stable")
               if how.iloc[i] != "not reached" and np.isfinite(cpu.iloc[i])]
    if not reached:
        return None
    top, best = reached[0], float(cpu.iloc[reached[0]])
    samples = table[f"samples_{name}"]
    margins = {}
    for i in reached[1:]:
        if float(cpu.iloc[i]) > margin.BAND * best:
            break
        margins[int(i)] = margin.margin(line_name(table.iloc[i]), samples.iloc[top],
                                        samples.iloc[i], float(cpu.iloc[i]) / best)
    return Contest(int(top), margins, margin.verdict(margins.values()))


def line_name(row) -> str:
    """``label (formulation)``: how the answers name a line."""
    return f"{row['label']} ({row['formulation']})"


def tied_with_cheapest(table: pd.DataFrame, name: str) -> list[bool]:
    """For each line of ``table`` (a :func:`target_table`, or one target's part of
    it), whether it ties with the cheapest line at the target tagged ``name``
    (:func:`contest`; the cheapest itself does not)."""
    found = contest(table, name)
    tied = set(found.tied[1:]) if found is not None else set()
    return [i in tied for i in range(len(table))]


def cpu_to_reach(rows: pd.DataFrame, target: float,
                 measure: str = DEFAULT_ERROR) -> pd.DataFrame:
    """CPU and counters at which each line of ``rows`` reaches ``target``.

    Parameters
    ----------
    rows : pandas.DataFrame
        Result records with every field (``ibench run``'s DataFrame, a loaded
        store, :func:`~integrator_bench.harness.ranking.records.clean_records`),
        any number of problems, parameter sets and lines; ``unsupported`` cases
        are left out.
    target : float
        Error to reach, in ``measure``.
    measure : str
        A key of :data:`ERRORS`, or a column of ``rows`` in digits whose
        ``10**-value`` is the error (``"mescd"``, or ``-log10(monitor_err)``
        for Orlov's pin-force error); see :func:`error_values`.

    Returns
    -------
    pandas.DataFrame
        One row per line: the line's keys
        (:data:`~integrator_bench.harness.ranking.records.LINE`: problem, params,
        label, formulation, mode), ``cpu_s``, ``spread`` (of the CPU, NaN when
        unknown), ``samples`` (of the CPU to reach the target, an array or
        None), ``cases`` (the ``case_id`` of the records the crossing is read
        off), ``nsteps``, ``nfev``, ``njev``, ``nlu`` (nullable
        integers), ``tol`` (rtol or h at the crossing), ``how``,
        ``integrator`` (the registry name), ``best_err`` (least finite error
        of the line, NaN without one), ``n_ok`` and ``n_failed``.
    """
    return _reach(rows, (target,), measure)[target]


def cpu_to_reach_each(rows: pd.DataFrame, targets,
                      measure: str = DEFAULT_ERROR) -> dict[float, pd.DataFrame]:
    """:func:`cpu_to_reach` at each of ``targets``, the lines' points found once.

    Parameters
    ----------
    rows : pandas.DataFrame
        As for :func:`cpu_to_reach`.
    targets : sequence of float
        Errors to reach, in ``measure``.
    measure : str
        As for :func:`cpu_to_reach`.

    Returns
    -------
    dict
        Target -> the table :func:`cpu_to_reach` gives at it.
    """
    return _reach(rows, tuple(targets), measure)


def _reach(rows: pd.DataFrame, targets, measure: str) -> dict:
    """:func:`cpu_to_reach` at each of ``targets`` (target -> table), the lines'
    points found once."""
    run = rows[rows["status"] != "unsupported"]
    pts = line_points(run, measure)
    # each line's points as positions into plain arrays (a group of a DataFrame per
    # line cost most of a report's tables), its records' statuses counted per line
    lines = pts.groupby(LINE, sort=False).indices if len(pts) else {}
    err, cpu, tol = (pts[c].to_numpy(float) for c in ("err", "cpu_s", "tol"))
    every = {n: [None if pd.isna(v) else v for v in pts[n]] for n in COUNTS}
    spreads = [None if pd.isna(v) else float(v) for v in pts[SPREAD]]
    tally = pd.DataFrame({**{c: run[c] for c in LINE}, "n_ok": run["status"] == "ok",
                          "n_failed": run["status"] != "ok"}).groupby(LINE, sort=True).sum()
    none = np.array([], int)
    out = {t: [] for t in targets}
    samples = list(pts["cpu_samples"])
    case_ids = list(pts["case_id"])
    integrator = run.groupby(LINE, sort=True)["integrator"].first()
    for key, n_ok, n_failed in zip(tally.index, tally["n_ok"], tally["n_failed"]):
        at = lines.get(key, none)
        counts = {n: [every[n][i] for i in at] for n in COUNTS}
        spread = [spreads[i] for i in at]
        finite = err[at][np.isfinite(err[at])]
        common = {"integrator": str(integrator[key]),
                  "best_err": float(finite.min()) if len(finite) else math.nan,
                  "n_ok": int(n_ok), "n_failed": int(n_failed)}
        for t in targets:
            got = reach_line(err[at], cpu[at], t, counts, spread, tol[at],
                             [samples[i] for i in at])
            got.pop("w")
            got["cases"] = tuple(case_ids[at[p]] for p in got.pop("points"))
            out[t].append({**dict(zip(LINE, key)), **got, **common})
    cols = LINE + ["cpu_s", "spread", "samples", "cases", *COUNTS, "tol", "how", "integrator",
                   "best_err", "n_ok", "n_failed"]
    tables = {}
    for t in targets:
        table = pd.DataFrame(out[t], columns=cols)
        for n in COUNTS:
            table[n] = pd.array([None if v is None or pd.isna(v) else int(v)
                                 for v in table[n]], dtype="Int64")
        tables[t] = table
    return tables


def target_table(rows: pd.DataFrame, targets=TARGETS,
                 measure: str = DEFAULT_ERROR) -> pd.DataFrame:
    """The report's table: one row per line, the CPU to reach each target.

    Parameters
    ----------
    rows : pandas.DataFrame
        Records with every field (as for :func:`cpu_to_reach`) of one problem
        and parameter set, or several.
    targets : sequence of float
        Errors in ``measure``, loosest first.
    measure : str
        As in :func:`cpu_to_reach`.

    Returns
    -------
    pandas.DataFrame
        Line keys (:data:`~integrator_bench.harness.ranking.records.LINE`), then
        per target ``t`` (``T = tag(t)``, :func:`tag`) the columns
        ``cpu_T``, ``spread_T``, ``samples_T``, ``cases_T``, ``tol_T``, ``how_T``, ``tie_T`` (the
        line ties with the cheapest, :func:`tied_with_cheapest`) and ``{count}_T`` of
        :data:`COUNTS`, then ``integrator``,
        ``best_err``, ``n_ok``, ``n_failed``. Sorted by CPU at the tightest
        target, then the next looser ones (not reached last), then least error.
    """
    wide = None
    parts = _reach(rows, targets, measure)
    for t in targets:
        part = parts[t]
        name = tag(t)
        part = part.rename(columns={"cpu_s": f"cpu_{name}", "how": f"how_{name}",
                                    "spread": f"spread_{name}", "tol": f"tol_{name}",
                                    "samples": f"samples_{name}", "cases": f"cases_{name}",
                                    **{n: f"{n}_{name}" for n in COUNTS}})
        part[f"tie_{name}"] = tied_with_cheapest(part, name)
        if wide is None:
            wide = part
        else:
            wide = wide.merge(part.drop(columns=["integrator", "best_err", "n_ok",
                                                 "n_failed"]), on=LINE)
    tail = ["integrator", "best_err", "n_ok", "n_failed"]
    wide = wide[[c for c in wide.columns if c not in tail] + tail]
    order = [f"cpu_{tag(t)}" for t in reversed(list(targets))]
    return wide.sort_values(order + ["best_err"] + LINE, na_position="last",
                            kind="stable").reset_index(drop=True)


def cpu_ratio(num: float, num_how: str, den: float, den_how: str) -> tuple[float, str]:
    """``num / den`` of two CPUs to reach a target, with how sure it is.

    Returns
    -------
    (float, str)
        The ratio and ``"="`` when both were interpolated, ``"≤"`` or ``"≥"``
        when one is an upper bound ("at most") so the ratio is bounded on one
        side, and (NaN, ``""``) when either line did not reach the target or
        both are bounds.
    """
    exact = ("interpolated", "at a point")
    if math.isnan(num) or math.isnan(den) or "not reached" in (num_how, den_how):
        return math.nan, ""
    if num_how in exact and den_how in exact:
        return num / den, "="
    if num_how == "at most" and den_how in exact:
        return num / den, "≤"
    if den_how == "at most" and num_how in exact:
        return num / den, "≥"
    return math.nan, ""


def cheapest(table: pd.DataFrame, target: float = DEFAULT_TARGET) -> dict | None:
    """The one answer to "which line is cheapest to ``target``", from a
    :func:`target_table`: the :func:`contest` of its lines that reach the
    target; None when no line reaches it. The report's answer line, the run's
    summary and the advice all take it.

    Returns
    -------
    dict or None
        ``label`` (the line's integrator with its settings), ``integrator``,
        ``formulation``, ``mode``, ``cpu_s``, ``how``, ``tol``, ``verdict``
        (``winner`` or ``tie``: a winner is named only when every contender's
        margin interval lies above 1), ``tied`` (every line
        in the tie as ``"label (formulation)"``, this one first; empty unless
        the verdict is a tie), ``ties`` (the same without this one),
        ``tied_lines`` (the same as ``{"label", "formulation"}``),
        ``same_code`` (the library codes two or more of the tied lines run,
        each with its lines: ``{"SUNDIALS CVODE (Adams)": [{"label":
        "cvode-adams", "formulation": "ode"}, ...]}``), ``margins`` (the contenders'
        :class:`~integrator_bench.harness.ranking.margin.Margin`, cheapest
        first) and ``runner_up``: the next line that reaches the target, as
        ``{"line", "ratio": its CPU over this one's, "sure": "=", "≥" or ""
        (:func:`cpu_ratio`), "tie": bool, "margin": its Margin or None (out of
        contention)}``, or None when no other line reaches it.
    """
    name = tag(target)
    if not len(table) or f"how_{name}" not in table:
        return None
    found = contest(table, name)
    if found is None:
        return None
    top = table.iloc[found.top]
    cpu = float(top[f"cpu_{name}"])
    cpus = table[f"cpu_{name}"].astype(float).to_numpy()
    later = [i for i in np.argsort(cpus, kind="stable") if i != found.top
             and table[f"how_{name}"].iloc[i] != "not reached" and np.isfinite(cpus[i])]
    tied = [line_name(table.iloc[i]) for i in found.tied] if found.verdict == "tie" else []
    runner_up = None
    if later:
        second = table.iloc[later[0]]
        ratio, sure = cpu_ratio(float(second[f"cpu_{name}"]), second[f"how_{name}"], cpu,
                                top[f"how_{name}"])
        runner_up = {"line": line_name(second), "ratio": ratio, "sure": sure,
                     "tie": line_name(second) in tied,
                     "margin": found.margins.get(int(later[0]))}
    return {"label": str(top["label"]), "integrator": str(top["integrator"]),
            "formulation": str(top["formulation"]), "mode": top["mode"], "cpu_s": cpu,
            "how": top[f"how_{name}"], "tol": float(top[f"tol_{name}"]),
            "verdict": found.verdict, "tied": tied, "ties": tied[1:],
            "tied_lines": [{"label": table["label"].iloc[i],
                            "formulation": table["formulation"].iloc[i]}
                           for i in found.tied] if tied else [],
            "same_code": same_code([table.iloc[i] for i in found.tied] if tied else []),
            "margins": list(found.margins.values()), "runner_up": runner_up}


def answer_text(top: dict | None, name=line_name) -> str:
    """The answer of :func:`cheapest` in words, as the run's summary, the report and
    the advice say it: ``assimulo-dopri5 (ode) (margin 1.3 over scipy-DOP853 (ode),
    95 % 1.2-1.4)``; ``tie:
    assimulo-dopri5 (ode), scipy-DOP853 (ode) (margin 1.04, 95 % 0.91-1.19)``, the
    runner-up's margin; ``(... interval not measured)`` when a contender has no
    interval; ``(only line)``, or ``(runner-up 3.1x)`` beyond the band; then
    which tied lines run one library code through two wrappers. ``name`` names a
    line from a row with ``label`` and ``formulation``; "not reached" for None."""
    if top is None:
        return "not reached"
    lines, why, same = answer_parts(top, name)
    return f"{lines} ({why}){same}"


def answer_parts(top: dict, name=line_name) -> tuple[str, str, str]:
    """The three parts of :func:`answer_text`: the line or the tie, the margin
    (without parentheses) and the note on one code (``""`` or ``"; A and B are
    one code, C"``)."""
    if top["verdict"] == "tie":
        lines = "tie: " + ", ".join(name(t) for t in top["tied_lines"])
    else:
        lines = name(top)
    second = top["runner_up"]
    if second is None:
        why = "only line"
    elif second["margin"] is not None:
        why = second["margin"].text(over=top["verdict"] != "tie")
    elif second["sure"]:
        why = f"runner-up {second['sure'].replace('=', '')}{second['ratio']:.2g}x".replace(
            "≥", "≥ ")
    else:
        why = "runner-up an upper bound too"
    same = "".join(f"; {' and '.join(name(t) for t in lines_)} are one code, {code}"
                   for code, lines_ in top["same_code"].items())
    return lines, why, same


def same_code(rows) -> dict:
    """The library codes that two or more of ``rows`` (target-table rows) run
    through different wrappers, each with its lines (``{"label", "formulation"}``):
    an integrator's ``code`` (:class:`~integrator_bench.integrators.base.Integrator`),
    read from the registry; {} when none is shared."""
    known = registry.integrators()
    by_code: dict = {}
    for row in rows:
        code = getattr(known.get(row["integrator"]), "code", None)
        if code:
            by_code.setdefault(code, []).append(row)
    return {code: [{"label": r["label"], "formulation": r["formulation"]} for r in got]
            for code, got in by_code.items() if len({r["integrator"] for r in got}) > 1}


def tol_cell(tol: float, line_mode: str) -> str:
    """``rtol 3.2e-07`` or ``h 0.001``: the tolerance at a crossing (``–`` unknown)."""
    if pd.isna(tol):
        return "–"
    return f"{'h' if line_mode == 'h' else 'rtol'} {tol:.2g}"


def measure_text(measure: str, rows: pd.DataFrame | None = None,
                 components: str = "") -> str:
    """What a figure or table of ``rows`` (one problem) measures, in words:
    ``"the largest mixed error over the output times, |y - r| / (floor + |r|) of
    the error components (x, y), floor 0.001 (the problem's absolute scale
    atol/rtol)"``, with a note when the final-time error is degenerate."""
    name = effective_error(rows, measure) if rows is not None else measure
    spec = ERRORS.get(name)
    words = spec.words if spec else f"10^-{name}"
    floor = (_column(rows, "err_floor").dropna() if rows is not None
             else pd.Series(dtype=float))
    where = f" ({components})" if components else ""
    text = (f"the {words}, |y - r| / (floor + |r|) over the error components{where}, "
            + (f"floor {floor.min():.3g}" if len(floor) else "floor atol/rtol")
            + " (the problem's absolute scale atol/rtol)")
    if name != measure and name == TRAJECTORY_ERROR:
        text += ("; ranked by it instead of the final-time error, which says nothing here: "
                 "the reference's final state is within the floor of zero on every error "
                 "component")
    events = rows is None or _column(rows, "events_missed").notna().any()
    return text + ("; a run that missed or added an event reaches no target" if events else "")


def cpu_cell(cpu: float, how: str, tied: bool = False) -> str:
    """A CPU cell: ``0.123``, ``≤ 0.123`` (upper bound), ``0.123 tie`` (ties with
    a cheaper line) or ``not reached``."""
    if how == "not reached" or pd.isna(cpu):
        return "not reached"
    return f"{'≤ ' if how == 'at most' else ''}{cpu:.3g}{' tie' if tied else ''}"
