"""A raced store against an exhaustive one of the same matrix: what racing kept exact.

Run the same selection twice from empty stores, raced and ``--exhaustive``, then
compare::

    .venv/bin/ibench run --preset iftomm --store /tmp/raced.sqlite --no-contenders
    .venv/bin/ibench run --preset iftomm --exhaustive --store /tmp/exh.sqlite --no-contenders
    .venv/bin/python studies/race_check.py /tmp/raced.sqlite /tmp/exh.sqlite

For each target (default: the report's, 1e-3 and 1e-5, both at or looser than the
race target) it prints per problem and parameter set whether the answer is the
same (each store's cheapest line among the lines the other's answer names, a
winner or a tie: :func:`same_answer`); per integrator whether its share of the problems within 2x, 10x and tau
(16x) of the best is the same (the performance profile's shares); and per line
whether its Pareto front below tau times the problem's best is the same cases. Then
the cases each store ran and their CPU by the records (the solves alone; a
``timeout`` or ``dominated`` case at its budget or bound). Exits 1 when any answer,
share or front differs, 2 on bad input.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
import pandas as pd

from integrator_bench.harness.matrix.store import StoreError, load
from integrator_bench.harness.ranking import reach
from integrator_bench.harness.ranking.racing import TAU
from integrator_bench.harness.ranking.records import LINE, clean_records
from integrator_bench.harness.report import profiles

FACTORS = (2.0, 10.0, TAU)


def answers(records: pd.DataFrame, target: float) -> dict:
    """``(problem, params) -> (line, lines)`` at ``target``: the cheapest line's
    ``"label (formulation)"`` by :func:`~integrator_bench.harness.ranking.reach.cheapest`
    and the lines its answer names (that line alone for a winner, every tied line
    for a tie); ``("not reached", {})`` when no line reaches it."""
    out = {}
    for key, rows in records.groupby(["problem", "params"], sort=True):
        top = reach.cheapest(reach.target_table(rows, (target,)), target)
        if top is None:
            out[key] = ("not reached", frozenset())
        else:
            line = reach.line_name(top)
            out[key] = (line, frozenset(top["tied"]) if top["verdict"] == "tie"
                        else frozenset([line]))
    return out


def same_answer(a: tuple | None, b: tuple | None) -> bool:
    """Whether two stores' answers (:func:`answers`) agree: each one's cheapest line
    is among the lines the other's answer names. Which line of a tie timed the
    cheaper, and which lines at a tie's edge joined it, is the noise of the CPU;
    a winner the other store does not name, or a line missing from it, is not."""
    if a is None or b is None:
        return a is b
    return a[0] in b[1] | {b[0]} and b[0] in a[1] | {a[0]}


def answer_words(answer: tuple | None) -> str:
    """An answer of :func:`answers` as the check prints it."""
    if answer is None:
        return "none"
    line, lines = answer
    return f"tie: {', '.join(sorted(lines))}" if len(lines) > 1 else line


def shares(records: pd.DataFrame, target: float) -> pd.DataFrame:
    """Per integrator, the share of the solved problems within each of :data:`FACTORS`."""
    cpu, _ = profiles.costs(records, target)
    return profiles.share_table(cpu, FACTORS).drop(columns="solved")


def fronts(records: pd.DataFrame, target: float) -> dict:
    """Per line, the case ids of its Pareto front below tau times its problem's least
    CPU to ``target``."""
    points = reach.line_points(records[records["status"] != "unsupported"])
    best = reach.cpu_to_reach(records, target).groupby(["problem", "params"])["cpu_s"].min()
    out = {}
    for key, rows in points.groupby(LINE, sort=True):
        bound = TAU * best.get((key[0], key[1]), np.nan)
        front = rows.iloc[reach.pareto_front(rows["err"], rows["cpu_s"])]
        out[key] = sorted(front.loc[front["cpu_s"] <= bound, "case_id"])
    return out


def cpu_by_records(records: pd.DataFrame) -> float:
    """The solves' CPU: ``cpu_s`` times its samples, a ``timeout`` at its budget, a
    ``dominated`` case stopped at its bound at that bound."""
    cpu = pd.to_numeric(records["cpu_s"], errors="coerce").fillna(0.0)
    repeat = pd.to_numeric(records["repeat"], errors="coerce").fillna(1.0)
    total = cpu * repeat
    timeout = records["status"] == "timeout"
    total[timeout] = np.maximum(total[timeout], pd.to_numeric(records["budget_s"][timeout]))
    stopped = (records["status"] == "dominated") & (records["reason"] == "race_bound")
    total[stopped] = pd.to_numeric(records["race_bound_s"][stopped])
    return float(total.sum())


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("raced")
    p.add_argument("exhaustive")
    p.add_argument("--target", type=float, action="append")
    args = p.parse_args(argv)
    try:
        raced, full = (clean_records(load(path)) for path in (args.raced, args.exhaustive))
    except StoreError as exc:
        print(f"race_check: {exc}", file=sys.stderr)
        return 2
    differ = 0
    for target in args.target or reach.TARGETS:
        a, b = answers(raced, target), answers(full, target)
        keys = sorted(set(a) | set(b))
        wrong = [k for k in keys if not same_answer(a.get(k), b.get(k))]
        edge = [k for k in keys if k not in wrong and a.get(k) != b.get(k)]
        print(f"target {target:g}: {len(a)} problems, answers differ on {len(wrong)}"
              f" (the same, the tie's lines or its cheapest one differing, on {len(edge)})")
        for k in wrong + edge:
            print(f"  {'differs' if k in wrong else 'same'}: {k[0]} {k[1]}: raced "
                  f"{answer_words(a.get(k))}, exhaustive {answer_words(b.get(k))}")
        sa, sb = shares(raced, target), shares(full, target)
        diff = (sa - sb.reindex_like(sa)).abs()
        bad = diff[(diff > 1e-12).any(axis=1)]
        print(f"  profile shares within {', '.join(f'{f:g}x' for f in FACTORS)}: "
              f"{len(sa)} integrators, {len(bad)} differ")
        for name in bad.index:
            print(f"    {name}: raced {sa.loc[name].round(3).tolist()}, "
                  f"exhaustive {sb.loc[name].round(3).tolist()}")
        fa, fb = fronts(raced, target), fronts(full, target)
        moved = [k for k in set(fa) | set(fb) if fa.get(k, []) != fb.get(k, [])]
        print(f"  Pareto fronts below tau times the best: {len(fb)} lines, {len(moved)} differ")
        for k in sorted(moved)[:10]:
            print(f"    {k[2]} ({k[3]}) on {k[0]}: raced {fa.get(k)}, exhaustive {fb.get(k)}")
        differ += len(wrong) + len(bad) + len(moved)
    for name, records in (("raced", raced), ("exhaustive", full)):
        counts = records["status"].value_counts()
        print(f"{name}: {len(records)} cases ({', '.join(f'{n} {s}' for s, n in counts.items())}); "
              f"solves' CPU by the records {cpu_by_records(records):.1f} s")
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
