"""The seeds' stated ratios and criterion beside the project's runs (the rows of
the report's "The sources, number by number"): seed 000's CPU ratios at the
seminar's tolerance and at matched error, seed 001's stiffness criterion beside
what an explicit and an implicit method did. What runs and what the seeds say is
:mod:`integrator_bench.harness.model.seed_runs`."""

from __future__ import annotations

import math
from dataclasses import dataclass

import pandas as pd

from integrator_bench.harness.model.seed_runs import (
    EXPLICIT, HELD, IMPLICIT, MATCHED, PHYSICAL, RATIOS, STIFFNESS_PROBLEMS, STIFFNESS_RTOL,
    STRUGGLE, CpuRatio, Line)


def line_records(df: pd.DataFrame, line: Line) -> pd.DataFrame:
    """The store's records of ``line`` (one per tolerance or step, the last
    successful one; see :func:`integrator_bench.harness.model.seed_numbers.match`)."""
    from integrator_bench.harness.model.seed_numbers import match

    found = [r for case in line.cases() for r in [match(df, *case)] if r is not None]
    return pd.DataFrame(found)


def _cpu_at(records: pd.DataFrame, rtol: float) -> float:
    if records.empty or "rtol" not in records:
        return math.nan
    hit = records[(records["status"] == "ok")
                  & (pd.to_numeric(records["rtol"], errors="coerce") == rtol)]
    return float(hit["cpu_s"].iloc[-1]) if len(hit) else math.nan


def _reach(records: pd.DataFrame, target: float) -> tuple[float, str]:
    from integrator_bench.harness.report.targets import cpu_to_reach
    if records.empty:
        return math.nan, "not reached"
    (row,) = cpu_to_reach(records, target).to_dict("records")
    return row["cpu_s"], row["how"]


@dataclass
class RatioCompared:
    row: CpuRatio
    at_tol: float = math.nan              # ours at the seminar's tolerance
    matched: dict | None = None           # target -> (ratio, "=", "≤", "≥" or "")
    verdict: str = "not run"


def compare_ratios(df: pd.DataFrame) -> list[RatioCompared]:
    """Every ratio of :data:`RATIOS` beside ours from the store's records ``df``."""
    from integrator_bench.harness.report.targets import cpu_ratio
    from integrator_bench.harness.model.seed_numbers import AGREE

    out = []
    for row in RATIOS:
        num, den = line_records(df, row.num), line_records(df, row.den)
        c = RatioCompared(row)
        if num.empty or den.empty:
            out.append(c)
            continue
        if row.tols is not None:
            c.at_tol = _cpu_at(num, row.tols[0]) / _cpu_at(den, row.tols[1])
        c.matched = {t: cpu_ratio(*_reach(num, t), *_reach(den, t)) for t in MATCHED}
        ours = [v for v, _ in c.matched.values() if not math.isnan(v)] + \
            ([c.at_tol] if not math.isnan(c.at_tol) else [])
        # every figure of ours must agree (within the counts' AGREE): no picking one
        close = [abs(v / row.published - 1) <= AGREE for v in ours]
        c.verdict = ("agrees" if close and all(close) else "explained in part" if ours
                     else "not run")
        out.append(c)
    return out


def ratio_table(compared: list[RatioCompared]) -> tuple[list[str], list[tuple]]:
    """Header and rows: the seminar's ratio beside ours at its tolerance and at
    matched error, the verdict and what differs."""
    header = ["figure", "published", "ours at the seminar's ERROR",
              *(f"ours at matched error {t:g}" for t in MATCHED), "verdict", "what differs"]
    rows = []
    for c in compared:
        cells = [_ratio_cell(v, sure) for v, sure in (c.matched or {}).values()] or \
            ["–"] * len(MATCHED)
        at = "–" if math.isnan(c.at_tol) else f"{c.at_tol:.2f}"
        rows.append((c.row.figure, f"{c.row.published:.2f}", at, *cells, c.verdict,
                     f"{c.row.num.name} over {c.row.den.name}: {c.row.differs}"))
    return header, rows


def _ratio_cell(value: float, sure: str) -> str:
    if math.isnan(value):
        return "–"
    return f"{'' if sure == '=' else sure + ' '}{value:.2f}"


def _problem(spec: str):
    from integrator_bench.harness.model import registry
    from integrator_bench.harness.model.cases import parse_problem_spec
    (params,) = parse_problem_spec(spec)
    return registry.get_problem_class(spec.partition(":")[0])(**params)


