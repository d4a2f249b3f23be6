"""The seed's headline on the roller chain: index-3 HHT and Newmark against IDA.

The ADAMS/Solver seminar (seed ``000_504002bd78ba5f4b``, "CPU Comparison (C++
vs. C++)") reports, on a generic chain of 3759 equations (40 ms) and a generic
belt of 7242 equations (40 ms), CPU seconds SI2-BDF / HHT / Newmark of
1030.6 / 438.6 / 445.7 and 4624.1 / 1127.0 / 1237.6: the index-3 methods 2.3 to
4.1 times faster than the stabilized index-2 BDF (:data:`SEED`).

This script runs, side by side in one run and one store, ``chain_drive`` at
``--n-links`` links with HHT (``hht``, adaptive, over ``--rtol``) and Newmark
(``newmark``, fixed step, over ``--h``) on ``i3``, and IDA on ``ggl`` (ADAMS's
SI2) and on ``i2`` (over ``--rtol``), each case through the harness
(:class:`integrator_bench.harness.run.runner.Session`: a forked worker per case,
CPU of the solve alone, counters, errors against the committed reference). Then
:func:`integrator_bench.harness.ranking.reach.target_table` gives the CPU each line
needs to reach a relative position error, with the problem's position scale as
floor, of 1e-3 and 1e-5 (``10**-mescd`` at the final time: the largest
``|e| / (position_scale + |ref|)`` over the positions, IVP Test Set sect. II;
interpolated along its work-precision line, never extrapolated), with nsteps,
nfev, njev and nlu, and the ratios IDA/HHT and IDA/Newmark beside the seed's.
The pure relative error ``10**-scd`` is not used: on ``chain_drive`` it is
dominated by components whose reference is near zero (a link angle of about
-0.005 rad; link coordinates pass through zero), and such a component's error
weighs (0.1 + 0.005) / 0.005, about 20, times more in it than in ``mescd``
(position scale 0.1).

Usage::

    .venv/bin/python studies/chain_headline.py --n-links 30          # Markdown
    .venv/bin/python studies/chain_headline.py --n-links 150 --json  # JSON

The reference of ``chain_drive`` at that size must exist (results/reference,
or ``IBENCH_REFERENCE_DIR``); ``--compute-reference`` lets the harness compute
a missing one first. Bad input: one line on standard error, exit 2.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd

from integrator_bench.harness.measure import references

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.cases import expand
from integrator_bench.harness.ranking import reach
from integrator_bench.harness.report import ranking_text
from integrator_bench.harness.run.context import RunContext
from integrator_bench.harness.run.limits import Limits
from integrator_bench.harness.run.runner import Session
from integrator_bench.harness.matrix.store import Store
from integrator_bench.harness.matrix.record import CaseStatus

#: the compared lines: (integrator, formulation)
HHT, NEWMARK = ("hht", "i3"), ("newmark", "i3")
IDA_LINES = (("ida", "ggl"), ("ida", "i2"))
LINES = (HHT, NEWMARK) + IDA_LINES
#: the seed's CPU seconds (SI2-BDF, HHT, Newmark), seed 000 "CPU Comparison (C++ vs. C++)"
SEED = {"generic chain, 3759 equations, 40 ms": (1030.6, 438.6, 445.7),
        "generic belt, 7242 equations, 40 ms": (4624.1, 1127.0, 1237.6)}
RTOLS = (1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11)
HS = (1e-4, 3e-5, 1e-5, 3e-6, 1e-6)


def seed_ratios() -> dict[str, tuple[float, float]]:
    """Per seed model, (SI2-BDF / HHT, SI2-BDF / Newmark) CPU ratios."""
    return {name: (bdf / hht, bdf / nm) for name, (bdf, hht, nm) in SEED.items()}


#: ``num / den`` of two CPUs to reach a target, with how sure it is (the other
#: studies import it from here)
ratio = reach.cpu_ratio


def make_cases(n_links: int, rtols, hs) -> list:
    """The cases of the four lines (nothing unsupported)."""
    spec = [f"chain_drive:n_links={n_links}"]
    cases = (expand(problems=spec, formulations=["i3", "ggl", "i2"], integrators=["hht", "ida"],
                    rtols=list(rtols))
             + expand(problems=spec, formulations=["i3"], integrators=["newmark"], hs=list(hs)))
    return [c for c in cases if (c.integrator, c.formulation) in LINES and not c.unsupported]


def headline(df: pd.DataFrame) -> dict:
    """The target table of the four lines and the IDA/HHT, IDA/Newmark ratios."""
    table = reach.target_table(df, measure="final")
    by = {(r["label"], r["formulation"]): r for r in table.to_dict("records")}
    ratios = []
    for ida in IDA_LINES:
        for other in (HHT, NEWMARK):
            if ida not in by or other not in by:
                continue
            for t in reach.TARGETS:
                tag = f"{t:.0e}"
                a, b = by[ida], by[other]
                value, sure = ratio(a[f"cpu_{tag}"], a[f"how_{tag}"],
                                    b[f"cpu_{tag}"], b[f"how_{tag}"])
                ratios.append({"target": t, "numerator": f"{ida[0]} ({ida[1]})",
                               "denominator": f"{other[0]} ({other[1]})",
                               "ratio": value, "bound": sure})
    return {"table": table, "ratios": ratios}


def _num(value):
    if value is None or (isinstance(value, float) and math.isnan(value)) or value is pd.NA:
        return None
    return value.item() if hasattr(value, "item") else value


def markdown(result: dict, meta: dict) -> str:
    """The README's Markdown: the target table, the ratios and the seed's."""
    from integrator_bench.harness.tables import markdown_lines

    header, body = ranking_text.markdown_rows(result["table"])
    lines = [f"### chain_drive, {meta['n_links']} links: CPU to reach a relative position "
             "error (position scale as floor, 10^-mescd)", "", ranking_text.CAPTION, ""]
    lines += markdown_lines(header, body, header[2:])
    seed = seed_ratios()
    seed_text = {("hht", True): " / ".join(f"{r[0]:.2f}" for r in seed.values()),
                 ("newmark", True): " / ".join(f"{r[1]:.2f}" for r in seed.values())}
    rows = []
    for r in result["ratios"]:
        cell = "–" if math.isnan(r["ratio"]) else \
            f"{'' if r['bound'] == '=' else r['bound'] + ' '}{r['ratio']:.2f}"
        rows.append((f"{r['target']:.0e}", f"{r['numerator']} / {r['denominator']}", cell,
                     seed_text[(r["denominator"].split()[0], True)]))
    lines += ["", "CPU ratios (> 1: the index-3 method is faster); the seed's SI2-BDF / "
              "HHT and SI2-BDF / Newmark on its generic chain / generic belt:", ""]
    lines += markdown_lines(("target", "ratio", "here", "seed (chain / belt)"), rows,
                            ["here"])
    lines += ["", f"{meta['cases']} cases, {meta['failed']} not ok; CPU of all solves "
              f"{meta['cpu_total_s']:.1f} s, wall time of the script {meta['wall_s']:.0f} s "
              f"({meta['jobs']} worker{'s' if meta['jobs'] > 1 else ''}); code "
              f"{meta['code_version']}."]
    return "\n".join(lines) + "\n"


def to_json(result: dict, meta: dict) -> str:
    """The same as JSON: ``meta``, ``rows`` (the target table), ``ratios``, ``seed``."""
    rows = [{k: _num(v) for k, v in r.items()}      # a line's label, headed "integrator"
            for r in result["table"].rename(columns={"label": "integrator"}).to_dict("records")]
    ratios = [{k: _num(v) for k, v in r.items()} for r in result["ratios"]]
    seed = {name: {"si2_bdf_over_hht": a, "si2_bdf_over_newmark": b}
            for name, (a, b) in seed_ratios().items()}
    return json.dumps({**meta, "targets": list(reach.TARGETS), "rows": rows,
                       "ratios": ratios, "seed": seed}, indent=1)


def _fail(message: str) -> int:
    print(f"chain_headline: error: {message}", file=sys.stderr)
    return 2


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n-links", type=int, default=150)
    ap.add_argument("--rtol", type=float, nargs="+", default=list(RTOLS),
                    help="tolerance ladder of HHT and IDA")
    ap.add_argument("--h", type=float, nargs="+", default=list(HS),
                    help="step ladder of Newmark (fixed step)")
    ap.add_argument("--jobs", type=int, default=1,
                    help="cases at once (default 1: no two solves share a core)")
    ap.add_argument("--timeout", type=float, default=900.0, help="seconds a case may take")
    ap.add_argument("--store", type=Path, help="store to keep the records (default: temporary)")
    ap.add_argument("--compute-reference", action="store_true",
                    help="compute a missing reference first (may take long)")
    ap.add_argument("--json", action="store_true", help="print JSON instead of Markdown")
    args = ap.parse_args(argv)
    if any(not (v > 0) for v in args.rtol + args.h):
        return _fail(f"--rtol and --h take positive numbers, got {args.rtol + args.h}")
    if args.jobs < 1 or not args.timeout > 0:
        return _fail(f"--jobs must be >= 1 and --timeout > 0, got {args.jobs}, {args.timeout}")
    try:
        problem = registry.get_problem_class("chain_drive")(n_links=args.n_links)
    except Exception as exc:  # the problem names the bad value and the valid range
        return _fail(f"--n-links {args.n_links}: {exc}")
    ref, why = references.read(problem)
    if ref is None and not args.compute_reference:
        return _fail(f"no usable reference for {problem.label()} ({why}); "
                     "give --compute-reference or another --n-links")
    cases = make_cases(args.n_links, args.rtol, args.h)
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        with Store(args.store or Path(tmp) / "headline.sqlite") as store, \
                Session(RunContext(store=store, jobs=args.jobs, progress=False,
                                   command=" ".join(sys.argv),
                                   limits=Limits(budget_s=args.timeout))) as session:
            df = session.run(cases)
    wall = time.perf_counter() - start
    meta = {"problem": "chain_drive", "n_links": args.n_links, "rtols": args.rtol,
            "hs": args.h, "cases": len(df), "failed": int((df["status"] != CaseStatus.OK).sum()),
            "cpu_total_s": float(pd.to_numeric(df["cpu_s"], errors="coerce").sum()),
            "wall_s": wall, "jobs": args.jobs,
            "code_version": str(df["code_version"].iloc[0]) if len(df) else None}
    result = headline(df)
    print(to_json(result, meta) if args.json else markdown(result, meta), end="")
    return 0


if __name__ == "__main__":
    sys.exit(main())
