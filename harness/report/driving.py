"""What the driving costs each formulation: a driven problem's records against
those of its undriven twin.

A driven problem (constraints ``g(q, t) = 0`` that move with time,
:attr:`~integrator_bench.problems.mechanical.MechanicalProblem.driven`) may declare
``undriven``, the parameter values that stop its drive (Kapitza's pendulum: the
support's amplitude ``A = 0``). Its twin is the same model, start and time span
without the driving; a bare problem name runs it beside each set
(:func:`~integrator_bench.harness.matrix.cases.with_twins`), so the quick preset
does. The comparison is measured, case by case:

* a **pair** is a record of the driven set and one of the twin, both ``ok``, of the
  same line (integrator with its settings, formulation) at the same rtol or step;
* per pair, the driven record's work over the twin's: steps and f-evals (adaptive
  pairs only: a fixed-step pair takes the same steps by construction), CPU
  (``cpu_s``, the median of its timed solves) and CPU per f-eval
  (``cpu_s / nfev``: what one evaluation costs with the Newton iterations,
  Jacobians, factorizations and projections that come with it); the digits of
  accuracy lost (the twin's ``mescd`` less the driven one's); and each one's
  drift of the position and velocity constraints;
* per formulation, the median of each over its pairs with its range (least to
  largest, the spread over integrators and tolerances), and the medians of the
  drifts.

What it measures and what it does not: the twin is the driven problem's own model
(the same compiled functions: a symbolic model whose constraint holds ``t``
evaluates ``g_t``, ``G_t`` and ``g_tt`` at ``A = 0`` too, as zeros), so the CPU
per f-eval ratio is the change in work per evaluation the driven *motion* brings
(more Newton iterations, Jacobians, projections per step), not the arithmetic of
the driving terms; and the twin moves otherwise (Kapitza's pendulum falls
instead of staying upright), so the ratios are the driven problem against the
same mechanism at rest, not two runs of one trajectory.

:func:`findings` says which formulation the driving costs most and least in
f-evals and in digits, from the medians, and calls the difference clear only
when the two formulations' ranges do not overlap and each has at least
:data:`MIN_PAIRS` values; otherwise it says they overlap or are too few.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from integrator_bench.harness.ranking.records import params_dict
from integrator_bench.harness.report.names import fmt_value

#: the columns of a pair's identity: its line and its tolerance or step
PAIR_KEYS = ("label", "formulation", "rtol", "h")
#: ``(key, header)`` of the ratio columns, driven over twin, each a median with its range
RATIOS = (("nsteps", "steps ×"), ("nfev", "f-evals ×"), ("cpu_s", "CPU ×"),
          ("cpu_per_fev", "CPU per f-eval ×"))
#: ratios taken over adaptive pairs only (a fixed-step pair's steps are the same)
ADAPTIVE_ONLY = ("nsteps", "nfev")
#: the fewest values on each side for :func:`findings` to call a difference clear
MIN_PAIRS = 3
HEADER = ("formulation", "pairs (adaptive)", *(h for _, h in RATIOS), "digits lost",
          "drift |g| driven / twin", "drift |G v + g_t| driven / twin")


def twin_params(problem_class, params: dict) -> dict | None:
    """The parameters of the undriven twin of ``problem_class`` at ``params``; None
    when the problem is not driven, declares no twin or ``params`` are the twin's."""
    undriven = getattr(problem_class, "undriven", None)
    if not (undriven and getattr(problem_class, "driven", False)):
        return None
    twin = {**params, **undriven}
    return None if twin == params else twin


def pairs(driven: pd.DataFrame, twin: pd.DataFrame) -> pd.DataFrame:
    """One row per pair (module docstring): its line, tolerance, whether adaptive,
    the ratios of :data:`RATIOS`, ``lost`` (digits) and the four drifts."""
    cols = [*PAIR_KEYS, "nsteps", "nfev", "cpu_s", "mescd", "drift_pos", "drift_vel"]
    a, b = (_ok(rows)[cols] for rows in (driven, twin))
    joined = a.merge(b, on=list(PAIR_KEYS), suffixes=("", "_twin"))
    out = joined[list(PAIR_KEYS)].copy()
    out["adaptive"] = joined["rtol"].notna()
    for key in ("nsteps", "nfev", "cpu_s"):
        out[key] = _ratio(joined[key], joined[f"{key}_twin"])
    out["cpu_per_fev"] = _ratio(_ratio(joined["cpu_s"], joined["nfev"]),
                                _ratio(joined["cpu_s_twin"], joined["nfev_twin"]))
    for key in ADAPTIVE_ONLY:
        out.loc[~out["adaptive"], key] = np.nan
    out["lost"] = _float(joined["mescd_twin"]) - _float(joined["mescd"])
    for key in ("drift_pos", "drift_vel"):
        out[key], out[f"{key}_twin"] = _float(joined[key]), _float(joined[f"{key}_twin"])
    return out


