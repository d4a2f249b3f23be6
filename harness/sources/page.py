"""The report's part "The sources, number by number" (:func:`page`) and
``docs/seed-numbers.md`` (:func:`document`, the same part with the records it was
made from): the seeds' tables row by row
(:func:`integrator_bench.harness.sources.numbers.compare`), the sources' claims
side by side (:func:`claims`), Orlov's DUMKA3 speed-ups at his error criterion and
seed 004's own verdicts on P4-P9 (:func:`compare_orlov`, :func:`compare_cells`),
seed 000's CPU ratios at the seminar's tolerance and at matched error with the raw
counts beside them (:func:`compare_ratios`), seed 001's stiffness criterion beside
what an explicit and an implicit method did (:func:`stiffness_rows`) and the
sources' figures with no counterpart here. Every verdict is one of
:data:`integrator_bench.harness.sources.numbers.VERDICTS`, from the records
alone. What runs and what the seeds say is
:mod:`integrator_bench.harness.sources.numbers` and
:mod:`integrator_bench.harness.sources.runs`."""

from __future__ import annotations

import functools
import json
import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from integrator_bench.harness.errors import ModelFault
from integrator_bench.harness.forking.child import call
from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.line import spec_name
from integrator_bench.harness.measure import references, stiffness
from integrator_bench.harness.ranking.cost import by_cost
from integrator_bench.harness.ranking.reach import cpu_ratio, cpu_to_reach
from integrator_bench.harness.ranking.records import clean_records
from integrator_bench.harness.report import markdown
from integrator_bench.harness.report.document import Appendix, Block, Part, Table
from integrator_bench.harness.sources import numbers as sn
from integrator_bench.harness.sources.claims import CLAIM_HEADER, build, claims
from integrator_bench.harness.sources.numbers import AGREE, match, ran_through, within
from integrator_bench.harness.sources.runs import (
    EXPLICIT, HELD, IMPLICIT, MATCHED, PHYSICAL, RATIO_NOTE, RATIOS, STIFFNESS_NOTE,
    STIFFNESS_PROBLEMS, STIFFNESS_RTOL, STRUGGLE, CpuRatio, Ladder)


def ladder_records(df: pd.DataFrame, ladder: Ladder) -> pd.DataFrame:
    """The store's records of ``ladder`` (one per tolerance or step, the last
    successful one; see :func:`integrator_bench.harness.sources.numbers.match`)."""

    found = [r for case in ladder.cases() for r in [match(df, *case)] if r is not None]
    return pd.DataFrame(found)


def _cpu_at(records: pd.DataFrame, rtol: float) -> float:
    if records.empty or "rtol" not in records:
        return math.nan
    hit = records[(records["status"] == "ok")
                  & (pd.to_numeric(records["rtol"], errors="coerce") == rtol)]
    return float(hit["cpu_s"].iloc[-1]) if len(hit) else math.nan


def _reach(records: pd.DataFrame, target: float) -> tuple[float, str]:
    if records.empty:
        return math.nan, "not reached"
    (row,) = cpu_to_reach(records, target).to_dict("records")
    return row["cpu_s"], row["how"]


@dataclass
class RatioCompared:
    row: CpuRatio
    at_tol: float = math.nan              # ours at the seminar's tolerance
    matched: dict | None = None           # target -> (ratio, "=", "≤", "≥" or "")
    counts: dict | None = None            # nfev, njev, nlu: numerator's over denominator's
    work: dict | None = None              # target -> (ratio, how sure) of the method's work
    verdict: str = "cannot test"
    status: str = ""


#: the raw counts set beside seed 000's CPU ratios (the numerator's over the denominator's)
COUNTED = ("nfev", "njev", "nlu")


def _count_ratios(num: dict, den: dict) -> dict:
    out = {}
    for k in COUNTED:
        a, b = num.get(k), den.get(k)
        if a is not None and b and not pd.isna(a) and not pd.isna(b):
            out[k] = float(a) / float(b)
    return out


