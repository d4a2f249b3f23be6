"""CPU to reach a target error: the measure the IFToMM multibody benchmarks use.

A *line* is one (integrator with its settings, formulation, mode) of one problem
and parameter set (:func:`~integrator_bench.harness.report.records.named_variants`):
adaptive over its tolerances (mode ``rtol``) or fixed-step over its step sizes
(mode ``h``); an integrator that runs both ways has two lines. Its error (:data:`MEASURE`) is the
**relative position error at the final time, with the problem's position scale
as floor**, ``10**-mescd``: ``mescd`` of the record is -log10 of the largest
mixed error ``|y_i - r_i| / (atol/rtol + |r_i|)`` over the problem's error
components (its positions, for a mechanical system), where ``atol/rtol`` is the
problem's absolute scale of that component (``atol_scale``; for a multibody
problem its ``position_scale``)
(:mod:`integrator_bench.harness.metrics`; Mazzia and Magherini, IVP Test Set,
sect. II). Unlike the pure relative error ``10**-scd`` it does not blow up at a
component whose reference is near zero (a link angle of -0.005 rad, a
coordinate passing through zero), and it approaches the relative error where
the reference is large against the scale. ``err_max`` is not used: it is the mixed
error over all output times.

The line is walked in order of increasing work, that is of decreasing tolerance
(rtol, else h: the order in which the work-precision figure draws it). The
target is reached at the **first** point whose error is at or below it:

* if that point is not the first of the line, its predecessor's error is above
  the target, and the CPU is interpolated linearly in log10(cpu_s) against
  log10(error) between the two ("interpolated"; "at a point" when the point's
  error equals the target). A non-monotone line (an error that rises again at a
  tighter tolerance) is thus taken at its first crossing; later crossings are
  ignored;
* if it is the first point, the line starts below the target and its crossing
  lies outside the measured range: the CPU is not extrapolated; the first
  point's CPU is given as an upper bound ("at most", shown ``≤``);
* if no point gets there: "not reached", no CPU.

Beside the CPU, the counters ``nsteps``, ``nfev``, ``njev``, ``nlu`` are
interpolated with the same weight, geometrically (log-log) when both ends are
positive, linearly when one is zero, and rounded to integers; a counter that
either end cannot report stays null. With an upper bound they are the first
point's own counts.

Failed, timed-out and other non-ok cases are not points of the line.

Ties. The CPU of a record is the median of its timed solves and ``cpu_s_iqr``
their interquartile range (:mod:`integrator_bench.harness.record`, "Timing").
The spread at the target is interpolated with the same weight, as a share of
the CPU (linearly; the first point's with an upper bound). Two lines **tie** at
a target when their CPUs differ by less than the mean of their spreads, that
is when their interquartile ranges, centred on the medians, overlap
(:func:`ties`); a line whose spread is unknown (fewer than four samples, an
older store) ties with none. The table marks a line that ties with a cheaper
one, and the answer names the lines that tie with the cheapest.

References: IFToMM Technical Committee for Multibody Dynamics, "Library of
Computational Benchmark Problems", https://www.iftomm-multibody.org/benchmark/
(CPU time to reach a given accuracy); F. Mazzia and C. Magherini, "Test Set for
Initial Value Problem Solvers", release 2.4 (2008), sect. II ("mescd").
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from integrator_bench.harness.report.records import mode, named_variants

#: the errors of the report's table (relative position errors with the position scale
#: as floor, ``10**-mescd``)
TARGETS = (1e-3, 1e-5)
#: the record field whose ``10**-value`` is the table's error (see the module docstring)
MEASURE = "mescd"
#: the counters shown beside the CPU
COUNTS = ("nsteps", "nfev", "njev", "nlu")
#: the record field of the CPU's spread (interquartile range of the timed solves)
SPREAD = "cpu_s_iqr"
#: how a target was reached (see the module docstring)
HOW = ("interpolated", "at a point", "at most", "not reached")
_LINE = ["problem", "params", "integrator", "formulation", "mode"]


def with_mode(rows: pd.DataFrame) -> pd.DataFrame:
    """``rows`` with the column ``mode`` of each record's line
    (:func:`integrator_bench.harness.report.records.mode`)."""
    return rows.assign(mode=[mode(r, h) for r, h in zip(rows["rtol"], rows["h"])])


def line_points(rows: pd.DataFrame, measure: str = MEASURE) -> pd.DataFrame:
    """The ok records with a finite error and a positive CPU, in line order.

    Parameters
    ----------
    rows : pandas.DataFrame
        Result records (columns of :data:`integrator_bench.harness.record.FIELDS`).
    measure : str
        The record field giving the error ``10**-measure``: ``"mescd"`` (the
        target table's, :data:`MEASURE`), ``"scd"`` (the pure relative error,
        the work-precision figure's axis) or another column in digits.

    Returns
    -------
    pandas.DataFrame
        Those rows with ``err = 10**-measure``, ``tol`` (rtol, else h) and
        ``mode`` added, sorted by problem, params, integrator, formulation, mode and then by
        decreasing tolerance (increasing work).
    """
    rows = named_variants(rows)
    digits = pd.to_numeric(rows[measure], errors="coerce").astype(float)
    cpu = pd.to_numeric(rows["cpu_s"], errors="coerce").astype(float)
    ok = rows[(rows["status"] == "ok") & np.isfinite(digits) & np.isfinite(cpu) & (cpu > 0)]
    rtol = pd.to_numeric(ok["rtol"], errors="coerce").astype(float)
    h = pd.to_numeric(ok["h"], errors="coerce").astype(float)
    ok = ok.assign(err=10.0 ** -digits[ok.index], cpu_s=cpu[ok.index], tol=rtol.fillna(h),
                   mode=with_mode(ok)["mode"])
    keys = [k for k in _LINE if k in ok.columns]
    return ok.sort_values(keys + ["tol"], ascending=[True] * len(keys) + [False],
                          na_position="last", kind="stable")


def _count(c0, c1, w: float):
    if c0 is None or c1 is None or pd.isna(c0) or pd.isna(c1):
        return None
    c0, c1 = float(c0), float(c1)
    if c0 > 0 and c1 > 0:
        return int(round(math.exp(math.log(c0) + w * (math.log(c1) - math.log(c0)))))
    return int(round(c0 + w * (c1 - c0)))


def _spread(cpu, spread, k0: int, k1: int, w: float) -> float:
    """The spread at the target: the two points' spreads as shares of their CPU,
    interpolated linearly with weight ``w``, times the interpolated ``cpu``."""
    if spread is None:
        return math.nan
    s0, s1 = (float(spread[k]) if spread[k] is not None else math.nan for k in (k0, k1))
    return s0 / cpu[k0] + w * (s1 / cpu[k1] - s0 / cpu[k0])


def reach_line(err, cpu, target: float, counts: dict | None = None, spread=None) -> dict:
    """Where one line reaches ``target``: its CPU, counters and how.

    Parameters
    ----------
    err, cpu : sequence of float
        The line's errors and CPU seconds, in order of increasing work.
    target : float
        Error to reach (same measure as ``err``).
    counts : dict of str to sequence, optional
        Counters of the same points (``nsteps`` ...); None entries for counts
        the integrator cannot report.
    spread : sequence of float or None, optional
        The points' CPU spreads (``cpu_s_iqr``; None or NaN where unknown).

    Returns
    -------
    dict
        ``cpu_s`` (NaN when not reached), ``spread`` (the CPU's spread there,
        NaN when unknown or not reached), one entry per counter (None when not
        reached or not reported), ``how`` (one of :data:`HOW`) and ``w``, the
        interpolation weight from the point before the crossing (1: at the
        point reaching the target; NaN when not interpolated).
    """
    err, cpu = np.asarray(err, float), np.asarray(cpu, float)
    counts = counts or {}
    below = np.flatnonzero(err <= target)
    if not len(below):
        return {"cpu_s": math.nan, "spread": math.nan, **{k: None for k in counts},
                "how": "not reached", "w": math.nan}
    k = int(below[0])
    if k == 0 or err[k] == target:        # exactly the point's own CPU and counts
        return {"cpu_s": float(cpu[k]), "spread": cpu[k] * _spread(cpu, spread, k, k, 0.0),
                **{n: _count(v[k], v[k], 0.0) for n, v in counts.items()},
                "how": "at most" if k == 0 else "at a point", "w": math.nan if k == 0 else 1.0}
    e0, e1 = math.log(err[k - 1]), math.log(err[k])
    w = (math.log(target) - e0) / (e1 - e0)
    c = math.exp(math.log(cpu[k - 1]) + w * (math.log(cpu[k]) - math.log(cpu[k - 1])))
    return {"cpu_s": c, "spread": c * _spread(cpu, spread, k - 1, k, w),
            **{n: _count(v[k - 1], v[k], w) for n, v in counts.items()},
            "how": "interpolated", "w": w}


def tie(cpu_a: float, spread_a: float, cpu_b: float, spread_b: float) -> bool:
    """Whether two CPUs tie: they differ by less than the mean of their spreads
    (their interquartile ranges, centred on the medians, overlap); False when
    a spread or a CPU is unknown (NaN)."""
    gap, width = abs(cpu_a - cpu_b), (spread_a + spread_b) / 2
    return bool(np.isfinite(gap) and np.isfinite(width) and gap < width)


def ties(cpu, spread) -> list[bool]:
    """For each line, whether it ties (:func:`tie`) with a cheaper line (lines
    without a CPU tie with none)."""
    cpu, spread = np.asarray(cpu, float), np.asarray(spread, float)
    return [any(cpu[j] < cpu[i] and tie(cpu[j], spread[j], cpu[i], spread[i])
                for j in range(len(cpu))) for i in range(len(cpu))]


def cpu_to_reach(rows: pd.DataFrame, target: float, measure: str = MEASURE) -> pd.DataFrame:
    """CPU and counters at which each line of ``rows`` reaches ``target``.

    Parameters
    ----------
    rows : pandas.DataFrame
        Result records (``ibench run``'s DataFrame or a loaded store), any
        number of problems, parameter sets and lines; ``unsupported`` cases
        are left out.
    target : float
        Error to reach: relative position error with the position scale as
        floor, ``10**-mescd`` (:data:`MEASURE`).
    measure : str
        The record field (digits) whose ``10**-value`` is the error: ``"mescd"``,
        or another column of ``rows`` in digits, such as ``-log10(monitor_err)``
        for Orlov's pin-force error.

    Returns
    -------
    pandas.DataFrame
        One row per line: the line's keys (problem, params when present,
        integrator, formulation, mode), ``cpu_s``, ``spread`` (of the CPU, NaN
        when unknown), ``nsteps``, ``nfev``, ``njev``, ``nlu`` (nullable
        integers), ``how`` and ``best_err`` (least error
        ``10**-mescd`` of the line, NaN without an ok point), ``n_ok`` and ``n_failed``.
    """
    rows = with_mode(named_variants(rows))
    keys = [k for k in _LINE if k in rows.columns]
    run = rows[rows["status"] != "unsupported"]
    pts = line_points(run, measure)
    out = []
    for key, sub in run.groupby(keys, sort=True):
        line = pts[pts.index.isin(sub.index)]
        counts = {n: [None if pd.isna(v) else v for v in line[n]] if n in line else
                  [None] * len(line) for n in COUNTS}
        spread = ([None if pd.isna(v) else float(v) for v in line[SPREAD]]
                  if SPREAD in line else None)
        got = reach_line(line["err"], line["cpu_s"], target, counts, spread)
        got.pop("w")
        out.append({**dict(zip(keys, key)), **got,
                    "best_err": float(line["err"].min()) if len(line) else math.nan,
                    "n_ok": int((sub["status"] == "ok").sum()),
                    "n_failed": int((sub["status"] != "ok").sum())})
    cols = keys + ["cpu_s", "spread", *COUNTS, "how", "best_err", "n_ok", "n_failed"]
    table = pd.DataFrame(out, columns=cols)
    for n in COUNTS:
        table[n] = pd.array([None if v is None or pd.isna(v) else int(v)
                             for v in table[n]], dtype="Int64")
    return table


def target_table(rows: pd.DataFrame, targets=TARGETS, measure: str = MEASURE) -> pd.DataFrame:
    """The report's table: one row per line, the CPU to reach each target.

    Parameters
    ----------
    rows : pandas.DataFrame
        Records of one problem and parameter set (or several: the line keys
        then include problem and params).
    targets : sequence of float
        Errors ``10**-mescd`` (:data:`MEASURE`), loosest first.
    measure : str
        As in :func:`cpu_to_reach`.

    Returns
    -------
    pandas.DataFrame
        Line keys, then per target ``t`` the columns ``cpu_{t:.0e}``,
        ``spread_{t:.0e}``, ``how_{t:.0e}``, ``tie_{t:.0e}`` (the line ties with
        a cheaper one, :func:`ties`) and ``{count}_{t:.0e}`` of
        :data:`COUNTS`, then
        ``best_err``, ``n_ok``, ``n_failed``. Sorted by CPU at the tightest
        target, then the next looser ones (not reached last), then least error.
    """
    keys, wide = None, None
    for t in targets:
        part = cpu_to_reach(rows, t, measure)
        keys = [k for k in _LINE if k in part.columns]
        tag = f"{t:.0e}"
        part = part.rename(columns={"cpu_s": f"cpu_{tag}", "how": f"how_{tag}",
                                    "spread": f"spread_{tag}",
                                    **{n: f"{n}_{tag}" for n in COUNTS}})
        part[f"tie_{tag}"] = ties(part[f"cpu_{tag}"], part[f"spread_{tag}"])
        if wide is None:
            wide = part
        else:
            wide = wide.merge(part.drop(columns=["best_err", "n_ok", "n_failed"]), on=keys)
    tail = ["best_err", "n_ok", "n_failed"]
    wide = wide[[c for c in wide.columns if c not in tail] + tail]
    order = [f"cpu_{t:.0e}" for t in reversed(list(targets))]
    return wide.sort_values(order + ["best_err"] + keys, na_position="last",
                            kind="stable").reset_index(drop=True)


def cpu_cell(cpu: float, how: str, tied: bool = False) -> str:
    """A CPU cell: ``0.123``, ``≤ 0.123`` (upper bound), ``0.123 tie`` (ties with
    a cheaper line) or ``not reached``."""
    if how == "not reached" or pd.isna(cpu):
        return "not reached"
    return f"{'≤ ' if how == 'at most' else ''}{cpu:.3g}{' tie' if tied else ''}"


def markdown_rows(table: pd.DataFrame, targets=TARGETS) -> tuple[list[str], list[list[str]]]:
    """Header and string cells of :func:`target_table`'s output, for Markdown or HTML."""
    header = ["integrator", "formulation"]
    for t in targets:
        header += [f"CPU [s] to {t:.0e}", "nsteps", "nfev", "njev", "nlu"]
    header += ["least error"]
    body = []
    for r in table.to_dict("records"):
        fixed = " (fixed h)" if r.get("mode") == "h" else ""
        cells = [str(r["integrator"]), f"{r['formulation']}{fixed}"]
        for t in targets:
            tag = f"{t:.0e}"
            cells.append(cpu_cell(r[f"cpu_{tag}"], r[f"how_{tag}"], r[f"tie_{tag}"]))
            cells += ["–" if r[f"{n}_{tag}"] is None or pd.isna(r[f"{n}_{tag}"])
                      else str(int(r[f"{n}_{tag}"])) for n in COUNTS]
        cells.append("–" if pd.isna(r["best_err"]) else f"{r['best_err']:.1e}")
        body.append(cells)
    return header, body


CAPTION = ("CPU seconds to reach a relative position error, with the problem's position "
           "scale as floor (10^-mescd: the largest mixed error |e| / (atol/rtol + |ref|) of the "
           "positions at the final time, atol/rtol the position scale; IVP Test Set), "
           "interpolated log-log between the two consecutive tolerances whose errors bracket "
           "the target, at the first crossing in order of increasing work; nsteps, nfev, njev, "
           "nlu interpolated with the same weight. ≤: the loosest tolerance is already below "
           "the target (its CPU, an upper bound; never extrapolated). tie: the line's CPU differs "
           "from a cheaper line's by less than the mean of their interquartile ranges "
           "(the median of the timed solves is the CPU). Least error: the line's "
           "least 10^-mescd. Sorted by CPU at the tightest target. (The work-precision "
           "figure's error axis is the pure relative error 10^-scd, which is larger where a "
           "reference position is near zero.)")
