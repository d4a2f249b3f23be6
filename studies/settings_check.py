"""What the seeds' integrator settings buy, at matched accuracy.

The ADAMS/Solver seminar (seed ``000``, integrator controls) advises: "KMAX ...
Useful for models with contact and/or very stiff elements. Recommended then to
reduce to 2". This script measures that advice, and HHT's damping, through the
harness (:class:`integrator_bench.harness.run.runner.Session`: a worker per case,
CPU of the solve alone, errors against the committed references):

* ``chain_bushing`` (30 and 150 links) and ``cvt_chain`` (smooth and switching
  friction law), underlying ODE: CVODE BDF and IDA at maximum order 2 and 5
  (5 is the default);
* ``chain_drive`` (30 links): CVODE on ``ode`` and IDA on ``ggl`` at maximum
  order 2 and 5, HHT on ``i3`` at alpha 0, -0.3 (the default) and -1/3.

Per line, the CPU to reach a relative position error (position scale as floor,
``10**-mescd``) of 1e-3 and 1e-5 comes from the report's own code
(:func:`integrator_bench.harness.ranking.reach.target_table`), so the
accuracy is matched: each CPU is interpolated along the line's own
work-precision curve to the same error. Beside each variant, its CPU over the
default's; "lines cross" when the variant is cheaper at one target and dearer at
the other.

Usage::

    .venv/bin/python studies/settings_check.py            # the README's table (~25 min, --jobs 1)
    .venv/bin/python studies/settings_check.py --quick    # seconds: two_mass

``--store PATH`` keeps the records (and ``--resume`` reuses them); ``--json``
prints the table as JSON. Bad input: one line on standard error, exit 2.
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

from integrator_bench.harness.matrix.cases import expand
from integrator_bench.harness.ranking import reach
from integrator_bench.harness.ranking.records import clean_records
from integrator_bench.harness.report import ranking_text
from integrator_bench.harness.run.context import RunContext
from integrator_bench.harness.run.limits import Limits
from integrator_bench.harness.run.runner import Session
from integrator_bench.harness.matrix.store import Store

ORDERS = "max_order=2|5"
ALPHAS = f"alpha=0|-0.3|{-1 / 3!r}"
#: (problem spec, formulation, integrator specs, rtols): the full measurement. The
#: tolerances reach 1e-5 for every line where the budget allows (order 2 needs
#: tighter rtol than order 5 for the same error).
PLAN = (
    ("chain_bushing:n_links=30", "ode", (f"cvode-bdf:{ORDERS}", f"ida:{ORDERS}"),
     (1e-3, 1e-4, 1e-5, 1e-6, 1e-7)),
    ("chain_bushing:n_links=150", "ode", (f"cvode-bdf:{ORDERS}", f"ida:{ORDERS}"),
     (1e-3, 1e-4, 1e-5)),
    ("chain_drive:n_links=30", "ode", (f"cvode-bdf:{ORDERS}",), (1e-3, 1e-4, 1e-5, 1e-6)),
    ("chain_drive:n_links=30", "ggl", (f"ida:{ORDERS}",), (1e-3, 1e-4, 1e-5, 1e-6)),
    ("chain_drive:n_links=30", "i3", (f"hht:{ALPHAS}",), (1e-3, 1e-4, 1e-5)),
    ("cvt_chain:friction=1", "ode", (f"cvode-bdf:{ORDERS}", f"ida:{ORDERS}"), (1e-3, 1e-4)),
    ("cvt_chain:friction=0", "ode", (f"cvode-bdf:{ORDERS}", f"ida:{ORDERS}"), (1e-3, 1e-4)),
)
#: seconds: a test's run
QUICK_PLAN = (
    ("two_mass:c2=1000", "ode", (f"cvode-bdf:{ORDERS}",), (1e-3, 1e-4, 1e-5)),
)
#: seconds a case may take before it is recorded timeout (not a point of its line)
TIMEOUT_S, QUICK_TIMEOUT_S = 120.0, 20.0


def make_cases(plan) -> list:
    """The cases of ``plan`` (nothing unsupported)."""
    cases = []
    for spec, form, integrators, rtols in plan:
        cases += expand(problems=[spec], formulations=[form], integrators=list(integrators),
                        rtols=list(rtols))
    return [c for c in cases if not c.unsupported]


def _num(value):
    if value is None or value is pd.NA or (isinstance(value, float) and math.isnan(value)):
        return None
    return value.item() if hasattr(value, "item") else value


def compare(df: pd.DataFrame) -> list[dict]:
    """One row per line: problem, formulation, line, CPU (and how) to each target,
    the ratio to its default's CPU, and whether it crosses the default."""
    rows = []
    records = clean_records(df)
    for (problem, params, form), group in records.groupby(["problem", "params", "formulation"],
                                                        sort=False):
        table = reach.target_table(group, measure="final")
        by = {r["label"]: r for r in table.to_dict("records")}
        base = dict(zip(group["label"], group["integrator"]))   # label -> registry name
        for name in sorted(by, key=lambda n: (base[n], n != base[n], n)):
            r, default = by[name], by.get(base[name])
            row = {"problem": problem, "params": json.loads(params), "formulation": form,
                   "line": name}
            faster = []
            for t in reach.TARGETS:
                tag = f"{t:.0e}"
                cpu, how = _num(r[f"cpu_{tag}"]), r[f"how_{tag}"]
                row[f"cpu_{tag}"], row[f"how_{tag}"] = cpu, how
                row[f"nfev_{tag}"] = _num(r[f"nfev_{tag}"])
                ratio = None
                if default is not None and name != base[name]:
                    d = _num(default[f"cpu_{tag}"])
                    if cpu is not None and d:
                        ratio = cpu / d
                    elif cpu is not None and d is None:
                        ratio = 0.0       # the variant reaches it, the default does not
                    elif cpu is None and d is not None:
                        ratio = math.inf
                row[f"ratio_{tag}"] = ratio
                if ratio is not None:
                    faster.append(ratio < 1)
            row["least_err"] = _num(r["best_err"])
            row["crosses"] = len(set(faster)) > 1
            rows.append(row)
    return rows


