"""Which formulation/integrator pairs reach the IFToMM precision levels, and at what CPU.

The IFToMM multibody benchmark library (specifications A01-A05 of the University of A
Coruna, ``mbsbenchmark/dist/A0x/A0x_specification.xml``) judges a simulation by the
largest error of its reference variables over the output steps against two levels:
A01 and A02 give 1e-1 (low precision) and 1e-3 (high precision). After ::

    .venv/bin/ibench run --preset iftomm --jobs 2 --store results/iftomm.sqlite
    .venv/bin/python studies/iftomm_levels.py results/iftomm.sqlite

this prints, per problem, a Markdown table with one row per formulation/integrator
pair: for each level the least CPU of an ok run whose largest error over the output
times (the record's ``err_max``: mixed error ``|e| / (1 + |ref|)`` of the problem's
error components, B0's position for ``n_four_bar``, at its ``position_scale`` of 1 m)
is within the level (with its rtol or h), or why none is: ``not reached`` (ran, too
inaccurate), ``failed``/``timeout`` (the statuses of its runs, with the first
message), ``unsupported``. The velocity error of that run (``err_vel``) is shown beside
it, since A02 scores B0's velocity too. A problem declaring ``precision_levels`` uses
its own; the others take A01/A02's (1e-1, 1e-3), and the table says so. Bad input: one
line on standard error, exit 2.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import pandas as pd

from integrator_bench.harness.model import registry
from integrator_bench.harness.model.record import CaseStatus
from integrator_bench.harness.report.records import named_variants

#: A01's and A02's levels: low and high precision
LEVELS = {"low": 1e-1, "high": 1e-3}


def levels_of(problem: str) -> tuple[dict, bool]:
    """The problem's precision levels, and whether it declares them itself."""
    cls = registry.problems().get(problem)
    own = getattr(cls, "precision_levels", None)
    return (dict(own), True) if own else (dict(LEVELS), False)


def cell(runs: pd.DataFrame, level: float) -> str:
    """The cheapest ok run within ``level``, or why there is none."""
    ok = runs[runs.status == CaseStatus.OK]
    within = ok[ok.err_max <= level].sort_values("cpu_s")
    if len(within):
        best = within.iloc[0]
        tol = f"rtol {best.rtol:g}" if pd.notna(best.rtol) else f"h {best.h:g}"
        vel = f", vel {best.err_vel:.1e}" if pd.notna(best.err_vel) else ""
        return f"{best.cpu_s:.2f} s ({tol}, err {best.err_max:.1e}{vel})"
    if len(ok):
        return f"not reached (best err {ok.err_max.min():.1e})"
    statuses = runs.status.value_counts()
    first = runs[runs.status != CaseStatus.OK].iloc[0]
    message = str(first.message or "")[:60]
    return f"{'/'.join(statuses.index)}: {message}"


def tables(df: pd.DataFrame) -> str:
    """The Markdown tables of every problem in the records ``df``."""
    out = []
    for (problem, params), rows in df.groupby(["problem", "params"], sort=True):
        levels, own = levels_of(problem)
        note = "" if own else " (A01/A02's levels; the problem declares none)"
        out += [f"## {problem} {params}{note}", "",
                "| formulation | integrator | " + " | ".join(
                    f"{name} ({value:g})" for name, value in levels.items()) + " |",
                "|---|---|" + "---|" * len(levels)]
        run = rows[rows.status != CaseStatus.UNSUPPORTED]
        for (form, integ), runs in run.groupby(["formulation", "integrator"], sort=True):
            out.append(f"| {form} | {integ} | " + " | ".join(
                cell(runs, value) for value in levels.values()) + " |")
        out += ["", f"{len(rows) - len(run)} unsupported cases left out.", ""]
    return "\n".join(out)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("store", type=Path, help="SQLite store of an `ibench run`")
    args = parser.parse_args(argv)
    if not args.store.is_file():
        print(f"store {str(args.store)!r} does not exist", file=sys.stderr)
        return 2
    from integrator_bench.harness.model.store import load
    df = named_variants(load(args.store))
    df = df.sort_values("created").drop_duplicates("case_id", keep="last")
    print(tables(df))
    return 0


if __name__ == "__main__":
    sys.exit(main())
