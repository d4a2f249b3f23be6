"""The seed's CVT headline: where a stabilized explicit method wins (Orlov, seed 004).

Orlov (seed 004, section 3) integrates a CVT rocker-pin chain whose regularized
pin-half friction puts eigenvalues down to about -1e8 1/s: RK4's steps are limited
by its stability, the W-methods failed, the trapezoidal rule was accurate at 2e-6 s,
and DUMKA3 with a fixed polynomial was accurate at 2e-6 s with P5-P8 and at 4e-6 s
with P8 alone, "several times faster than RK4" (its Table 1 survives as headings
only). The figures 4.4 to 5.9 and RK4 at 5e-8 s are the 2017 slides' (Orlov, Kuzin
and Shabrov, :data:`ORLOV_SPEEDUP`). His accuracy measure is the
pin-force error ``E = max_[t*, t_end] |P - P_ref| / max |P_ref|``, unacceptable
above 0.05.

This script runs ``cvt_chain`` (both friction laws, ``--friction``) side by side
in one run and one store, each case through the harness
(:class:`integrator_bench.harness.run.runner.Session`: a forked worker per case,
CPU of the solve alone, counters, errors against the committed reference):

* RK4 at fractions of its largest stable step ``beta / rho`` (``rho`` the
  spectral radius of the ``ode`` Jacobian along the reference, by
  :mod:`integrator_bench.harness.measure.stiffness`), and GBS at RK4's largest;
* DUMKA3 with each fixed polynomial P4 ... P9 (Orlov's labels, P0 = degree 3:
  degrees 21 to 81; :func:`~integrator_bench.integrators.dumka.with_polynomial`,
  registered for this run as ``dumka3-P4`` ...) at fractions of its ``beta_k /
  rho``, and DUMKA3 adaptive (step and polynomial) over ``--rtol``
  (``studies/orlov_grid.py`` runs them at Orlov's own steps);
* the trapezoidal rule (analytic sparse Jacobian), W1 and SW2 over ``--h``;
* Radau, CVODE-BDF, RKC, ROCK2, SERK2v2, DOPRI5 (scipy-RK45) and DOP853 over ``--rtol``
  (the two explicit Runge-Kutta codes over ``--explicit-rtol`` only: they step
  at their stability limit whatever the tolerance).

Then :func:`integrator_bench.harness.ranking.reach.target_table` with the measure
``-log10 E`` (the record's ``monitor_err``) gives the CPU each line needs to
reach E <= 0.05 and E <= 1e-3 (interpolated log-log along the line, never
extrapolated), with nsteps, nfev, njev and nlu; every fixed-step explicit line
at its largest stable step, as Orlov ran them, with RK4's CPU over its own
beside Orlov's speed-up; and RK4's CPU over adaptive DUMKA3's at each target.

Usage::

    .venv/bin/python studies/cvt_headline.py                 # Markdown, both laws
    .venv/bin/python studies/cvt_headline.py --friction 1 --json

The references of ``cvt_chain`` must exist (they are committed for the
benchmark sets). Bad input: one line on standard error, exit 2.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from integrator_bench.harness.measure import references, stiffness

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.cases import expand
from integrator_bench.harness.sources.numbers import ORLOV_SPEEDUPS
from integrator_bench.harness.ranking import reach
from integrator_bench.harness.report import ranking_text
from integrator_bench.harness.run.context import RunContext
from integrator_bench.harness.run.limits import Limits
from integrator_bench.harness.run.runner import Session
from integrator_bench.harness.matrix.store import Store
from integrator_bench.harness.matrix.record import CaseStatus
from integrator_bench.integrators.dumka import PUBLISHED_BETA, with_polynomial

sys.path.insert(0, str(Path(__file__).resolve().parent))
from chain_headline import _num, ratio  # noqa: E402

#: Orlov's DUMKA3 speed-up over RK4 at acceptable accuracy, least and most (the 2017
#: slides, transcribed in the harness:
#: :data:`~integrator_bench.harness.sources.numbers.ORLOV_SPEEDUPS`)
ORLOV_SPEEDUP = (min(s for *_, s in ORLOV_SPEEDUPS), max(s for *_, s in ORLOV_SPEEDUPS))
#: Orlov's acceptable and a tight pin-force error
TARGETS = (0.05, 1e-3)
MEASURE = "e_digits"            # -log10(monitor_err), added to the records here
POLYNOMIALS = (4, 5, 6, 7, 8, 9)
FRACTIONS = (0.95, 0.7, 0.5)    # of a method's largest stable step beta / rho
RTOLS = (1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7)
EXPLICIT_RTOLS = (1e-3, 1e-6)
HS = (8e-6, 4e-6, 2e-6, 1e-6, 5e-7)
ADAPTIVE = ("dumka3", "rkc", "rock2", "serk2v2", "scipy-Radau", "cvode-bdf")
EXPLICIT = ("scipy-RK45", "scipy-DOP853")
IMPLICIT_FIXED = ("trapezoidal", "w1", "sw2")


def spectral_radius(problem) -> float:
    """The largest spectral radius of the ``ode`` Jacobian at the start, middle
    and end of the reference."""
    t0, t1 = problem.t_span
    return stiffness.analyse(problem, [t0, 0.5 * (t0 + t1), t1], store=None)["rho"]


def all_lines() -> tuple[str, ...]:
    """Every line's integrator name, in the table's order of families."""
    return (("rk4", "gbs") + tuple(f"dumka3-P{k}" for k in POLYNOMIALS) + ADAPTIVE
            + EXPLICIT + IMPLICIT_FIXED)


def make_cases(spec: str, rho: float, rtols, explicit_rtols, hs, lines=None) -> list:
    """The cases of the ``lines`` (default all) for one parameter set ``spec``."""
    lines = set(all_lines() if lines is None else lines)
    rk4_h = [f * registry.get_integrator("rk4").stability_intervals[""] / rho
             for f in FRACTIONS]
    # GBS (12 evaluations a step) only at RK4's largest step: 5 min a run at 5 ms
    ladders = {"rk4": ("h", rk4_h), "gbs": ("h", rk4_h[:1])}
    for k in POLYNOMIALS:
        ladders[f"dumka3-P{k}"] = ("h", [f * PUBLISHED_BETA[k] / rho for f in FRACTIONS])
    ladders.update({name: ("rtol", list(rtols)) for name in ADAPTIVE})
    ladders.update({name: ("rtol", list(explicit_rtols)) for name in EXPLICIT})
    ladders.update({name: ("h", list(hs)) for name in IMPLICIT_FIXED})
    cases = []
    for name in all_lines():
        if name in lines:
            kind, values = ladders[name]
            cases += expand(problems=[spec], integrators=[name], **{kind + "s": values})
    return [c for c in cases if not c.unsupported]


def with_e_digits(df: pd.DataFrame) -> pd.DataFrame:
    """The records with ``e_digits = -log10(monitor_err)`` (NaN where none)."""
    e = pd.to_numeric(df["monitor_err"], errors="coerce").astype(float)
    return df.assign(e_digits=-np.log10(e.where(e > 0)))


def largest_steps(rows: pd.DataFrame) -> list[dict]:
    """Each fixed-step explicit line (RK4, GBS, DUMKA3 P4-P9) at its largest step,
    ``FRACTIONS[0]`` of its ``beta / rho``, as Orlov ran them: status, h, E, CPU,
    nfev, and RK4's CPU over the line's when both ran and E <= 0.05 for both."""
    names = ["rk4", "gbs"] + [f"dumka3-P{k}" for k in POLYNOMIALS]
    out = []
    for name in names:
        g = rows[(rows["integrator"] == name) & rows["h"].notna()]
        if len(g):
            r = g.loc[pd.to_numeric(g["h"]).idxmax()]
            out.append({"integrator": name, "h": float(r["h"]), "status": str(r["status"]),
                        "E": _num(r["monitor_err"]), "cpu_s": _num(r["cpu_s"]),
                        "nfev": _num(r["nfev"])})
    ok = {o["integrator"]: o for o in out
          if o["status"] == CaseStatus.OK and o["E"] is not None and o["E"] <= TARGETS[0]}
    for o in out:
        both = "rk4" in ok and o["integrator"] in ok
        o["rk4_over"] = ok["rk4"]["cpu_s"] / o["cpu_s"] if both else math.nan
    return out


def speedups(table: pd.DataFrame) -> list[dict]:
    """CPU of RK4 over adaptive DUMKA3's at each target (> 1: DUMKA3 faster), from
    the target table (bounded when a line is already below a target)."""
    by = {r["label"]: r for r in table.to_dict("records")}
    out = []
    if "rk4" not in by:
        return out
    for name in sorted(n for n in by if n == "dumka3"):
        for t in TARGETS:
            tag = f"{t:.0e}"
            a, b = by["rk4"], by[name]
            value, sure = ratio(a[f"cpu_{tag}"], a[f"how_{tag}"], b[f"cpu_{tag}"],
                                b[f"how_{tag}"])
            out.append({"target": t, "integrator": name, "rk4_over": value, "bound": sure})
    return out


def failures(df: pd.DataFrame) -> list[dict]:
    """Per line, how many cases were not ok and why (the reasons)."""
    bad = df[df["status"] != CaseStatus.OK]
    return [{"integrator": name, "not_ok": len(g),
             "reasons": sorted(set(map(str, g["reason"].fillna(g["status"]))))}
            for name, g in bad.groupby("integrator")]


def markdown(results: list[dict], meta: dict) -> str:
    """The README's Markdown: per friction law the target table on E, the
    speed-ups over RK4 beside Orlov's and the failures."""
    from integrator_bench.harness.tables import markdown_lines

    lines = []
    for res in results:
        header, body = ranking_text.markdown_rows(res["table"], TARGETS)
        header = [h.replace("CPU [s] to", "CPU [s] to E ≤") for h in header]
        header[-1] = "least E"
        lines += [f"### cvt_chain, friction {res['friction']} ({res['law']}), rho = "
                  f"{res['rho']:.3g} 1/s: CPU to reach a pin-force error E", ""]
        lines += markdown_lines(header, body, header[2:])
        big = [(o["integrator"], f"{o['h']:.3g}", o["status"],
                "–" if o["E"] is None else f"{o['E']:.1e}",
                "–" if o["cpu_s"] is None else f"{o['cpu_s']:.3g}",
                "–" if o["nfev"] is None else str(int(o["nfev"])),
                "–" if math.isnan(o["rk4_over"]) else f"{o['rk4_over']:.1f}")
               for o in res["largest"]]
        if big:
            lines += ["", f"Fixed-step explicit lines at their largest stable step "
                      f"({FRACTIONS[0]} beta / rho), as Orlov ran them; RK4 / line is RK4's "
                      f"CPU over the line's where both reach E <= {TARGETS[0]} (Orlov's DUMKA3 "
                      f"over RK4: {ORLOV_SPEEDUP[0]}-{ORLOV_SPEEDUP[1]}):", ""]
            lines += markdown_lines(("line", "h [s]", "status", "E", "CPU [s]", "nfev",
                                     "RK4 / line"), big, [1, 3, 4, 5, 6])
        rows = [(f"{s['target']:g}", s["integrator"],
                 "–" if math.isnan(s["rk4_over"]) else
                 f"{'' if s['bound'] == '=' else s['bound'] + ' '}{s['rk4_over']:.2f}")
                for s in res["speedups"]]
        if rows:
            lines += ["", "RK4 CPU over adaptive DUMKA3's to reach each E (≤: RK4's CPU is "
                      "an upper bound, its largest stable step being already that accurate):",
                      ""]
            lines += markdown_lines(("E target", "line", "RK4 / line"), rows, [2])
        if res["failures"]:
            lines += ["", "Not ok: " + "; ".join(
                f"{f['integrator']} {f['not_ok']} ({', '.join(f['reasons'])})"
                for f in res["failures"]) + "."]
        lines.append("")
    lines.append(f"{meta['cases']} cases, {meta['failed']} not ok; CPU of all solves "
                 f"{meta['cpu_total_s']:.0f} s, wall time {meta['wall_s']:.0f} s "
                 f"({meta['jobs']} worker{'s' if meta['jobs'] > 1 else ''}); code "
                 f"{meta['code_version']}.")
    return "\n".join(lines) + "\n"