def compare_ratios(df: pd.DataFrame) -> list[RatioCompared]:
    """Every ratio of :data:`RATIOS` beside ours from the store's records ``df``: CPU
    at the seminar's tolerance and at matched error, the method's work at matched
    error (``work``: the counted evaluations, factorizations and solves at the
    problem's measured unit costs, :mod:`~integrator_bench.harness.ranking.cost`),
    and the raw counts (f-evaluations, Jacobians, factorizations) at the tightest
    matched error.

    The verdict, by :data:`~integrator_bench.harness.sources.numbers.RULE`, is on
    CPU, the quantity the seminar's claim speaks of (:func:`cpu_verdict`); work and
    counts are shown beside it, not voted (HHT's and Newmark's ``njev`` counts
    their tangent matrices, not Jacobians as IDA's does)."""

    out = []
    for row in RATIOS:
        num, den = ladder_records(df, row.num), ladder_records(df, row.den)
        c = RatioCompared(row)
        if num.empty or den.empty:
            c.status = "a line is not in the store"
            out.append(c)
            continue
        if row.tols is not None:
            c.at_tol = _cpu_at(num, row.tols[0]) / _cpu_at(den, row.tols[1])
        c.matched = {t: cpu_ratio(*_reach(num, t), *_reach(den, t)) for t in MATCHED}
        wn, wd = by_cost(num, "work"), by_cost(den, "work")
        c.work = {t: cpu_ratio(*_reach(wn, t), *_reach(wd, t)) for t in MATCHED}
        tight = MATCHED[-1]
        (a,), (b,) = (cpu_to_reach(x, tight).to_dict("records") for x in (num, den))
        c.counts = _count_ratios(a, b) if a["how"] != "not reached" and \
            b["how"] != "not reached" else {}
        figures = list(c.matched.values())
        if not math.isnan(c.at_tol):
            figures.append((c.at_tol, "="))
        c.verdict, c.status = cpu_verdict(figures, row.published)
        out.append(c)
    return out


def cpu_verdict(figures, published: float) -> tuple[str, str]:
    """The verdict of one seminar ratio from our CPU ratios ``figures`` (``(value,
    how)``, how ``=`` for a value, ``≤``/``≥`` for a bound, NaN for none): agrees when
    every value is within AGREE of ``published`` (bounds are no values); contradicts
    when every figure shows the ratio below 1 (a value below 1, or an upper bound
    below 1) and none shows it above; cannot test with no value or usable bound;
    differs, unexplained otherwise (the cause unknown: no run here measures one)."""
    values = [v for v, how in figures if how == "=" and not math.isnan(v)]
    below = [v for v, how in figures if not math.isnan(v) and v < 1 and how in ("=", "≤")]
    above = [v for v, how in figures if not math.isnan(v) and v >= 1 and how in ("=", "≥")]
    if not below and not above:
        return "cannot test", "no CPU ratio measured (a bound alone says nothing here)"
    bounds_fit = all(not (how == "≤" and v < published * (1 - AGREE)
                          or how == "≥" and v > published * (1 + AGREE))
                     for v, how in figures if not math.isnan(v))
    if values and bounds_fit and all(within(v / published) for v in values):
        return "agrees", ""
    if below and not above:
        return "contradicts", "reversed on CPU, the claim's quantity"
    return "differs, unexplained", "cause unknown"


def ratio_table(compared: list[RatioCompared]) -> tuple[list[str], list[tuple]]:
    """Header and rows: the seminar's ratio beside ours at its tolerance and at
    matched error, the counts, the verdict and what differs."""
    header = ["figure", "published", "ours at the seminar's ERROR",
              *(f"ours at matched error {t:g}" for t in MATCHED),
              *(f"work at matched error {t:g}" for t in MATCHED),
              f"counts at matched error {MATCHED[-1]:g} (" + ", ".join(COUNTED) + ")",
              "verdict", "what differs"]
    rows = []
    for c in compared:
        cells = [_ratio_cell(v, sure) for v, sure in (c.matched or {}).values()] or \
            ["–"] * len(MATCHED)
        cells += [_ratio_cell(v, sure) for v, sure in (c.work or {}).values()] or \
            ["–"] * len(MATCHED)
        at = "–" if math.isnan(c.at_tol) else f"{c.at_tol:.2f}"
        counts = ", ".join(f"{k} {v:.2f}" for k, v in (c.counts or {}).items()) or "–"
        verdict = f"{c.verdict}: {c.status}" if c.status else c.verdict
        rows.append((c.row.figure, f"{c.row.published:.2f}", at, *cells, counts, verdict,
                     f"{c.row.num.name} over {c.row.den.name}: {c.row.differs}"))
    return header, rows


def _ratio_cell(value: float, sure: str) -> str:
    if math.isnan(value):
        return "–"
    return f"{'' if sure == '=' else sure + ' '}{value:.2f}"


