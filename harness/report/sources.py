"""The report's part "The sources, number by number" (:func:`page`) and
``docs/seed-numbers.md`` (:func:`document`, the same part with the records it was
made from): the seeds' tables row by row
(:func:`integrator_bench.harness.matrix.source_numbers.compare`), the sources' claims
side by side (:func:`claims`), Orlov's DUMKA3 speed-ups at his error criterion and
seed 004's own verdicts on P4-P9 (:func:`compare_orlov`, :func:`compare_cells`),
seed 000's CPU ratios at the seminar's tolerance and at matched error with the raw
counts beside them (:func:`compare_ratios`), seed 001's stiffness criterion beside
what an explicit and an implicit method did (:func:`stiffness_rows`) and the
sources' figures with no counterpart here. Every verdict is one of
:data:`integrator_bench.harness.matrix.source_numbers.VERDICTS`, from the records
alone. What runs and what the seeds say is
:mod:`integrator_bench.harness.matrix.source_numbers` and
:mod:`integrator_bench.harness.matrix.source_runs`."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from integrator_bench.harness.matrix.source_runs import (
    EXPLICIT, HELD, IMPLICIT, MATCHED, PHYSICAL, RATIOS, STIFFNESS_PROBLEMS, STIFFNESS_RTOL,
    STRUGGLE, CpuRatio, Line)


def line_records(df: pd.DataFrame, line: Line) -> pd.DataFrame:
    """The store's records of ``line`` (one per tolerance or step, the last
    successful one; see :func:`integrator_bench.harness.matrix.source_numbers.match`)."""
    from integrator_bench.harness.matrix.source_numbers import match

    found = [r for case in line.cases() for r in [match(df, *case)] if r is not None]
    return pd.DataFrame(found)


def _cpu_at(records: pd.DataFrame, rtol: float) -> float:
    if records.empty or "rtol" not in records:
        return math.nan
    hit = records[(records["status"] == "ok")
                  & (pd.to_numeric(records["rtol"], errors="coerce") == rtol)]
    return float(hit["cpu_s"].iloc[-1]) if len(hit) else math.nan


def _reach(records: pd.DataFrame, target: float) -> tuple[float, str]:
    from integrator_bench.harness.ranking.reach import cpu_to_reach
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
    problem's measured unit costs, :mod:`~integrator_bench.harness.ranking.cost`: a
    measure that does not favour IDA's compiled code over the in-house Python
    HHT and Newmark), and the raw counts (f-evaluations, Jacobians,
    factorizations) at the tightest matched error. The seminar's ratios are
    all above 1 (its index-3 codes faster): ours *contradicts* when every CPU
    figure, every work figure and every count is below 1, *agrees* when every CPU
    figure is within :data:`~integrator_bench.harness.matrix.source_numbers.AGREE`,
    and *differs, unexplained* otherwise (no run here changes the seminar's
    configuration differences: model size, code, machine)."""
    from integrator_bench.harness.ranking.cost import by_cost
    from integrator_bench.harness.ranking.reach import cpu_ratio, cpu_to_reach
    from integrator_bench.harness.matrix.source_numbers import AGREE

    out = []
    for row in RATIOS:
        num, den = line_records(df, row.num), line_records(df, row.den)
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
        ours = [v for v, _ in c.matched.values() if not math.isnan(v)] + \
            ([c.at_tol] if not math.isnan(c.at_tol) else [])
        work = [v for v, _ in c.work.values() if not math.isnan(v)]
        if not ours:
            c.status = "neither line reaches a matched error"
        elif all(abs(v / row.published - 1) <= AGREE for v in ours):
            c.verdict = "agrees"
        elif all(v < 1 for v in ours + work) and all(v < 1 for v in c.counts.values()):
            c.verdict = "contradicts"
            c.status = "reversed on CPU, on work and on every count"
        else:
            c.verdict = "differs, unexplained"
            if all(v < 1 for v in ours):
                c.status = ("reversed on CPU, not on work" if work and not all(
                    v < 1 for v in work) else "reversed on CPU and on work, not on every "
                    "count" if work else "reversed on CPU, not on every count")
        out.append(c)
    return out


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