def _ok(rows: pd.DataFrame) -> pd.DataFrame:
    """The ok records, the newest of a case kept (rtol and h made comparable: NaN
    for null, which merges with itself)."""
    ok = rows[rows["status"] == "ok"].copy()
    for key in ("rtol", "h"):
        ok[key] = _float(ok[key])
    return ok.drop_duplicates(list(PAIR_KEYS), keep="last")


def _float(values) -> pd.Series:
    return pd.to_numeric(pd.Series(values), errors="coerce").astype(float)


def _ratio(num, den) -> pd.Series:
    """``num / den`` where both are finite and positive, NaN elsewhere."""
    num, den = _float(num).to_numpy(), _float(den).to_numpy()
    good = np.isfinite(num) & np.isfinite(den) & (num > 0) & (den > 0)
    return pd.Series(np.where(good, num / np.where(good, den, 1.0), np.nan))


def by_formulation(paired: pd.DataFrame) -> pd.DataFrame:
    """Per formulation (rows, by name): ``pairs``, ``adaptive`` (how many of them),
    for each ratio and ``lost`` its median, least, largest and number of values
    (``<key>``, ``<key>_lo``, ``<key>_hi``, ``<key>_n``; NaN without a value), and
    the medians of the drifts."""
    rows = []
    for form, sub in sorted(paired.groupby("formulation"), key=lambda kv: kv[0]):
        row = {"formulation": form, "pairs": len(sub), "adaptive": int(sub["adaptive"].sum())}
        for key in (*(k for k, _ in RATIOS), "lost"):
            values = sub[key].dropna()
            row.update({key: values.median(), f"{key}_lo": values.min(),
                        f"{key}_hi": values.max(), f"{key}_n": len(values)} if len(values)
                       else {key: np.nan, f"{key}_lo": np.nan, f"{key}_hi": np.nan,
                             f"{key}_n": 0})
        for key in ("drift_pos", "drift_vel"):
            row[key], row[f"{key}_twin"] = sub[key].median(), sub[f"{key}_twin"].median()
        rows.append(row)
    return pd.DataFrame(rows)


def _spread(value, lo, hi, fmt) -> str | None:
    if not math.isfinite(value):
        return None
    return fmt.format(value) if lo == hi else f"{fmt.format(value)} ({fmt.format(lo)}–" \
                                              f"{fmt.format(hi)})"


def _drift(driven, twin) -> str | None:
    if not (math.isfinite(driven) or math.isfinite(twin)):
        return None
    return " / ".join("–" if not math.isfinite(v) else f"{v:.1e}" for v in (driven, twin))


def table_rows(summary: pd.DataFrame) -> list[list]:
    """The cells of :data:`HEADER`, one row per formulation of ``summary``."""
    body = []
    for r in summary.to_dict("records"):
        body.append([r["formulation"], f"{r['pairs']} ({r['adaptive']})",
                     *(_spread(r[k], r[f"{k}_lo"], r[f"{k}_hi"], "{:.2g}") for k, _ in RATIOS),
                     _spread(r["lost"], r["lost_lo"], r["lost_hi"], "{:+.1f}"),
                     _drift(r["drift_pos"], r["drift_pos_twin"]),
                     _drift(r["drift_vel"], r["drift_vel_twin"])])
    return body


def _extremes(summary: pd.DataFrame, key: str, what: str, fmt: str) -> str | None:
    """Which formulation's median ``key`` is largest and which least, and whether
    the difference is clear: their ranges apart (the least of the one above the
    largest of the other), each over at least :data:`MIN_PAIRS` values."""
    have = summary[summary[key].notna()].sort_values([key, "formulation"])
    if len(have) < 2:
        return None
    least, most = have.iloc[0], have.iloc[-1]
    if most[key] == least[key]:
        return f"The driving costs every formulation the same {what} ({fmt.format(most[key])})."
    few = min(most[f"{key}_n"], least[f"{key}_n"]) < MIN_PAIRS
    apart = most[f"{key}_lo"] > least[f"{key}_hi"]
    return (f"The driving costs {most.formulation} the most {what} (median "
            f"{fmt.format(most[key])}) and {least.formulation} the least "
            f"({fmt.format(least[key])}): "
            + (f"too few pairs to call (fewer than {MIN_PAIRS} in one)." if few else
               "their ranges are apart, a clear difference." if apart else
               "their ranges overlap, so the difference is within the spread over "
               "integrators and tolerances."))


def findings(summary: pd.DataFrame) -> list[str]:
    """The sentences of the comparison: the extremes in f-evals (adaptive pairs) and
    in digits lost (:func:`_extremes`); none when fewer than two formulations have
    the measure."""
    found = [_extremes(summary, "nfev", "in f-evals", "×{:.2g}"),
             _extremes(summary, "lost", "in accuracy", "{:+.1f} digits lost")]
    return [f for f in found if f]


def changed(params: str, twin: str) -> str:
    """``A=0``: the twin's parameters (records' JSON) that differ from ``params``."""
    mine, theirs = params_dict(params), params_dict(twin)
    return ", ".join(f"{k}={fmt_value(v)}" for k, v in sorted(theirs.items())
                     if mine.get(k) != v)