def _steps(df: pd.DataFrame, problem: str, integrator: str) -> tuple[float | None, str]:
    """The run's steps and, for one that ran to the end over the divergence bound
    (:func:`~integrator_bench.harness.sources.numbers.ran_through`), its final error."""
    records = ladder_records(df, Ladder(problem, "ode", integrator, rtols=(STIFFNESS_RTOL,)))
    if records.empty:
        return None, ""
    rec = records.iloc[-1]
    if rec["status"] == "ok":
        return float(rec["nsteps"]), ""
    if ran_through(rec):
        return float(rec["nsteps"]), f" (final error {10 ** -float(rec['mescd']):.2g})"
    return None, ""


#: (problem spec, its reference's checksum) -> its stiffness analysis (None: its stored
#: reference is not the problem's; a ModelFault: it failed): made once per process, though
#: :func:`page` runs twice a report (its part, then :func:`document`)
_ANALYSED: dict = {}
#: CPU seconds a problem's stiffness analysis (its fingerprint checked, its Jacobian's
#: spectrum at three times) may take in its process of its own
ANALYSIS_BUDGET_S = 60.0


def _checked_analysis(problem) -> dict | None:
    """The stiffness analysis of ``problem`` along its stored reference once the
    reference's fingerprint is the problem's (None when it is not): what the
    process of :func:`stiffness_rows`' call does, as every call of a model's code."""

    if references.read(problem)[0] is None:
        return None
    return stiffness.analyse(problem, stiffness.parse_times(problem, None), None)


def stiffness_rows(df: pd.DataFrame) -> tuple[list[str], list[tuple]]:
    """Seed 001's criterion on each problem beside the runs: header and rows.

    Per problem: the ADAMS stiffness ratio (its largest over the reference's start,
    middle and end) and its class, rho, the largest imaginary part, the explicit
    method's steps against ``T rho / beta`` (what its real stability interval
    forces over the span), the implicit method's steps and what that shows. A
    problem without a stored reference (its runs compute it) says so. The analysis
    (the model's code: the reference's fingerprint, the Jacobian) runs in a process of
    its own (:func:`~integrator_bench.harness.forking.child.call`, within
    :data:`ANALYSIS_BUDGET_S`), as every call of a model's code outside a case: one
    that fails there says so in its row, the report goes on.
    """

    beta = registry.get_integrator(EXPLICIT).stability_intervals[""]
    header = ["problem", "stiffness ratio", "criterion", "rho [1/s]", "max |Im| [1/s]",
              f"{EXPLICIT} steps", "T rho / beta", f"{IMPLICIT} steps",
              "explicit / implicit steps", "what the runs show"]
    rows = []
    for spec in STIFFNESS_PROBLEMS:
        problem = build(spec)
        ref = references.stored(problem)[0]   # its files only: no call of the model here
        key = ref and (spec, ref.meta["checksum"])   # the page and sources.md ask for the same
        if ref is not None and key not in _ANALYSED:
            try:
                _ANALYSED[key] = call(functools.partial(_checked_analysis, problem),
                                      "its stiffness was analysed", ANALYSIS_BUDGET_S)
            except ModelFault as exc:
                _ANALYSED[key] = exc
        got = None if ref is None else _ANALYSED[key]
        if got is None:
            rows.append((spec, "–", "no reference stored", *["–"] * 7))
            continue
        if isinstance(got, ModelFault):
            rows.append((spec, "–", f"no analysis: {got}", *["–"] * 7))
            continue
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


# --- Orlov's DUMKA3 against RK4 (seed 004 and the 2017 slides) -------------------------

@dataclass
class OrlovCompared:
    """One of the slides' speed-ups beside ours at Orlov's error criterion."""

    k: int
    h: float
    published: float
    cell_err: float = math.nan          # the cell's pin-force error E
    rk4_h: float = math.nan             # RK4's largest step here meeting the criterion
    rk4_err: float = math.nan
    cpu: float = math.nan               # RK4's CPU over the cell's
    nfev: float = math.nan              # RK4's f-evaluations over the cell's
    work: float = math.nan              # RK4's work over the cell's (record's ``work``)
    edge_h: float = math.nan            # RK4's next larger step run, missing the criterion
    edge_err: float = math.nan
    edge_cpu: float = math.nan          # the speed-up against RK4 at that step (CPU)
    edge_nfev: float = math.nan
    verdict: str = "cannot test"
    status: str = ""


def _err(record) -> float:
    value = None if record is None else record.get("monitor_err")
    return math.nan if value is None or pd.isna(value) else float(value)