def _problem(spec: str):
    from integrator_bench.harness.matrix.cases import parse_problem_spec
    (pspec,) = parse_problem_spec(spec)
    return pspec.build()


def _steps(df: pd.DataFrame, problem: str, integrator: str) -> tuple[float | None, str]:
    """The run's steps and, for one that ran to the end over the divergence bound
    (:func:`~integrator_bench.harness.matrix.source_numbers.ran_through`), its final error."""
    from integrator_bench.harness.matrix.source_numbers import ran_through
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
    from integrator_bench.harness.matrix import registry

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
    verdict: str = "cannot test"
    status: str = ""


def _err(record) -> float:
    value = None if record is None else record.get("monitor_err")
    return math.nan if value is None or pd.isna(value) else float(value)


def rk4_matched(df: pd.DataFrame):
    """RK4's record at its largest step (of :data:`~integrator_bench.harness.matrix.source_numbers.RK4_HS`)
    whose pin-force error meets Orlov's criterion, and every RK4 record by step."""
    from integrator_bench.harness.matrix import source_numbers as sn
    runs = {h: sn.match(df, *sn.rk4_case(h)) for h in sn.RK4_HS}
    good = [(h, r) for h, r in runs.items()
            if r is not None and r["status"] == "ok" and _err(r) <= sn.ORLOV_E]
    return (max(good, key=lambda x: x[0])[1] if good else None), runs


def compare_orlov(df: pd.DataFrame) -> list[OrlovCompared]:
    """The slides' speed-ups (:data:`~integrator_bench.harness.matrix.source_numbers.ORLOV_SPEEDUPS`)
    at matched accuracy: the cell and RK4 both meet Orlov's E <= 0.05, RK4 at its
    largest step that does; CPU, f-evaluation and work ratios (the work: counted
    evaluations at the problem's measured unit costs,
    :mod:`~integrator_bench.harness.ranking.cost`; both codes are this project's
    Python steppers, so CPU and work differ by their overhead alone). Verdict on the CPU ratio
    (Orlov's is of simulation times): agrees within AGREE, contradicts below 1 (RK4
    faster), differs, unexplained otherwise."""
    from integrator_bench.harness.matrix import source_numbers as sn
    rk4, _ = rk4_matched(df)
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
            c.verdict = ("agrees" if abs(c.cpu / published - 1) <= sn.AGREE else
                         "contradicts" if c.cpu < 1 else "differs, unexplained")
            if c.verdict == "differs, unexplained":
                c.status = ("Orlov's 3600-state chain against cvt_chain's 298 states; no "
                            "run here changes that")
        out.append(c)
    return out