def to_json(results: list[dict], meta: dict) -> str:
    out = []
    for res in results:
        rows = [{k: _num(v) for k, v in r.items()}  # a line's label, headed "integrator"
                for r in res["table"].rename(columns={"label": "integrator"}).to_dict("records")]
        out.append({**{k: v for k, v in res.items() if k != "table"}, "rows": rows,
                    "speedups": [{k: _num(v) for k, v in s.items()} for s in res["speedups"]],
                    "largest": [{k: _num(v) for k, v in o.items()} for o in res["largest"]]})
    return json.dumps({**meta, "targets": list(TARGETS), "orlov_speedup": ORLOV_SPEEDUP,
                       "results": out}, indent=1)


def run_options_error(args) -> str | None:
    """The one-line error of bad ``--jobs``, ``--timeout`` or ``--friction``, or None."""
    if args.jobs < 1 or not args.timeout > 0:
        return f"--jobs must be >= 1 and --timeout > 0, got {args.jobs}, {args.timeout}"
    bad = [f for f in args.friction if f not in (0, 1)]
    if bad:
        return f"--friction {bad[0]}: valid are 1 (smooth) and 0 (linear)"
    return None


def cvt_problems(frictions, t_end, compute_reference) -> list:
    """The ``cvt_chain`` problems of ``frictions`` (and ``t_end`` when given) with
    their references, computed when missing if ``compute_reference``; ValueError
    with one line naming the bad input otherwise."""
    cls = registry.get_problem_class("cvt_chain")
    extra = {} if t_end is None else {"t_end": t_end}
    try:
        problems = [cls(friction=f, **extra) for f in frictions]
    except Exception as exc:  # the problem names the bad value and its range
        raise ValueError(f"--t-end {t_end}: {exc}") from None
    for problem in problems:
        ref, why = references.read(problem)
        if ref is None and not compute_reference:
            raise ValueError(f"no usable reference for {problem.label()} ({why}); run "
                             "`ibench reference -p cvt_chain` or give --compute-reference")
        if ref is None:
            references.load(problem)
    return problems