def rk4_matched(df: pd.DataFrame):
    """RK4's record at its largest step (of :data:`~integrator_bench.harness.sources.numbers.RK4_HS`)
    whose pin-force error meets Orlov's criterion, the record at the next larger step
    run (which misses it; None when none ran), and every RK4 record by step."""
    runs = {h: sn.match(df, *sn.rk4_case(h)) for h in sn.RK4_HS}
    good = [(h, r) for h, r in runs.items()
            if r is not None and r["status"] == "ok" and _err(r) <= sn.ORLOV_E]
    if not good:
        return None, None, runs
    h_ok, rk4 = max(good, key=lambda x: x[0])
    larger = [(h, r) for h, r in runs.items() if h > h_ok and r is not None
              and r["status"] == "ok"]
    edge = min(larger, key=lambda x: x[0])[1] if larger else None
    return rk4, edge, runs


def compare_orlov(df: pd.DataFrame) -> list[OrlovCompared]:
    """The slides' speed-ups (:data:`~integrator_bench.harness.sources.numbers.ORLOV_SPEEDUPS`)
    at matched accuracy: the cell meets Orlov's E <= 0.05, and RK4's largest step
    that does lies between its largest run step that meets it and the next larger
    run step, which misses it; the speed-up is bracketed by the two (CPU,
    f-evaluation and work ratios: RK4's over the cell's; the work: counted
    evaluations at the problem's measured unit costs,
    :mod:`~integrator_bench.harness.ranking.cost`). Verdict by
    :data:`~integrator_bench.harness.sources.numbers.RULE` on the CPU bracket
    (Orlov's figures are of simulation times): agrees when both ends are within
    AGREE, contradicts when both are below 1 (RK4 faster), differs, unexplained when
    both lie on one side outside AGREE (cause unknown), cannot test when the bracket
    straddles AGREE's edge (the criterion's edge decides) or has one end only."""
    rk4, edge, _ = rk4_matched(df)
    out = []
    for k, h, published in sn.ORLOV_SPEEDUPS:
        c = OrlovCompared(k, h, published)
        cell = sn.match(df, *sn.orlov_cell(k, h))
        c.cell_err = _err(cell)
        if cell is None or cell["status"] != "ok":
            c.status = "the cell is not in the store or did not succeed"
        elif not c.cell_err <= sn.ORLOV_E:
            c.status = f"the cell misses E <= {sn.ORLOV_E:g} here (E {c.cell_err:.2g})"
        elif rk4 is None:
            c.status = f"no RK4 run meets E <= {sn.ORLOV_E:g}"
        else:
            c.rk4_h, c.rk4_err = float(rk4["h"]), _err(rk4)
            c.cpu = float(rk4["cpu_s"]) / float(cell["cpu_s"])
            c.nfev = float(rk4["nfev"]) / float(cell["nfev"])
            c.work = _ratio(rk4.get("work"), cell.get("work"))
            if edge is not None:
                c.edge_h, c.edge_err = float(edge["h"]), _err(edge)
                c.edge_cpu = float(edge["cpu_s"]) / float(cell["cpu_s"])
                c.edge_nfev = float(edge["nfev"]) / float(cell["nfev"])
            c.verdict, c.status = _bracket_verdict(c.edge_cpu, c.cpu, published)
        out.append(c)
    return out


def _bracket_verdict(low: float, high: float, published: float) -> tuple[str, str]:
    """The verdict of a speed-up known to lie in ``(low, high]`` (NaN ``low``: only
    ``high`` is known)."""
    if math.isnan(low):
        return ("cannot test", "RK4's largest run step meets the criterion: a larger "
                               "step was not run, so the speed-up is a bound only")
    ends = (low, high)
    if all(within(v / published) for v in ends):
        return "agrees", ""
    if all(v < 1 for v in ends):
        return "contradicts", "RK4 faster at both ends"
    if all(v > published * (1 + AGREE) for v in ends) or \
            all(v < published * (1 - AGREE) for v in ends):
        return "differs, unexplained", "cause unknown"
    return ("cannot test", f"the criterion's edge decides: the speed-up lies in "
                           f"{low:.2f}-{high:.2f}, across {AGREE:.0%} of the slides'")


