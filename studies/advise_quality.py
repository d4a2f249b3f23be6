"""How good is ``ibench advise``: its pick against the best line of the full matrix.

For each problem named (``-p``, default: the small built-in ones) and each target
(``--target``, default 1e-3 and 1e-5), the advice's pick (its advised run's CPU)
against the cheapest line the full preset's matrix finds at that target on the same
problem (:func:`integrator_bench.harness.ranking.reach.cheapest` of the report's
:func:`~integrator_bench.harness.ranking.reach.target_table`, interpolated), and the
advice's wall time (and of it, its search's) against the matrix's. The matrix is
``ibench run -p P --preset full`` (``--matrix full``, the default) or the sweep that
answers the advice's question (``--matrix sweep``: the same, adaptive lines only, rtol
1e-2 ... 1e-8 a decade apart, 5 s a case: :data:`SWEEP`)
(with the same ``-i`` restriction, when one is given) on the parameter set the advice
takes (a bare name: the problem's first benchmark set, named explicitly, since the
matrix would run every set), run once per problem into its own store (kept: a second
call reuses it and its wall time); the advices run into another, each from scratch
(``--no-resume``). ``--jobs`` goes to both. An advice that exits with neither an answer
nor a partial one (a crash) is a row ``failed`` and its error's last line goes to
standard error.

    python studies/advise_quality.py -p two_mass:c2=1000 -i scipy-RK45 -i cvode-bdf ...

Prints one Markdown table row per (problem, target): pick (``[partial]`` when the advice
marked its answer so), its CPU, the matrix's best, its CPU, the ratio pick / best, the
walls.
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.cases import parse_problem_spec
from integrator_bench.harness.matrix.line import parse_spec
from integrator_bench.harness.matrix.store import load
from integrator_bench.harness.ranking import reach

DEFAULT_PROBLEMS = ("two_mass:c2=1000", "two_mass:c2=0.1", "spring_pendulum", "bouncing_ball")


def _ibench(*args) -> tuple[subprocess.CompletedProcess, float]:
    start = time.monotonic()
    got = subprocess.run([sys.executable, "-m", "integrator_bench.harness.cli", *args],
                         capture_output=True, text=True)
    return got, time.monotonic() - start


def first_set(problem: str) -> str:
    """``problem`` with a bare name's first benchmark parameter set written out (the
    set the advice takes; ``ibench run`` would run every set of a bare name)."""
    name, given = parse_spec(problem)
    if given is not None:
        return problem
    sets = registry.get_problem_class(name).benchmark_parameters
    params = sets[0] if sets else {}
    return f"{name}:" + ",".join(f"{k}={v!r}" for k, v in params.items()) if params else name


#: the sweep that answers the advice's question (``--matrix sweep``): every adaptive line
#: the advice may choose among (every integrator, seed variant and formulation of the
#: full preset), a decade of tolerances apart, at the full preset's budget a case
SWEEP = ("--rtol", *(f"1e-{e}" for e in range(2, 9)), "--timeout", "5")


def matrix(problem: str, integrators, store: Path, jobs=None, kind: str = "full") -> float:
    """Run the full preset (``kind`` ``full``) or the sweep of the advice's candidates
    (``sweep``: :data:`SWEEP`) on ``problem`` into ``store``; its wall seconds."""
    args = ["run", "-p", first_set(problem), "--preset", "full", "--store", str(store),
            "--json", *(SWEEP if kind == "sweep" else ())]
    for i in integrators or ():
        args += ["-i", i]
    if jobs:
        args += ["--jobs", str(jobs)]
    got, wall = _ibench(*args)
    if got.returncode not in (0, 1):
        raise SystemExit(f"the matrix of {problem} failed: {got.stderr[-500:]}")
    return wall


def best_line(store: Path, target: float, measure: str, params: dict):
    """The cheapest adaptive line of the matrix in ``store`` at ``target``, on the
    parameter set ``params`` (a store of an earlier run may hold several)."""
    rows = load(store)
    same = rows["params"].map(lambda p: json.loads(p) == params)
    rows = rows[rows["h"].isna() & same]   # adaptive lines: what the advice chooses among
    return reach.cheapest(reach.target_table(rows, (target,), measure), target)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-p", "--problem", action="append")
    parser.add_argument("-i", "--integrator", action="append")
    parser.add_argument("--target", action="append", type=float)
    parser.add_argument("--error", default="max")
    parser.add_argument("--jobs", type=int, help="worker processes of the matrix and the "
                        "advice (default: theirs, the number of cores)")
    parser.add_argument("--matrix", choices=("full", "sweep"), default="full",
                        help="what the advice is measured against: the full preset's matrix "
                        "(adaptive and fixed-step lines, 7 tolerances and 3 step counts), or "
                        "the sweep of the advice's own candidates, rtol 1e-2 ... 1e-8 a decade "
                        "apart, 5 s a case")
    parser.add_argument("--out", type=Path, default=Path("results/advise_quality"))
    args = parser.parse_args(argv)
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    print("| problem | target | advice's pick | CPU s | matrix's best | CPU s | pick / best "
          "| advice wall s | of it the search | matrix wall s | advice / matrix |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    ratios, walls = [], []
    for problem in args.problem or DEFAULT_PROBLEMS:
        stem = re.sub(r"[^A-Za-z0-9.+-]+", "_", problem)   # an FMU's path too
        kind = "" if args.matrix == "full" else f"{args.matrix}-"
        mstore = out / f"matrix-{kind}{stem}.sqlite"
        walls_file = mstore.with_suffix(".wall")   # the matrix's wall, kept for re-runs
        if not mstore.exists():
            walls_file.write_text(
                f"{matrix(problem, args.integrator, mstore, args.jobs, args.matrix)}\n")
        params = parse_problem_spec(first_set(problem))[0].params_dict
        mwall = float(walls_file.read_text()) if walls_file.exists() else float("nan")
        for target in args.target or (1e-3, 1e-5):
            cmd = ["advise", "-p", problem, "--target", str(target), "--error", args.error,
                   "--store", str(out / "advise.sqlite"),
                   "--out", str(out / f"page-{stem}-{target:g}"),
                   "--json", "--no-resume"]
            for i in args.integrator or ():
                cmd += ["-i", i]
            if args.jobs:
                cmd += ["--jobs", str(args.jobs)]
            got, awall = _ibench(*cmd)
            answer = json.loads(got.stdout) if got.returncode in (0, 1) and got.stdout.strip() \
                else {"status": "failed"}
            if answer["status"] == "failed":
                print(f"{problem} at {target:g}: the advice failed (exit {got.returncode}): "
                      f"{(got.stderr.strip().splitlines() or [''])[-1]}", file=sys.stderr)
            best = best_line(mstore, target, args.error, params)
            win = answer.get("winner")
            pick = f"{win['integrator']} ({win['formulation']})" if win else answer["status"]
            if win and answer["status"] != "answer":    # partial: marked, as the advice does
                pick += f" [{answer['status']}]"
            pcpu = win["run"]["cpu_s"] if win else float("nan")
            bcpu = best["cpu_s"] if best else float("nan")
            bname = f"{best['label']} ({best['formulation']})" if best else "not reached"
            ratio = pcpu / bcpu if best and win else float("nan")
            search_wall = answer.get("cost", {}).get("search_wall_s", float("nan"))
            print(f"| {problem} | {target:g} | {pick} | {pcpu:.3g} | {bname} | {bcpu:.3g} | "
                  f"{ratio:.2f} | {awall:.0f} | {search_wall:.0f} | {mwall:.0f} | "
                  f"{awall / mwall:.2f} |", flush=True)
            ratios.append(ratio)
            walls.append(awall / mwall)
    within = sum(r <= 1.5 for r in ratios)
    print(f"\npick within 1.5x of the matrix's best: {within} of {len(ratios)}; advice wall / "
          f"matrix wall: at most {max(walls, default=float('nan')):.2f}")
    return 0


if __name__ == "__main__":
    pd.set_option("display.width", 200)
    sys.exit(main())