def prepare(args, polynomials, origin: str) -> list:
    """What a CVT study does before its cases: check ``--jobs``, ``--timeout`` and
    ``--friction`` (:func:`run_options_error`), build the problems with their
    references (:func:`cvt_problems`) and register DUMKA3 at each of
    ``polynomials`` (``dumka3-P{k}``, by ``origin``). ValueError with one line
    naming the bad input."""
    wrong = run_options_error(args)
    if wrong:
        raise ValueError(wrong)
    problems = cvt_problems(args.friction, args.t_end, args.compute_reference)
    for k in polynomials:
        registry.register(with_polynomial(k), origin=origin)
    return problems


def cvt_spec(problem, t_end) -> str:
    """The problem spec of one of :func:`cvt_problems`."""
    extra = {} if t_end is None else {"t_end": t_end}
    return "cvt_chain:" + ",".join(f"{k}={v:g}" for k, v in
                                   {"friction": problem.params["friction"], **extra}.items())


def _fail(message: str) -> int:
    print(f"cvt_headline: error: {message}", file=sys.stderr)
    return 2


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--friction", type=int, nargs="+", default=[1, 0],
                    help="friction laws: 1 smooth, 0 linear (default both)")
    ap.add_argument("--rtol", type=float, nargs="+", default=list(RTOLS))
    ap.add_argument("--explicit-rtol", type=float, nargs="+", default=list(EXPLICIT_RTOLS))
    ap.add_argument("--h", type=float, nargs="+", default=list(HS),
                    help="step ladder of the trapezoidal rule, W1 and SW2")
    ap.add_argument("--lines", nargs="+", metavar="INTEGRATOR",
                    help="only these lines (default: all; see all_lines())")
    ap.add_argument("--t-end", type=float, help="a shorter span than the benchmark's 5 ms")
    ap.add_argument("--compute-reference", action="store_true",
                    help="compute a missing reference first (for --t-end)")
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--timeout", type=float, default=900.0, help="seconds a case may take")
    ap.add_argument("--store", type=Path, help="store to keep the records (default: temporary)")
    ap.add_argument("--json", action="store_true", help="print JSON instead of Markdown")
    args = ap.parse_args(argv)
    values = args.rtol + args.explicit_rtol + args.h
    if any(not (v > 0) for v in values):
        return _fail(f"--rtol, --explicit-rtol and --h take positive numbers, got {values}")
    unknown = sorted(set(args.lines or ()) - set(all_lines()))
    if unknown:
        return _fail(f"--lines {unknown[0]}: valid are {', '.join(all_lines())}")
    try:
        problems = prepare(args, POLYNOMIALS, "studies/cvt_headline.py")
    except ValueError as exc:
        return _fail(str(exc))
    start = time.perf_counter()
    plan = []
    for problem in problems:
        rho = spectral_radius(problem)
        spec = cvt_spec(problem, args.t_end)
        plan.append((problem, rho, make_cases(spec, rho, args.rtol, args.explicit_rtol,
                                              args.h, args.lines)))
    cases = [c for _, _, cs in plan for c in cs]
    with tempfile.TemporaryDirectory() as tmp:
        with Store(args.store or Path(tmp) / "cvt_headline.sqlite") as store, \
                Session(RunContext(store=store, jobs=args.jobs, progress=False,
                                   command=" ".join(sys.argv),
                                   limits=Limits(budget_s=args.timeout))) as session:
            df = session.run(cases)
    wall = time.perf_counter() - start
    df = with_e_digits(df)
    results = []
    for problem, rho, _ in plan:
        rows = df[np.array([json.loads(p) == problem.params for p in df["params"]], bool)]
        friction = int(problem.params["friction"])
        table = reach.target_table(rows, TARGETS, measure=MEASURE)
        results.append({"friction": friction, "law": "smooth" if friction else "linear",
                        "rho": rho, "table": table, "speedups": speedups(table),
                        "largest": largest_steps(rows), "failures": failures(rows)})
    meta = {"problem": "cvt_chain", "cases": len(df),
            "failed": int((df["status"] != CaseStatus.OK).sum()),
            "cpu_total_s": float(pd.to_numeric(df["cpu_s"], errors="coerce").sum()),
            "wall_s": wall, "jobs": args.jobs,
            "code_version": str(df["code_version"].iloc[0]) if len(df) else None}
    print(to_json(results, meta) if args.json else markdown(results, meta), end="")
    return 0


if __name__ == "__main__":
    sys.exit(main())