def orlov_table(compared: list[OrlovCompared], df: pd.DataFrame) -> tuple[list, list, str]:
    """Header, rows and a note (RK4's runs) of the speed-ups at matched accuracy."""
    from integrator_bench.harness.matrix import source_numbers as sn
    header = ["cell", "speed-up (slides)", "cell's E", "RK4 step here (E)",
              "ours: CPU ratio", "ours: f-evaluation ratio", "ours: work ratio", "verdict"]
    rows = [(f"P{c.k} at h = {c.h:g}", f"{c.published:g}", _g(c.cell_err),
             "–" if math.isnan(c.rk4_h) else f"{c.rk4_h:g} ({_g(c.rk4_err)})", _f(c.cpu),
             _f(c.nfev), _f(c.work), f"{c.verdict}: {c.status}" if c.status else c.verdict)
            for c in compared]
    _, runs = rk4_matched(df)
    note = "; ".join(f"h {h:g}: " + ("not in the store" if r is None else
                                      f"{r['status']}, E {_g(_err(r))}, CPU "
                                      f"{float(r['cpu_s']):.3g} s, nfev {int(r['nfev'])}")
                     for h, r in runs.items())
    return header, rows, note


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
    and ours (accurate: the run ends with E <= 0.05): agrees or contradicts seed 004."""
    from integrator_bench.harness.matrix import source_numbers as sn
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
                c.verdict = "agrees" if (c.ours == "accurate") == (c.seed004 == "accurate") \
                    else "contradicts"
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
    "the cell and RK4 both meet E <= 0.05, RK4 at its largest step here that does, as "
    "ratios of CPU and of f-evaluations (not stage counts). RK4 runs at 5e-8, 4e-8 and "
    "2.5e-8 s only: a larger step between the one that meets the criterion and the next "
    "would make RK4 cheaper, so our ratios are upper bounds. Orlov's chain has about "
    "3600 states, cvt_chain 298.")

CELLS_NOTE = (
    "Seed 004 (Section 3.6): 'schemes DUMKA3-P5 - DUMKA3-P8 give sufficiently accurate "
    "solution at step 2 10, and at step 4 10 only the scheme DUMKA3-P8 does so' (the "
    "exponents are lost in the text; the slides give 2e-6 and 4e-6 s) and 'Polynomials 4 "
    "and 9 have shown poor performance' (no step given: tested at both). The slides' grid "
    "(good, bad, failed, untested) beside it; ours: accurate when the run ends with E <= "
    "0.05.")


# --- the headline: one row per source claim -----------------------------------------

CLAIM_HEADER = ("seed", "claim", "its numbers", "ours", "verdict")


def _overall(verdicts: list[str], any_contradicts: bool = True) -> str:
    """One verdict of several: theirs when they agree; else contradicts when one does
    (``any_contradicts``), differs, unexplained otherwise."""
    if not verdicts or all(v == "cannot test" for v in verdicts):
        return "cannot test"
    tested = [v for v in verdicts if v != "cannot test"]
    if all(v == tested[0] for v in tested):
        return tested[0]
    return ("contradicts" if any_contradicts and "contradicts" in tested
            else "differs, unexplained")


def _by_row(compared, seed: str, table: str) -> dict:
    return {c.row.row: c for c in compared if c.row.seed == seed and c.row.table.startswith(table)}


def _least(rows: dict, key: str) -> tuple[str | None, str | None]:
    """The row with the least published and the least of ours of ``key``."""
    pub = [(c.row.published[key], n) for n, c in rows.items() if key in c.row.published]
    ours = [(c.ours[key], n) for n, c in rows.items() if key in c.ours]
    return (min(pub)[1] if pub else None,
            min(ours)[1] if ours and len(ours) == len(pub) else None)


def claims(df: pd.DataFrame, compared, ratios, orlov, cells) -> list[tuple]:
    """One row per source claim (:data:`CLAIM_HEADER`): the claim, its numbers, ours,
    the verdict."""
    rows = []
    # seed 000
    ours = [v for c in ratios for v in ([c.at_tol] + [x for x, _ in (c.matched or {}).values()])
            if not math.isnan(v)]
    counts = [v for c in ratios for v in (c.counts or {}).values()]
    work = [x for c in ratios for x, _ in (c.work or {}).values() if not math.isnan(x)]
    rows.append(("000", "the index-3 HHT and Newmark beat ADAMS's SI2-BDF on CPU (belt, chain, "
                        "crawler models; a claim about CPU, all codes compiled in ADAMS)",
                 "SI2-BDF / HHT or Newmark 2.31-8.95",
                 (f"IDA (ggl) / HHT or Newmark on CPU {min(ours):.2f}-{max(ours):.2f}; "
                  + (f"on work {min(work):.2f}-{max(work):.2f}; " if work else "")
                  + f"counts (nfev, njev, nlu) {min(counts):.2f}-{max(counts):.2f}")
                 if ours and counts else "–",
                 _overall([c.verdict for c in ratios], any_contradicts=False)))
    # seed 001: the course's two-mass example
    rows.append(_stiffness_claim(df))
    # seed 002
    t2 = _by_row(compared, "002", "Table 2")
    pub, our = _least(t2, "nfev")
    rows.append(("002", "Table 2: Lsodar uses the fewest f-evaluations of Dymola's four codes",
                 f"fewest: {pub}", f"fewest here: {our or '–'}",
                 "cannot test" if our is None else "agrees" if our == pub else "contradicts"))
    rows.append(_fewer_calls_claim(_by_row(compared, "002", "Table 3")))
    t5 = _by_row(compared, "002", "Table 5")
    i3, i2 = t5.get("index 3, high ATOL on v, lambda"), t5.get("index 2, algvar")
    rows.append(_index3_claim(i3, i2))
    # seed 003
    rows.append(_pa_best_claim(compared))
    rows.append(_ics_claim(compared))
    rows.append(_ecs_claim(compared))
    # seed 004
    cpu = [c.cpu for c in orlov if not math.isnan(c.cpu)]
    work = [c.work for c in orlov if not math.isnan(c.work)]
    rows.append(("004 (slides)", "DUMKA3 several times faster than RK4 at acceptable accuracy "
                                 "(a claim about simulation time, compiled code)",
                 "5.9, 4.7, 4.4 (CPU)",
                 ("CPU " + ", ".join(f"{x:.1f}" for x in cpu)
                  + ("; work " + ", ".join(f"{x:.1f}" for x in work) if work else "")
                  + " at E <= 0.05") if cpu else "–",
                 _overall([c.verdict for c in orlov])))
    agree = sum(c.verdict == "agrees" for c in cells)
    tested = sum(c.verdict != "cannot test" for c in cells)
    rows.append(("004", "P5-P8 accurate at 2e-6 s, only P8 at 4e-6 s; P4 and P9 poor",
                 "12 cells", f"{agree} of {tested} cells tested agree",
                 _overall([c.verdict for c in cells])))
    return rows


def _stiffness_claim(df) -> tuple:
    from integrator_bench.harness.measure import stiffness
    ratios = {}
    for spec in ("two_mass:c2=1000", "two_mass:c2=0.1"):
        got = stiffness.analyse(_problem(spec), stiffness.parse_times(_problem(spec), None), None)
        rs = [f["ratio"] for f in got["times"] if f["ratio"] is not None]
        ratios[spec] = max(rs) if rs else None
    classes = {s: stiffness.classify(r) for s, r in ratios.items()}
    ok = classes["two_mass:c2=1000"] == "stiff" and classes["two_mass:c2=0.1"] != "stiff"
    return ("001", "the two-mass example: c2 = 1000 numerically stiff (ratio above 200), "
                   "c2 = 0.1 physically stiff only", "stiff above 200, non-stiff below 20",
            ", ".join(f"{s}: {'–' if r is None else f'{r:.3g}'} ({classes[s]})"
                      for s, r in ratios.items()), "agrees" if ok else "contradicts")


def _fewer_calls_claim(t3: dict) -> tuple:
    """Seed 002, Table 3: the adaptive codes (CVODE, Lsodar) take considerably fewer
    f-evaluations than the constant-step BDFs."""
    claim = ("002", "Table 3: CVODE and Lsodar solve it with considerably fewer function "
                    "calls than the constant-step BDFs", "NF 1227 and 2309 against 8349-8469")
    adaptive = [t3[n].ours.get("nfev") for n in ("CVODE (Adams)", "Lsodar") if n in t3]
    fixed = [t3[n].ours.get("nfev") for n in ("BDF2", "BDF3", "BDF4") if n in t3]
    if len(adaptive) < 2 or len(fixed) < 3 or None in adaptive + fixed:
        return (*claim, "–", "cannot test")
    return (*claim, f"NF {_n(adaptive[0])} and {_n(adaptive[1])} against "
                    f"{_n(min(fixed))}-{_n(max(fixed))}",
            "agrees" if max(adaptive) < min(fixed) else "contradicts")


def _index3_claim(i3, i2) -> tuple:
    """Seed 002, Table 5: index 3 performs worst, with many more Jacobians and Newton
    convergence failures than index 2 (algvar); judged on those two counts: agrees
    when both are larger here, contradicts when neither is, differs otherwise."""
    claim = ("002", "Table 5: index 3 performs worst: many more Jacobian evaluations and "
                    "Newton convergence failures than index 2",
             "NJ 784 against 120, NCF 120 against 0")
    ours3, ours2 = (i3.ours if i3 else {}), (i2.ours if i2 else {})
    if any(k not in o for k in ("njev", "nnfail") for o in (ours3, ours2)):
        return (*claim, "–", "cannot test")
    worse = [ours3[k] > ours2[k] for k in ("njev", "nnfail")]
    return (*claim, f"NJ {_n(ours3['njev'])} against {_n(ours2['njev'])}, NCF "
                    f"{_n(ours3['nnfail'])} against {_n(ours2['nnfail'])} (index 3 NS "
                    f"{_n(ours3.get('nsteps'))}, index 2 {_n(ours2.get('nsteps'))})",
            "agrees" if all(worse) else "contradicts" if not any(worse)
            else "differs, unexplained")


def _ics_claim(compared) -> tuple:
    """Seed 003: "From the tables it appears that ICS is the most efficient approach"
    (the paper's ICS NS at or below its PA's in 8 of 9 rows), judged on steps: ICS at
    the tuned alpha (the cause's run of each ICS row) against PA (the same CVODE-Adams
    on the unprojected index-1 ODE)."""
    claim = ("003", "'From the tables it appears that ICS is the most efficient approach'",
             "ICS NS at or below PA's in 8 of 9 rows")
    pairs = []
    for c in compared:
        if c.row.seed == "003" and c.row.row.startswith("ICS"):
            pa = next((p for p in compared if p.row.table == c.row.table
                       and p.row.row == c.row.row.replace("ICS", "PA")), None)
            if pa is not None and "nsteps" in c.measured and "nsteps" in pa.ours:
                pairs.append(c.measured["nsteps"] <= pa.ours["nsteps"])
    if not pairs:
        return (*claim, "–", "cannot test")
    held = sum(pairs)
    return (*claim, f"ICS at the tuned alpha (CVODE-Adams on baumgarte) NS at or below PA's "
                    f"(CVODE-Adams on ode) in {held} of {len(pairs)} rows (agrees: in most)",
            "agrees" if 2 * held > len(pairs) else "contradicts")


def tuning_table(records) -> tuple[list, list]:
    """The alpha sweep of each ICS problem, header and rows
    (:func:`~integrator_bench.harness.matrix.source_numbers.tune_alpha`)."""
    from integrator_bench.harness.matrix import source_numbers as sn
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


def _n(x) -> str:
    return "–" if x is None else f"{int(x)}"


def _pa_best_claim(compared) -> tuple:
    """The paper's "PA is the best" (ICS excluded, as the paper excludes it) on the
    counts here: PA with its projection takes no more steps (NS) and f-evaluations (NF)
    than TP and ECS, where the paper gives them, at each problem and TOL."""
    by: dict = {}
    for c in compared:
        if c.row.seed == "003":
            approach, _, tol = c.row.row.partition(", ")
            by.setdefault((c.row.table, tol), {})[approach] = c
    def tp(d):        # the paper's TP (the TP row's cause run) where it ran
        c = d.get("TP")
        return None if c is None else c.measured if c.measured else None

    checks = [pa.ours[k] <= other[k]
              for d in by.values() for pa in [d.get("PA projected")] if pa is not None
              for other in (tp(d), d["ECS"].ours if "ECS" in d else None) if other is not None
              for k in JUDGED_HERE if k in pa.ours and k in other]
    held = sum(checks)
    verdict = ("cannot test" if not checks else "agrees" if all(checks) else "contradicts")
    return ("003", "'in terms of all the performance indicators, PA is the best' (ICS "
                   "excluded; the paper's own Table 1 gives TP fewer NS and NF)",
            "Tables 1, 2, 4", f"PA with its projection (RK23) takes no more NS and NF than "
            f"the paper's TP (tangent charts, RK23) and ECS in {held} of {len(checks)} "
            "comparisons (the counts kept here; CPU, NJ, NΦ not compared)", verdict)


#: the counts the paper's indicators are compared by here
JUDGED_HERE = ("nsteps", "nfev")


def _ecs_claim(compared) -> tuple:
    ratios = []
    for c in compared:
        if c.row.seed == "003" and c.row.row.startswith("ECS") and "nsteps" in c.ours:
            pa = next((p for p in compared if p.row.table == c.row.table
                       and p.row.row == c.row.row.replace("ECS", "PA")), None)
            if pa is not None and pa.ours.get("nsteps"):
                ratios.append(c.ours["nsteps"] / pa.ours["nsteps"])
    verdict = "cannot test" if not ratios else "agrees" if all(r > 1 for r in ratios) \
        else "contradicts"
    return ("003", "ECS takes substantially more integration steps for all the examples",
            "ECS / PA steps 2.3-5.2", "–" if not ratios else
            f"ECS / PA steps {min(ratios):.2f}-{max(ratios):.2f}", verdict)


# --- the page -------------------------------------------------------------------------

def page(records: pd.DataFrame):
    """The part "The sources, number by number" of the records (with every field: a
    report's cleaned records, :func:`~integrator_bench.harness.ranking.records.clean_records`):
    its caption and blocks (:class:`~integrator_bench.harness.report.document.Block`),
    or None when the store holds none of the seeds' runs."""
    from integrator_bench.harness.matrix import source_numbers as sn
    from integrator_bench.harness.report.document import Block, Table

    compared = sn.compare(records)
    if all(c.status == "not in the store" for c in compared):
        return None
    ratios, orlov, cells = compare_ratios(records), compare_orlov(records), \
        compare_cells(records)
    claim_rows = claims(records, compared, ratios, orlov, cells)
    every = ([c.verdict for c in compared] + [c.verdict for c in ratios]
             + [c.verdict for c in orlov] + [c.verdict for c in cells]
             + ["cannot test"] * len(sn.UNTESTED))
    counts = dict.fromkeys(sn.VERDICTS, 0)
    for v in every:
        counts[v] += 1
    claim_counts = dict.fromkeys(sn.VERDICTS, 0)
    for r in claim_rows:
        claim_counts[r[-1]] += 1
    blocks = [Block(title="The sources' claims, side by side",
                    text=[sn.summary_line(claim_counts, "claims")],
                    tables=[Table(list(CLAIM_HEADER), claim_rows)])]
    blocks += [Block(title=title, tables=[Table(list(sn.TABLE_HEADER), rows,
                                                ("ours / published",))])
               for title, rows in sn.tables(compared)]
    header, rows = tuning_table(records)
    blocks.append(Block(title="seed 003: Baumgarte's alpha for ICS, tuned as the paper tunes it",
                        text=[TUNING_NOTE], tables=[Table(header, rows)]))
    ratio_rows = sn.within_table_ratios(compared)
    if ratio_rows:
        blocks.append(Block(title="Ratios between the methods of one table (seed 003: each "
                                  "approach over PA)",
                            tables=[Table(["table", "row", "ratio", "source", "ours"],
                                          ratio_rows, ("source", "ours"))]))
    header, rows, note = orlov_table(orlov, records)
    blocks.append(Block(title="seed 004 and the 2017 slides: DUMKA3 over RK4 at Orlov's "
                              "error criterion", text=[ORLOV_NOTE, "RK4 here: " + note],
                        tables=[Table(header, rows, tuple(header[1:6]))]))
    header, rows = cells_table(cells)
    blocks.append(Block(title="seed 004's own verdicts on P4-P9 beside the slides' grid and "
                              "ours", text=[CELLS_NOTE], tables=[Table(header, rows)]))
    header, rows = ratio_table(ratios)
    from integrator_bench.harness.matrix import source_runs
    blocks.append(Block(title="seed 000, the ADAMS seminar's CPU ratios beside ours",
                        text=[source_runs.RATIO_NOTE],
                        tables=[Table(header, rows, tuple(header[1:5]))]))
    header, rows = stiffness_rows(records)
    blocks.append(Block(title="seed 001, the ADAMS course's stiffness criterion on the "
                              "seeds' problems", text=[source_runs.STIFFNESS_NOTE],
                        tables=[Table(header, rows, tuple(header[1:9]))]))
    blocks.append(Block(title="Figures of the sources with no counterpart here (cannot test)",
                        tables=[Table(["seed", "where", "figures", "why"],
                                      [tuple(u) for u in sn.UNTESTED])]))
    caption = (sn.summary_line(counts) + " Every row of the tables below, each of seed "
               "000's ratios, Orlov's speed-ups and cells, and each figure with no "
               "counterpart counts once. Rows compare counts (NS, NF, NJ, NCF, NP); a row's "
               f"verdict judges NS and NF within {sn.AGREE:.0%}; 'differs, cause measured' "
               "only with the cause's run shown beside it.")
    return caption, blocks


# --- docs/seed-numbers.md: the page as a document, with the records it was made from ------

#: the records' fields the page reads (:func:`page`), embedded in the document
DOC_FIELDS = ("problem", "params", "formulation", "integrator", "settings", "rtol", "h",
              "status", "reason", "mescd", "err_max", "err_rms", "scd", "final_degenerate",
              "monitor_err", "cpu_s", "cpu_s_iqr", "nfev", "njev", "nlu", "nsteps",
              "nnfail", "nreject", "nevents", "drift_pos", "solver_counts", "code_version", "mode",
              "work")
DOC_RECORDS = "<!-- the records this document was generated from (sources.document) -->"

DOC_INTRO = """# The sources, number by number

Generated by `ibench report` (its `sources.md`, copied here) from the records of the
`seeds` preset; the same part is in the report's `index.md` and `index.html`. Do not edit
by hand: `tests/test_seed_doc.py` regenerates this file from the records embedded at its
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
`harness/matrix/source_numbers.py` and `harness/matrix/source_runs.py`. Each row has one of five
verdicts, from the records alone: **agrees** (within the stated tolerance); **differs,
cause measured** (a run that changes the named configuration difference moves the number
toward the source's; both runs shown); **differs, unexplained**; **contradicts** (the
source's claim reversed here); **cannot test** (what is missing is said). Where a source
contradicts itself, the row says so. Earlier studies of these sources (the quick-return
at TOL 1e-2, SERK2, Orlov's full grid) are in [seed-studies.md](seed-studies.md).
"""


def _doc_records(records: pd.DataFrame) -> pd.DataFrame:
    """The records the page can match: those of the problems, formulations and
    integrators of the preset's cases, with :data:`DOC_FIELDS`."""
    from integrator_bench.harness.matrix import source_numbers as sn
    from integrator_bench.harness.matrix.line import spec_name
    wanted = {(spec_name(p), f, spec_name(i)) for p, f, i, _, _ in sn.preset_cases()}
    keep = [(p, f, i) in wanted for p, f, i in
            zip(records["problem"], records["formulation"], records["integrator"])]
    sub = records[keep]
    return sub[[c for c in DOC_FIELDS if c in sub.columns]].reset_index(drop=True)


def document(records: pd.DataFrame) -> str:
    """``docs/seed-numbers.md``: :data:`DOC_INTRO`, the commits the records were run
    by, the part :func:`page` gives for the records, and the records themselves (as
    JSON, so that :func:`document` of them gives the same text)."""
    from integrator_bench.harness.ranking.records import clean_records
    from integrator_bench.harness.report import markdown
    from integrator_bench.harness.report.document import Part

    sub = _doc_records(records)
    got = page(clean_records(sub))
    if got is None:
        return ""
    caption, blocks = got
    commits = sorted({str(v) for v in sub.get("code_version", pd.Series(dtype=str)).dropna()})
    lines = [DOC_INTRO, f"Run by code {', '.join(commits) or 'unknown'}, {len(sub)} records.",
             ""]
    # as the report's index.md writes the part (escaped), so that the two read the same
    lines += [markdown.escaped("\n".join(markdown.part(Part(
        "sources", "The sources, number by number", caption=caption, blocks=blocks))))]
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


def records_of(text: str) -> pd.DataFrame:
    """The records embedded in a :func:`document`."""
    _, _, rest = text.partition(DOC_RECORDS)
    body = rest.split("```json", 1)[1].split("```", 1)[0]
    return pd.DataFrame(json.loads(body))
