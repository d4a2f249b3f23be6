"""Run-to-run spread: the same ``ibench run`` several times, what its CPU and answers do.

Runs one ``ibench run`` command ``--runs`` times (default 3; the quick preset unless
other ``ibench run`` arguments are given, ``--jobs N`` passed on), each into a fresh
temporary data directory (``IBENCH_DATA_DIR``) with the ``ibench`` of this interpreter
(``sys.executable -m integrator_bench.harness.cli``), one after the other, timing each
run's wall; or, with ``--stores``, only reads existing stores (an ``ibench.sqlite`` file
or a data directory holding one), one per run. Then prints:

1. **CPU spread**: over the cases ``ok`` in every run (matched on their key,
   :data:`~integrator_bench.harness.matrix.line.KEY_FIELDS`), each case's ratio of its
   largest recorded ``cpu_s`` to its least over the runs; the median, 90th percentile
   and largest of those ratios and the median relative spread (ratio - 1, in %),
   overall and by CPU decade of the case (its median ``cpu_s`` over the runs: the
   decade ``1 ms`` holds 1 ms <= CPU < 10 ms; ``< 1 ms`` the cases below).
2. **Answers**: per problem and parameter set, each run's answer to "which line is
   cheapest to the default target" (:data:`~integrator_bench.harness.ranking.reach.DEFAULT_TARGET`,
   error measure ``max``): the same call as ``ibench run``'s summary makes,
   :func:`~integrator_bench.harness.ranking.reach.cheapest` of
   :func:`~integrator_bench.harness.ranking.reach.target_table` on the cleaned records
   (:func:`~integrator_bench.harness.ranking.records.clean_records`). A run's answer is
   a set of lines ``"label (formulation)"``: the lines of the tie when ``cheapest``
   says ``verdict == "tie"`` (its ``tied``), else the one top line; ``{"not
   reached"}`` when no line reaches the target.
3. **Consistency**: a problem is consistent when every pair of runs gives answer
   sets that overlap (a single winner is a set of one: two runs naming different
   winners and no tie are inconsistent; a winner inside another run's tie is
   consistent). The count of consistent problems, and a table problem x run (a
   problem some run did not answer is counted apart, not in the table).
4. Each run's wall (measured here, or for a store the sum of its runs'
   ``finished - started``, to the second) and the total CPU of its solves (the sum
   of ``cpu_s`` over its records, as the run's summary counts it).

Usage::

    .venv/bin/python studies/rerun_spread.py                         # quick preset, 3 runs
    .venv/bin/python studies/rerun_spread.py --runs 5 --jobs 1 -p two_mass -p squeezer
    .venv/bin/python studies/rerun_spread.py --keep /tmp/spread      # keep /tmp/spread/run1 ...
    .venv/bin/python studies/rerun_spread.py --stores /tmp/run1 /tmp/run2 /tmp/run3

Bad input: one line on standard error, exit 2; a run that fails: exit 1.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from itertools import combinations
from pathlib import Path

import numpy as np
import pandas as pd

STORE_NAME = "ibench.sqlite"
#: the decades the spread is broken down by, labelled by their lower bound
DECADES = ((0.0, "< 1 ms"), (1e-3, "1 ms"), (1e-2, "10 ms"), (1e-1, "100 ms"),
           (1.0, "1 s"), (10.0, "10 s"))
NOT_REACHED = "not reached"


def store_path(path: Path) -> Path:
    """The store file of ``path``: itself when it is a file, else ``path/ibench.sqlite``."""
    return path if path.is_file() else path / STORE_NAME


def load_run(path: Path) -> tuple[pd.DataFrame, float | None]:
    """The cleaned records of the store at ``path`` (a file or a data directory) and
    the wall of its runs: the sum of ``finished - started`` (seconds; None when a
    run is unfinished or there is none)."""
    from integrator_bench.harness.matrix.store import load, load_runs
    from integrator_bench.harness.ranking.records import clean_records

    store = store_path(path)
    runs = load_runs(store)
    start = pd.to_datetime(runs["started"], utc=True, errors="coerce", format="ISO8601")
    end = pd.to_datetime(runs["finished"], utc=True, errors="coerce", format="ISO8601")
    wall = (end - start).dt.total_seconds()
    return clean_records(load(store)), (float(wall.sum()) if len(wall) and wall.notna().all()
                                        else None)


def _case_keys(df: pd.DataFrame) -> pd.DataFrame:
    from integrator_bench.harness.matrix.line import KEY_FIELDS

    keyed = df.assign(rtol=df["rtol"].fillna(-1.0), h=df["h"].fillna(-1.0))
    return keyed.set_index(list(KEY_FIELDS))


def cpu_spread(runs: list[pd.DataFrame]) -> pd.DataFrame:
    """Each case ``ok`` in every run: its ``cpu_s`` in each run and their spread.

    Parameters
    ----------
    runs : list of pandas.DataFrame
        The cleaned records of each run (one record per case).

    Returns
    -------
    pandas.DataFrame
        Indexed by the case key; columns ``cpu_0`` ... (each run's ``cpu_s``),
        ``median`` (their median), ``ratio`` (largest over least) and ``decade``
        (the label of :data:`DECADES` the median falls in).
    """
    cols = []
    for k, df in enumerate(runs):
        ok = _case_keys(df[(df["status"] == "ok") & (pd.to_numeric(df["cpu_s"]) > 0)])
        cols.append(pd.to_numeric(ok["cpu_s"]).astype(float).rename(f"cpu_{k}"))
    both = pd.concat(cols, axis=1, join="inner")
    cpu = both.to_numpy()
    both["median"] = np.median(cpu, axis=1)
    both["ratio"] = cpu.max(axis=1) / cpu.min(axis=1)
    both["decade"] = [decade(c) for c in both["median"]]
    return both


def decade(cpu: float) -> str:
    """The label of the :data:`DECADES` entry ``cpu`` seconds fall in."""
    return [label for low, label in DECADES if cpu >= low][-1]


def spread_table(spread: pd.DataFrame) -> list[dict]:
    """The summary of :func:`cpu_spread`: overall, then by decade (those with cases).

    Returns
    -------
    list of dict
        ``cases``: the group (``all`` or a decade's label), ``n``, ``median``,
        ``p90`` and ``max`` of the ratio largest/least over runs, and ``rel``, the
        median of ``ratio - 1`` (the relative spread).
    """
    groups = [("all", spread)] + [(label, spread[spread["decade"] == label])
                                   for _, label in DECADES]
    rows = []
    for name, g in groups:
        if not len(g) and name != "all":
            continue
        r = g["ratio"].to_numpy()
        rows.append({"cases": name, "n": len(g),
                     "median": float(np.median(r)) if len(r) else math.nan,
                     "p90": float(np.percentile(r, 90)) if len(r) else math.nan,
                     "max": float(r.max()) if len(r) else math.nan,
                     "rel": float(np.median(r - 1)) if len(r) else math.nan})
    return rows


def answer_set(top: dict | None) -> frozenset:
    """A run's answer as a set of ``"label (formulation)"`` lines, from what
    :func:`~integrator_bench.harness.ranking.reach.cheapest` returned: the lines of
    the tie (``tied``) when its ``verdict`` is ``"tie"``, else the top line alone;
    ``{"not reached"}`` when no line reaches the target (``top`` None)."""
    if top is None:
        return frozenset([NOT_REACHED])
    if top.get("verdict") == "tie":
        return frozenset(top["tied"])
    return frozenset([f"{top['label']} ({top['formulation']})"])


def answers(df: pd.DataFrame) -> dict:
    """Per ``(problem, params)`` of the cleaned records ``df``, the answer set
    (:func:`answer_set`) of the cheapest line to the default target, by the call
    ``ibench run``'s summary makes."""
    from integrator_bench.harness.ranking import reach

    out = {}
    for key, rows in df.groupby(["problem", "params"], sort=True):
        table = reach.target_table(rows, (reach.DEFAULT_TARGET,), reach.DEFAULT_ERROR)
        out[key] = answer_set(reach.cheapest(table, reach.DEFAULT_TARGET))
    return out


def consistent(sets: list[frozenset]) -> bool:
    """Whether every pair of the answer sets ``sets`` overlaps (one set, or none:
    consistent)."""
    return all(a & b for a, b in combinations(sets, 2))


def consistency(per_run: list[dict]) -> tuple[list[dict], int]:
    """The problems every run answered, each with its runs' answers and whether
    they are consistent (:func:`consistent`).

    Parameters
    ----------
    per_run : list of dict
        :func:`answers` of each run.

    Returns
    -------
    rows : list of dict
        ``problem``, ``params``, ``answers`` (one set per run) and ``consistent``.
    missing : int
        The problems some run did not answer (left out of ``rows``).
    """
    keys = set.intersection(*(set(a) for a in per_run)) if per_run else set()
    every = set().union(*(set(a) for a in per_run)) if per_run else set()
    rows = [{"problem": p, "params": q, "answers": [a[(p, q)] for a in per_run],
             "consistent": consistent([a[(p, q)] for a in per_run])} for p, q in sorted(keys)]
    return rows, len(every - keys)


def solves_cpu(df: pd.DataFrame) -> float:
    """The CPU of a run's solves: the sum of ``cpu_s`` over its records."""
    return float(pd.to_numeric(df["cpu_s"], errors="coerce").sum())


def short_label(problem: str, params: str) -> str:
    """``problem:key=value,...`` with the parameters that differ from the problem's
    defaults, as the run's summary names a problem and parameter set."""
    from integrator_bench.harness.matrix import registry
    from integrator_bench.problems.base import format_label

    values = json.loads(params)
    defaults = {p.name: p.default
                for p in getattr(registry.problems().get(problem), "parameters", ())}
    return format_label(problem, {k: v for k, v in values.items()
                                  if k not in defaults or v != defaults[k]})


def _cell(answer: frozenset) -> str:
    return " = ".join(sorted(answer)) if len(answer) > 1 else next(iter(answer))


def report(runs: list[pd.DataFrame], walls: list[float | None], names: list[str]) -> str:
    """The study's printout (parts 1-4 of the module docstring) of the cleaned
    records ``runs``, their walls and their names."""
    from integrator_bench.harness.tables import markdown_table

    out = [f"{len(runs)} runs: " + ", ".join(names), ""]
    spread = cpu_spread(runs)
    out.append(f"1. CPU spread (cpu_s, largest/least over the runs) of the {len(spread)} "
               "cases ok in every run")
    rows = [[r["cases"], r["n"], f"{r['median']:.3f}", f"{r['p90']:.3f}", f"{r['max']:.3f}",
             f"{100 * r['rel']:.1f} %"] for r in spread_table(spread)]
    out.append(markdown_table(["cases (CPU decade)", "n", "median ratio", "90th pct",
                               "largest", "median spread"], rows, right=range(1, 6)))
    per_run = [answers(df) for df in runs]
    rows, missing = consistency(per_run)
    n_ok = sum(r["consistent"] for r in rows)
    out.append(f"2-3. Cheapest line to 1e-5 (max error) per run: {n_ok} of {len(rows)} "
               "problems consistent (every pair of runs' answers overlaps; a = b: a tie)"
               + (f"; {missing} not answered in every run" if missing else ""))
    cells = [[short_label(r["problem"], r["params"]),
              *[_cell(a) for a in r["answers"]], "yes" if r["consistent"] else "NO"]
             for r in rows]
    out.append(markdown_table(["problem", *[f"run {k + 1}" for k in range(len(runs))],
                               "consistent"], cells))
    out.append("4. Runs")
    cells = [[f"run {k + 1}", name, "?" if wall is None else f"{wall:.0f}",
              f"{solves_cpu(df):.1f}", int((df["status"] == "ok").sum()), len(df)]
             for k, (df, wall, name) in enumerate(zip(runs, walls, names))]
    out.append(markdown_table(["run", "store", "wall s", "CPU of the solves s", "ok", "cases"],
                              cells, right=range(2, 6)))
    return "\n".join(out)


#: the checkout's committed references: every run reads the same ones (a fresh data
#: directory would compute its own, spending minutes and moving the errors a little)
COMMITTED_REFERENCES = Path(__file__).resolve().parents[1] / "results" / "reference"


def run_ibench(args: list[str], data_dir: Path) -> tuple[subprocess.CompletedProcess, float]:
    """``ibench run ARGS`` with this interpreter into the data directory ``data_dir``,
    on the committed references (:data:`COMMITTED_REFERENCES`, unless
    ``IBENCH_REFERENCE_DIR`` names others); its result and wall seconds."""
    env = {**os.environ, "IBENCH_DATA_DIR": str(data_dir)}
    if COMMITTED_REFERENCES.is_dir():
        env.setdefault("IBENCH_REFERENCE_DIR", str(COMMITTED_REFERENCES))
    start = time.monotonic()
    got = subprocess.run([sys.executable, "-m", "integrator_bench.harness.cli", "run", *args],
                         capture_output=True, text=True, env=env)
    return got, time.monotonic() - start


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0], allow_abbrev=False,
                                 epilog="Other arguments are passed on to `ibench run`.")
    ap.add_argument("--runs", type=int, default=3, metavar="N", help="runs (default 3)")
    ap.add_argument("--jobs", type=int, default=None, metavar="N",
                    help="passed on to ibench run")
    ap.add_argument("--stores", nargs="+", type=Path, metavar="DIR",
                    help="only read these stores (files or data directories), one per run")
    ap.add_argument("--keep", type=Path, metavar="DIR",
                    help="keep the runs' data directories as DIR/run1 ... (default: "
                         "temporary, deleted)")
    args, extra = ap.parse_known_args(argv)
    if args.stores:
        if extra or args.jobs is not None:
            print(f"rerun_spread: --stores reads stores only; not {extra or ['--jobs']}",
                  file=sys.stderr)
            return 2
        missing = [str(p) for p in args.stores if not store_path(p).is_file()]
        if missing:
            print(f"rerun_spread: no store at {missing[0]}", file=sys.stderr)
            return 2
        loaded = [load_run(p) for p in args.stores]
        print(report([df for df, _ in loaded], [w for _, w in loaded],
                     [str(p) for p in args.stores]))
        return 0
    if args.runs < 2:
        print("rerun_spread: --runs needs at least 2", file=sys.stderr)
        return 2
    command = extra + ([] if args.jobs is None else ["--jobs", str(args.jobs)])
    runs, walls, names = [], [], []
    with tempfile.TemporaryDirectory(prefix="rerun-spread-") as tmp:
        root = args.keep or Path(tmp)
        for k in range(args.runs):
            data = root / f"run{k + 1}"
            data.mkdir(parents=True, exist_ok=True)
            got, wall = run_ibench(command, data)
            if got.returncode != 0:
                print(f"rerun_spread: ibench run {' '.join(command)} exited "
                      f"{got.returncode}: {got.stderr.strip()[-500:]}", file=sys.stderr)
                return 1
            print(f"run {k + 1}: wall {wall:.1f} s", file=sys.stderr)
            df, _ = load_run(data)
            runs.append(df)
            walls.append(wall)
            names.append(str(data) if args.keep else f"run{k + 1}")
    print(f"ibench run {' '.join(command)}".rstrip())
    print(report(runs, walls, names))
    return 0


if __name__ == "__main__":
    sys.exit(main())