def _steps(df: pd.DataFrame, problem: str, integrator: str) -> tuple[float | None, str]:
    """The run's steps and, for one that ran to the end over the divergence bound
    (:func:`~integrator_bench.harness.model.seed_numbers.ran_through`), its final error."""
    from integrator_bench.harness.model.seed_numbers import ran_through
    records = line_records(df, Line(problem, "ode", integrator, rtols=(STIFFNESS_RTOL,)))
    if records.empty:
        return None, ""
    rec = records.iloc[-1]
    if rec["status"] == "ok":
        return float(rec["nsteps"]), ""
    if ran_through(rec):
        return float(rec["nsteps"]), f" (final error {10 ** -float(rec['mescd']):.2g})"
    return None, ""


def stiffness_rows(df: pd.DataFrame) -> tuple[list[str], list[tuple]]:
    """Seed 001's criterion on each problem beside the runs: header and rows.

    Per problem: the ADAMS stiffness ratio (its largest over the reference's start,
    middle and end) and its class, rho, the largest imaginary part, the explicit
    method's steps against ``T rho / beta`` (what its real stability interval
    forces over the span), the implicit method's steps and what that shows. A
    problem without a stored reference (its runs compute it) says so.
    """
    from integrator_bench.harness.measure import references, stiffness
    from integrator_bench.harness.model import registry

    beta = registry.get_integrator(EXPLICIT).stability_intervals[""]
    header = ["problem", "stiffness ratio", "criterion", "rho [1/s]", "max |Im| [1/s]",
              f"{EXPLICIT} steps", "T rho / beta", f"{IMPLICIT} steps",
              "explicit / implicit steps", "what the runs show"]
    rows = []
    for spec in STIFFNESS_PROBLEMS:
        problem = _problem(spec)
        if references.read(problem)[0] is None:
            rows.append((spec, "–", "no reference stored", *["–"] * 7))
            continue
        got = stiffness.analyse(problem, stiffness.parse_times(problem, None), None)
        ratios = [f["ratio"] for f in got["times"] if f["ratio"] is not None]
        ratio = max(ratios) if ratios else None
        verdict = stiffness.classify(ratio)
        rho = got["rho"]
        imag = max(f["max_imag"] for f in got["times"])
        bound = (problem.t_span[1] - problem.t_span[0]) * rho / beta
        (ex, ex_note), (im, im_note) = _steps(df, spec, EXPLICIT), _steps(df, spec, IMPLICIT)
        rows.append((spec, "–" if ratio is None else f"{ratio:.3g}", verdict, f"{rho:.3g}",
                     f"{imag:.3g}", _int(ex) + ex_note, f"{bound:.3g}", _int(im) + im_note,
                     "–" if not (ex and im) else f"{ex / im:.2g}",
                     shows(verdict, ex, im, bound, physical=imag >= PHYSICAL * rho)))
    return header, rows


def _int(x) -> str:
    return "–" if x is None else f"{int(x)}"


def shows(verdict: str, explicit: float | None, implicit: float | None, bound: float,
          physical: bool = False) -> str:
    """What the explicit method's steps say beside the criterion's class.

    It struggles when it takes :data:`STRUGGLE` times the implicit method's steps
    (without an implicit run: when held by its stability, at least :data:`HELD`
    of ``T rho / beta``). ``physical``: the fastest mode is underdamped (largest
    imaginary part near rho), the course's physical stiffness."""
    if explicit is None:
        return "the explicit run is not in the store (or did not succeed)"
    struggles = (explicit >= STRUGGLE * implicit if implicit
                 else explicit >= HELD * bound)
    if struggles and verdict == "stiff":
        return "explicit struggles, as the criterion says"
    if struggles and physical:
        return ("explicit struggles although the criterion says " + verdict + ": the fast "
                "modes are lightly damped (physical stiffness, which the course says all "
                "methods have problems with; the implicit method steps over them)")
    if struggles:
        return f"explicit struggles; the criterion says {verdict}"
    if verdict == "stiff":
        return "the criterion says stiff, but the explicit method keeps up at this tolerance"
    if physical:
        return (f"explicit keeps up, as the criterion ({verdict}) says; the fastest mode is "
                "underdamped and resolved by both (physical stiffness, if any)")
    return f"explicit keeps up, as the criterion ({verdict}) says"