def orlov_table(compared: list[OrlovCompared], df: pd.DataFrame) -> tuple[list, list, str]:
    """Header, rows and a note (RK4's runs) of the speed-ups at matched accuracy."""
    header = ["cell", "speed-up (slides)", "cell's E", "RK4 step here (E)",
              "ours: CPU ratio", "ours: f-evaluation ratio", "ours: work ratio",
              "RK4 at the next step (E), missing the criterion: CPU, f-evaluation ratio",
              "verdict"]
    rows = [(f"P{c.k} at h = {c.h:g}", f"{c.published:g}", _g(c.cell_err),
             "–" if math.isnan(c.rk4_h) else f"{c.rk4_h:g} ({_g(c.rk4_err)})", _f(c.cpu),
             _f(c.nfev), _f(c.work),
             "–" if math.isnan(c.edge_h) else
             f"{c.edge_h:g} ({_g(c.edge_err)}): {_f(c.edge_cpu)}, {_f(c.edge_nfev)}",
             f"{c.verdict}: {c.status}" if c.status else c.verdict)
            for c in compared]
    _, _, runs = rk4_matched(df)
    note = "; ".join(f"h {h:g}: " + ("not in the store" if r is None else
                                      f"{r['status']}, E {_g(_err(r))}, CPU "
                                      f"{float(r['cpu_s']):.3g} s, nfev {int(r['nfev'])}")
                     for h, r in runs.items())
    return header, rows, note


def orlov_quote(df: pd.DataFrame) -> str:
    """The page's speed-up figures as docs/study-cvt.md quotes them (its test checks
    the study against this sentence of the page's records)."""
    got = [c for c in compare_orlov(df) if not math.isnan(c.cpu)]
    _, _, runs = rk4_matched(df)
    if not got:
        return ""
    c0 = got[0]

    def listed(values) -> str:
        values = [f"{v:.2f}" for v in values]
        return ", ".join(values[:-1]) + " and " + values[-1]

    stable = runs.get(min(sn.RK4_HS))
    cells = {(c.k, c.h): sn.match(df, *sn.orlov_cell(c.k, c.h)) for c in got}
    text = (f"the sources page (`docs/seed-numbers.md`) has, against RK4 at {c0.rk4_h:g} s "
            f"(E = {c0.rk4_err:.2g}, its largest step run here that meets E <= 0.05), "
            f"{listed(c.cpu for c in got)} in CPU and {listed(c.nfev for c in got)} in "
            f"f-evaluations")
    if not math.isnan(c0.edge_h):
        text += (f"; against RK4 at {c0.edge_h:g} s (E = {c0.edge_err:.2g}, just missing "
                 f"it) {listed(c.edge_cpu for c in got)} in CPU, so the criterion's edge "
                 f"decides the figures")
    if stable is not None and stable["status"] == "ok":
        text += (f"; against RK4 at {float(stable['h']):g} s (E = {_err(stable):.2g}) "
                 + listed(float(stable["cpu_s"]) / float(cells[(c.k, c.h)]["cpu_s"])
                          for c in got) + " in CPU")
    return text + "."


def _ratio(a, b) -> float:
    """``a / b`` of two record values, NaN where either is missing or not positive."""
    try:
        a, b = float(a), float(b)
    except (TypeError, ValueError):
        return math.nan
    return a / b if a > 0 and b > 0 else math.nan


def _g(x) -> str:
    return "–" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.2g}"


def _f(x) -> str:
    return "–" if math.isnan(x) else f"{x:.2f}"


@dataclass
class CellCompared:
    k: int
    h: float
    seed004: str        # "accurate" or "not accurate"
    slides: str         # good, bad, failed, untested
    ours: str = "–"
    err: float = math.nan
    verdict: str = "cannot test"


def compare_cells(df: pd.DataFrame) -> list[CellCompared]:
    """Seed 004's own verdicts on P4-P9 at 2e-6 and 4e-6 s beside the slides' grid
    and ours (accurate: the run ends with E <= 0.05): agrees or contradicts seed 004;
    a cell the slides mark untested cannot test (seed 004's "only P8" measured
    nothing there)."""
    out = []
    for h, accurate in sn.SEED004_ACCURATE.items():
        for k in sn.ORLOV_POLYNOMIALS:
            c = CellCompared(k, h, "accurate" if k in accurate else "not accurate",
                             sn.SLIDES_GRID[(k, h)])
            rec = sn.match(df, *sn.orlov_cell(k, h))
            if rec is not None:
                c.err = _err(rec)
                good = rec["status"] == "ok" and c.err <= sn.ORLOV_E
                c.ours = "accurate" if good else (
                    "not accurate" if rec["status"] == "ok" else f"not accurate ({rec['status']})")
                c.verdict = ("cannot test" if c.slides == "untested" else
                             "agrees" if (c.ours == "accurate") == (c.seed004 == "accurate")
                             else "contradicts")
            out.append(c)
    return out