def _label(row) -> str:
    shown = ("friction",) if row["problem"] == "cvt_chain" else ("n_links",)
    params = ",".join(f"{k}={v:g}" if isinstance(v, (int, float)) else f"{k}={v}"
                      for k, v in row["params"].items() if k in shown)
    return f"{row['problem']} {params}".strip()


def markdown(rows: list[dict], wall: float) -> str:
    """The README's table."""
    from integrator_bench.harness.tables import markdown_lines

    header = ["problem", "form", "line"]
    for t in reach.TARGETS:
        header += [f"CPU to {t:.0e} [s]", f"nfev to {t:.0e}", "vs default"]
    header += ["least error", "lines cross"]
    body = []
    for r in rows:
        cells = [_label(r), r["formulation"], r["line"]]
        for t in reach.TARGETS:
            tag = f"{t:.0e}"
            cells.append(reach.cpu_cell(r[f"cpu_{tag}"], r[f"how_{tag}"]))
            cells.append("–" if r[f"nfev_{tag}"] is None else str(int(r[f"nfev_{tag}"])))
            ratio = r[f"ratio_{tag}"]
            cells.append("" if ratio is None else "only this" if ratio == 0
                         else "default only" if ratio == math.inf else f"{ratio:.2f}x")
        cells.append("–" if r["least_err"] is None else f"{r['least_err']:.1e}")
        cells.append("yes" if r["crosses"] else "")
        body.append(cells)
    lines = markdown_lines(header, body, header[3:])
    return "\n".join(lines + ["", ranking_text.CAPTION, "",
                              f"(vs default: the line's CPU over its integrator's default's "
                              f"at the same error; {wall:.0f} s wall for the whole table)"])


def _fail(message: str) -> int:
    print(f"settings_check: error: {message}", file=sys.stderr)
    return 2


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="seconds: two_mass only")
    parser.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    parser.add_argument("--store", type=Path, help="keep the records here (default: a temporary file)")
    parser.add_argument("--resume", action="store_true", help="reuse the records in --store")
    parser.add_argument("--json", action="store_true", help="print the table as JSON")
    args = parser.parse_args(argv)
    if args.jobs < 1:
        return _fail(f"--jobs {args.jobs} must be at least 1")
    if args.resume and args.store is None:
        return _fail("--resume needs --store")
    cases = make_cases(QUICK_PLAN if args.quick else PLAN)
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        limits = Limits(budget_s=QUICK_TIMEOUT_S if args.quick else TIMEOUT_S)
        with Store(args.store or Path(tmp) / "settings_check.sqlite") as store, \
                Session(RunContext(store=store, jobs=args.jobs, resume=args.resume,
                                   progress=False, command=" ".join(sys.argv),
                                   limits=limits)) as session:
            df = session.run(cases)
    rows = compare(df)
    wall = time.perf_counter() - start
    if args.json:
        print(json.dumps({"rows": rows, "wall_s": wall}, default=str))
    else:
        print(markdown(rows, wall))
    return 0


if __name__ == "__main__":
    sys.exit(main())
