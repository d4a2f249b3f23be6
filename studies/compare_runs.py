"""Two stores of the same matrix side by side: what a change did to each integrator.

For a change that should not alter results (a refactoring) or should alter them
in a known way (dense output in place of shortened steps), run the same preset
at the commit before and after it and compare the records case by case::

    git worktree add /tmp/before <commit>      # each with its own venv
    (cd /tmp/before && .venv/bin/ibench run --jobs 1 --store /tmp/before.sqlite)
    .venv/bin/ibench run --jobs 1 --store /tmp/after.sqlite
    .venv/bin/python studies/compare_runs.py /tmp/before.sqlite /tmp/after.sqlite

Cases are matched on (problem, parameters, formulation, integrator with its
settings (its label, ``cvode-bdf (max_order=2)``), rtol, h); ``--rename old=new``
matches an integrator that changed its name (for example ``hht-fixed=hht``). Per
integrator (with its settings) the table gives the matched cases, how many
ran (status ok) in each store, how many of the cases ok in both have identical
nsteps, nfev and njev, the median ratios after/before of nsteps and nfev, the
largest change of scd (significant correct digits) and the ratio of the summed
CPU. Cases found in one store only are counted below the table. Bad input: one
line on standard error, exit 2.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from integrator_bench.harness.matrix.record import CaseStatus

#: a case: its line's label (an integrator with settings is one of its own,
#: ``cvode-bdf (max_order=2)``) and its tolerance or step
KEY = ["problem", "params", "formulation", "label", "rtol", "h"]
COUNTS = ["nsteps", "nfev", "njev"]


def _load(path: Path) -> pd.DataFrame:
    from integrator_bench.harness.matrix.store import load

    df = load(path)      # every record with its label (the store fills it for older ones)
    df = df.sort_values("created").drop_duplicates(KEY, keep="last")
    return df[df.status != CaseStatus.UNSUPPORTED].copy()


def compare(before: pd.DataFrame, after: pd.DataFrame, rename: dict | None = None) -> tuple:
    """Per-integrator comparison table, and the keys found in one store only.

    Parameters
    ----------
    before, after : DataFrame
        Records (one per case) of the two runs.
    rename : dict, optional
        Labels (integrator names, with their settings) of ``before`` mapped to
        their names in ``after``.

    Returns
    -------
    table : DataFrame
        One row per integrator (see the module docstring for the columns).
    only_before, only_after : int
        Numbers of run cases without a match in the other store.
    """
    before = before.assign(label=before.label.replace(rename or {}))
    for df in (before, after):
        df["rtol"] = df.rtol.fillna(-1.0)
        df["h"] = df.h.fillna(-1.0)
    both = before.merge(after, on=KEY, suffixes=("_b", "_a"))
    rows = []
    for name, g in both.groupby("label"):
        ok = g[(g.status_b == CaseStatus.OK) & (g.status_a == CaseStatus.OK)]
        same = np.ones(len(ok), bool)
        for c in COUNTS:
            same &= (ok[f"{c}_b"].fillna(-1) == ok[f"{c}_a"].fillna(-1)).to_numpy()
        dscd = (ok.scd_a - ok.scd_b).abs()
        rows.append({
            "integrator": name, "cases": len(g),
            "ok before": int((g.status_b == CaseStatus.OK).sum()),
            "ok after": int((g.status_a == CaseStatus.OK).sum()),
            "counts identical": f"{int(same.sum())}/{len(ok)}",
            "nsteps after/before": float(np.median(ok.nsteps_a / ok.nsteps_b)) if len(ok) else np.nan,
            "nfev after/before": float(np.median(ok.nfev_a / ok.nfev_b)) if len(ok) else np.nan,
            "max |d scd|": float(dscd.max()) if len(ok) else np.nan,
            "CPU after/before": float(ok.cpu_s_a.sum() / ok.cpu_s_b.sum()) if len(ok) else np.nan,
        })
    keys_b = set(map(tuple, before[KEY].to_numpy().tolist()))
    keys_a = set(map(tuple, after[KEY].to_numpy().tolist()))
    return pd.DataFrame(rows), len(keys_b - keys_a), len(keys_a - keys_b)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("before", type=Path)
    ap.add_argument("after", type=Path)
    ap.add_argument("--rename", action="append", default=[], metavar="OLD=NEW",
                    help="an integrator of BEFORE known by another name in AFTER")
    args = ap.parse_args(argv)
    for path in (args.before, args.after):
        if not path.is_file():
            print(f"compare_runs: no store {path}", file=sys.stderr)
            return 2
    rename = {}
    for item in args.rename:
        old, sep, new = item.partition("=")
        if not sep or not old or not new:
            print(f"compare_runs: --rename {item!r}: expected OLD=NEW", file=sys.stderr)
            return 2
        rename[old] = new
    table, only_b, only_a = compare(_load(args.before), _load(args.after), rename)
    from integrator_bench.harness.tables import markdown_table

    cells = [[f"{v:.3g}" if isinstance(v, float) and v == v else v for v in row]
             for row in table.itertuples(index=False)]
    print(markdown_table(list(table.columns), cells, right=range(1, len(table.columns))), end="")
    print(f"\nrun cases only before: {only_b}; only after: {only_a}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