def cells_table(compared: list[CellCompared]) -> tuple[list, list]:
    header = ["polynomial", "h [s]", "seed 004", "slides", "ours", "E", "verdict"]
    return header, [(f"P{c.k}", f"{c.h:g}", c.seed004, c.slides, c.ours, _g(c.err),
                     c.verdict) for c in compared]


ORLOV_NOTE = (
    "Orlov's criterion (seed 004, eq. (3) and Section 3.4): the relative pin-force error "
    "E = max |P - P*| / max |P*| over [0.001, 0.005] s; a solution with E > 0.05 is "
    "unacceptable. The speed-ups 5.9, 4.7 and 4.4 and RK4's step 5e-8 s are from the "
    "slides (Orlov, Kuzin and Shabrov, Russian Supercomputing Days 2017, public "
    "repository deadmorous/rsd-2017, docs/speedup.html: '5.9x practical speedup "
    "(DUMKA-p5 @2e-6 vs RK4 @5e-8)' and the grid's cells); seed 004's Table 1 of "
    "speed-ups survives in its text as headings only. Ours compares at matched accuracy: "
    "the cell meets E <= 0.05, and so does RK4 at its largest step here that does; as "
    "ratios of CPU, of f-evaluations and of work. RK4 runs at 5e-8, 4e-8 and 2.5e-8 s "
    "only: its largest step meeting the criterion lies between the largest run step that "
    "meets it and the next larger one, which misses it, so the speed-up lies between the "
    "two ratios shown, and the criterion's edge decides within that range.")

CELLS_NOTE = (
    "Seed 004 (Section 3.6): 'schemes DUMKA3-P5 - DUMKA3-P8 give sufficiently accurate "
    "solution at step 2 10, and at step 4 10 only the scheme DUMKA3-P8 does so' (the "
    "exponents are lost in the text; the slides give 2e-6 and 4e-6 s) and 'Polynomials 4 "
    "and 9 have shown poor performance' (no step given: tested at both). The slides' grid "
    "(good, bad, failed, untested) beside it; ours: accurate when the run ends with E <= "
    "0.05.")


def tuning_table(records) -> tuple[list, list]:
    """The alpha sweep of each ICS problem, header and rows
    (:func:`~integrator_bench.harness.sources.numbers.tune_alpha`)."""
    header = (["problem", "alpha = beta"]
              + [f"TOL {t:g}: NS, NF, failed, drift_pos" for t in sn.ICS_TOLS]
              + ["violation (sum log10 drift_pos)", "failed steps (sum)", "rank sum",
                 "chosen"])
    rows = []
    for problem in sn.ICS_PROBLEMS:
        t = sn.tune_alpha(records, problem)
        for alpha in sn.ICS_ALPHAS:
            cells = []
            for tol in sn.ICS_TOLS:
                r = t.runs[alpha][tol]
                cells.append("did not succeed" if r is None else
                             f"{r['nsteps']:.0f}, {r['nfev']:.0f}, "
                             f"{r['nreject'] + r['nnfail']:.0f}, {r['drift_pos']:.2g}")
            rows.append((problem, f"{alpha:g}", *cells,
                         f"{t.violation[alpha]:.2f}" if alpha in t.violation else "–",
                         f"{t.failed[alpha]:.0f}" if alpha in t.failed else "–",
                         f"{t.rank_sum[alpha]:g}" if alpha in t.rank_sum else "not admissible",
                         "chosen" if alpha == t.chosen else ""))
    return header, rows


TUNING_NOTE = (
    "Sudarsan and Keerthi choose ICS's alpha per problem: 'We start with alpha = 0 (i.e., "
    "integrating just the underlying ODE) and slowly increase its value. By looking at the "
    "amount of constraint violation and the number of failed integration steps a proper "
    "(optimal) alpha is chosen' (Section 5.1; Remark 5.1 says 'by looking at the solution "
    "plots'); they give neither the values nor beta. Here the same two indicators make a "
    "rule: alpha = beta swept from 0 with CVODE-Adams on the baumgarte formulation "
    "(`PROBLEM:baumgarte_alpha=A`) at the three TOLs; an alpha is admissible when every "
    "TOL's run succeeds; the constraint violation (the sum over the TOLs of log10 of the "
    "largest position residual) and the failed steps (rejected steps plus Newton "
    "failures, summed) are ranked each, counting equally; the least rank sum is chosen, "
    "a tie going to the smaller alpha. The ICS rows above show the project's default alpha "
    "= beta = 10 and, as the cause's run, the chosen one. NS, NF, failed steps and "
    "drift_pos per TOL.")


