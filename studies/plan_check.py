"""A run's plan against the run: the predicted CPU, statuses and wall time beside the measured.

Save the plan from the store the run will write (an empty one: the committed cost
model), run, then compare::

    .venv/bin/ibench run --preset iftomm --plan --json --store /tmp/s.sqlite > /tmp/plan.json
    .venv/bin/ibench run --preset iftomm --store /tmp/s.sqlite
    .venv/bin/python studies/plan_check.py /tmp/plan.json /tmp/s.sqlite

Prints per problem and in all the plan's CPU, the records' (the solves' CPU:
``cpu_s`` times its samples, a ``timeout`` at its budget, a ``dominated`` case at
its bound: :func:`race_check.cpu_by_records`; the contenders' timings again left
out) and measured over predicted; the cases by status beside the plan's predicted
timeouts and skips; and each run of the store, its wall time (its ``runs`` row,
started to finished) beside the plan's makespan on its number of workers. The plan
is of an exhaustive run: a raced run's cuts and the stiffness bound's skips are not
in it. Exits 2 on bad input.
"""

from __future__ import annotations

import argparse
import json
import sys
from datetime import datetime

import pandas as pd

from integrator_bench.harness.matrix.store import StoreError, load

import race_check


def by_problem(plan: dict, records: pd.DataFrame) -> pd.DataFrame:
    """Per problem (and ``all``): ``predicted``, ``measured`` CPU seconds and their
    ratio ``measured / predicted``."""
    ran = matrix(records)
    ran = ran[~ran["status"].isin(["unsupported", "skipped"])]
    measured = {p: race_check.cpu_by_records(rows) for p, rows in ran.groupby("problem")}
    table = pd.DataFrame({"predicted": pd.Series(plan["cpu_s_by_problem"], dtype=float),
                          "measured": pd.Series(measured, dtype=float)}).fillna(0.0)
    table.loc["all"] = table.sum()
    table["ratio"] = table["measured"] / table["predicted"]
    return table.sort_values("predicted", ascending=False)


def matrix(records: pd.DataFrame) -> pd.DataFrame:
    """The records of the matrix's cases, without the contenders' timings again
    (a record with ``contended`` set: the run's extra rounds, which no plan predicts)."""
    if "contended" not in records:
        return records
    return records[pd.to_numeric(records["contended"], errors="coerce").isna()]


def runs(path: str) -> list[tuple[str, float | None, int | None]]:
    """``(run id, wall seconds or None when unfinished, workers)`` of each run of the store."""
    from integrator_bench.harness.matrix.store import Store

    with Store(path, create=False) as store:
        table = store.runs()
    out = []
    for _, row in table.iterrows():
        wall = None
        if row.get("started") and row.get("finished"):
            wall = (datetime.fromisoformat(row["finished"])
                    - datetime.fromisoformat(row["started"])).total_seconds()
        try:
            workers = json.loads(row.get("backend") or "{}").get("jobs")
        except (TypeError, ValueError):
            workers = None
        out.append((row["run_id"], wall, workers))
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("plan", help="the plan's JSON (ibench run --plan --json)")
    p.add_argument("store")
    args = p.parse_args(argv)
    try:
        with open(args.plan, encoding="utf-8") as f:
            plan = json.load(f)
        records = load(args.store)
        table = by_problem(plan, records)
    except (OSError, ValueError, KeyError, StoreError) as exc:
        print(f"plan_check: {exc}", file=sys.stderr)
        return 2
    print(f"{'problem':<24}{'predicted':>12}{'measured':>12}{'ratio':>8}")
    for name, row in table.iterrows():
        print(f"{name:<24}{row['predicted']:>11.1f}s{row['measured']:>11.1f}s{row['ratio']:>8.2f}")
    counts = matrix(records)["status"].value_counts()
    skipped = records[records["status"] == "skipped"]["reason"].value_counts()
    kinds = plan["cases"]
    print(f"timeout: predicted {kinds.get('timeout', 0)}, measured {counts.get('timeout', 0)}")
    for reason in sorted({k.split(': ')[1] for k in kinds if k.startswith("skipped")}
                         | set(skipped.index)):
        print(f"skipped {reason}: predicted {kinds.get(f'skipped: {reason}', 0)}, "
              f"measured {skipped.get(reason, 0)}")
    print("measured: " + ", ".join(f"{n} {s}" for s, n in counts.items()))
    for run_id, wall, workers in runs(args.store):
        planned = plan["wall_s"].get(str(workers), {}).get("makespan")
        print(f"run {run_id}: wall {'unfinished' if wall is None else f'{wall:.0f} s'} on "
              f"{workers} workers; the plan's makespan "
              + ("not asked for" if planned is None else f"{planned:.0f} s"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