# --- the page -------------------------------------------------------------------------

def page(records: pd.DataFrame):
    """The part "The sources, number by number" of the records (with every field: a
    report's cleaned records, :func:`~integrator_bench.harness.ranking.records.clean_records`):
    its caption and blocks (:class:`~integrator_bench.harness.report.document.Block`),
    or None when the store holds none of the seeds' runs."""

    compared = sn.compare(records)
    if all(c.status == "not in the store" or c.row.not_run for c in compared):
        return None
    ratios, orlov, cells = compare_ratios(records), compare_orlov(records), \
        compare_cells(records)
    claim_rows = claims(records, compared, ratios, orlov, cells)
    ratio_rows = sn.within_table_ratios(compared)
    every = ([c.verdict for c in compared] + [r[-1] for r in ratio_rows if r[-1] != "–"]
             + [c.verdict for c in ratios] + [c.verdict for c in orlov]
             + [c.verdict for c in cells] + ["cannot test"] * len(sn.UNTESTED))
    counts = dict.fromkeys(sn.VERDICTS, 0)
    for v in every:
        counts[v] += 1
    claim_counts = dict.fromkeys(sn.VERDICTS, 0)
    for r in claim_rows:
        claim_counts[r[-1]] += 1
    blocks = [Block(title="The rule", text=[rule_text()])]
    blocks += [Block(title="The sources' claims, side by side",
                    text=[sn.summary_line(claim_counts, "claims")],
                    tables=[Table(list(CLAIM_HEADER), claim_rows)])]
    blocks += [Block(title=title, tables=[Table(list(sn.TABLE_HEADER), rows,
                                                ("ours / published",))])
               for title, rows in sn.tables(compared)]
    header, rows = tuning_table(records)
    blocks.append(Block(title="seed 003: Baumgarte's alpha for ICS, tuned as the paper tunes it",
                        text=[TUNING_NOTE], tables=[Table(header, rows)]))
    if ratio_rows:
        blocks.append(Block(title="Ratios between the methods of one table (seed 003: each "
                                  "approach over PA)",
                            text=["Judged (verdict) where the table's counts cannot agree "
                                  "by construction (seed 002's Table 2: 30 s there, 1 s "
                                  "here), on NS and NF; shown elsewhere."],
                            tables=[Table(["table", "row", "ratio", "source", "ours",
                                           "verdict"], ratio_rows, ("source", "ours"))]))
    header, rows, note = orlov_table(orlov, records)
    blocks.append(Block(title="seed 004 and the 2017 slides: DUMKA3 over RK4 at Orlov's "
                              "error criterion", text=[ORLOV_NOTE, "RK4 here: " + note],
                        tables=[Table(header, rows, tuple(header[1:6]))]))
    header, rows = cells_table(cells)
    blocks.append(Block(title="seed 004's own verdicts on P4-P9 beside the slides' grid and "
                              "ours", text=[CELLS_NOTE], tables=[Table(header, rows)]))
    header, rows = ratio_table(ratios)
    blocks.append(Block(title="seed 000, the ADAMS seminar's CPU ratios beside ours",
                        text=[RATIO_NOTE],
                        tables=[Table(header, rows, tuple(header[1:5]))]))
    header, rows = stiffness_rows(records)
    blocks.append(Block(title="seed 001, the ADAMS course's stiffness criterion on the "
                              "seeds' problems", text=[STIFFNESS_NOTE],
                        tables=[Table(header, rows, tuple(header[1:9]))]))
    blocks.append(Block(title="Figures of the sources with no counterpart here (cannot test)",
                        tables=[Table(["seed", "where", "figures", "why"],
                                      [tuple(u) for u in sn.UNTESTED])]))
    caption = (sn.summary_line(counts) + " Every row of the tables below, each judged "
               "ratio between codes, each of seed 000's ratios, Orlov's speed-ups and cells, "
               "and each figure with no counterpart counts once; the verdicts follow the "
               "rule below.")
    return caption, blocks


def rule_text() -> str:
    """The page's one rule (:data:`~integrator_bench.harness.sources.numbers.RULE`
    and :data:`~integrator_bench.harness.sources.numbers.COMBINE`), as it states it."""
    return ("A row, a ratio or a cell: " + "; ".join(f"**{v}**: {sn.RULE[v]}"
                                                      for v in sn.VERDICTS)
            + ". A claim of the sources (the headline): " + sn.COMBINE + ".")


# --- docs/seed-numbers.md: the page as a document, with the records it was made from ------

#: the records' fields the page reads (:func:`page`), embedded in the document
DOC_FIELDS = ("problem", "params", "formulation", "integrator", "settings", "rtol", "h",
              "status", "reason", "mescd", "err_max", "err_rms", "scd", "final_degenerate",
              "monitor_err", "cpu_s", "cpu_s_iqr", "nfev", "njev", "nlu", "nsteps",
              "nnfail", "nniter", "nreject", "nevents", "events_by_kind", "drift_pos",
              "solver_counts", "code_version", "mode", "work")
DOC_RECORDS = "<!-- the records this document was generated from (sources.document) -->"

DOC_INTRO = """# The sources, number by number

Generated by `ibench report` (its `sources.md`, copied here) from the records of the
`seeds` preset; the same part is in the report's `index.md` and `index.html`. Do not edit
by hand: `tests/harness/sources/test_seed_doc.py` regenerates this file from the records embedded at its
end and fails on any difference. To regenerate:

```sh
.venv/bin/ibench run --preset seeds --jobs 2 --store results/seeds.sqlite
.venv/bin/ibench report --store results/seeds.sqlite
cp results/report/sources.md docs/seed-numbers.md
```

Every table of the seed documents that reports run statistics, row by row, beside the
project's run of the closest configuration, each seed's claims side by side, Orlov's
DUMKA3 speed-ups at his error criterion and seed 000's CPU ratios with the raw counts
beside them. The rows, the configurations and what differs are data in
`harness/sources/numbers.py` and `harness/sources/runs.py`. Each row has one of six
verdicts, from the records alone, by the one rule the page states ("The rule", below;
`tests/harness/sources/test_seed_doc.py` checks every row against it). Where a source contradicts
itself, the row says so. Earlier studies of these sources (the quick-return
at TOL 1e-2, SERK2, Orlov's full grid) are in [seed-studies.md](seed-studies.md).
"""


def _doc_records(records: pd.DataFrame) -> pd.DataFrame:
    """The records the page can match: those of the problems, formulations and
    integrators of the preset's cases, with :data:`DOC_FIELDS`."""
    wanted = {(spec_name(p), f, spec_name(i)) for p, f, i, _, _ in sn.preset_cases()}
    keep = [(p, f, i) in wanted for p, f, i in
            zip(records["problem"], records["formulation"], records["integrator"])]
    sub = records[keep]
    return sub.reindex(columns=list(DOC_FIELDS)).reset_index(drop=True)


def part(records: pd.DataFrame) -> Part | None:
    """The part "The sources, number by number": the seeds' tables and claims beside
    the project's closest runs (:func:`page`); None when the records hold none of
    those runs."""
    got = page(records)
    if got is None:
        return None
    caption, blocks = got
    return Part("sources", "The sources, number by number", caption=caption, blocks=blocks)


def appendix(records: pd.DataFrame) -> Appendix | None:
    """The report's appendix of the (cleaned) records
    (:attr:`~integrator_bench.harness.report.write.ReportOptions.appendix`): their
    :func:`part` and ``sources.md``, its :func:`document`; None without the part."""
    got = part(records)
    return None if got is None else Appendix(got, "sources.md", document(records))


def document(records: pd.DataFrame) -> str:
    """``docs/seed-numbers.md``: :data:`DOC_INTRO`, the commits the records were run
    by, the part :func:`page` gives for the records, and the records themselves (as
    JSON, so that :func:`document` of them gives the same text)."""

    sub = _doc_records(records)
    got = part(clean_records(sub))
    if got is None:
        return ""
    commits = sorted({str(v) for v in sub.get("code_version", pd.Series(dtype=str)).dropna()})
    lines = [DOC_INTRO, f"Run by code {', '.join(commits) or 'unknown'}, {len(sub)} records.",
             ""]
    # as the report's index.md writes the part (escaped), so that the two read the same
    lines += [markdown.escaped("\n".join(markdown.part(got)))]
    data = [{k: _plain(v) for k, v in r.items()} for r in sub.to_dict("records")]
    lines += [DOC_RECORDS, "", "```json", json.dumps(data, sort_keys=True, indent=0), "```",
              ""]
    return "\n".join(lines)


def _plain(value):
    """A record's value as JSON keeps it the same way whatever its column's dtype:
    numbers as floats, missing values as null."""
    if value is None or (not isinstance(value, str) and pd.isna(value)):
        return None
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, float, np.integer, np.floating)):
        return float(value)
    return value
