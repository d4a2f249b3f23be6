"""Settling the contenders: more samples where they decide an answer, and nowhere else.

:func:`settle` works on a run's records, problem and parameter set by problem
and parameter set. At each target it answers at, the lines within
:data:`~integrator_bench.harness.ranking.margin.BAND` of the cheapest are in
contention (:func:`~integrator_bench.harness.ranking.reach.contest`); a contest
is *open* while some contender's margin is neither clear (its interval above 1)
nor settled as equal (:attr:`~integrator_bench.harness.ranking.margin.Margin.settled`).
The records that the open contests' lines read their crossings off (the cheapest
line's and the open contenders') are timed again as one block per problem: in
:data:`ROUNDS` rounds, alternating between them, in a process of its own after
a discarded warmup round (:class:`~integrator_bench.harness.run.resample.Block`),
the problems' blocks side by side on the run's ``jobs``. As each block ends, its
contest's margins are computed again and, still open, it gets its next block at
once (no process waits for a batch to end), until no contest is open, a record
has :data:`MAX_ROUNDS` rounds, or a block would take the CPU spent and planned
past ``cpu_cap_s`` (``ibench run``: :data:`CPU_SHARE` of the run's CPU). The
first blocks start cheapest first, so the cap leaves out the dearest contests,
never the cheap ones.

Each record timed again is stored anew (the store keeps its newest record of a
case: the earlier one is superseded, not lost), its ``cpu_samples`` extended by
the rounds, ``contended`` their number, ``cpu_s`` their median with the
earlier samples, ``cpu_s_min``, ``cpu_s_iqr`` and ``repeat`` with it.
"""

from __future__ import annotations

import dataclasses
import json
import math
import time

import pandas as pd

from integrator_bench.harness.ranking import reach
from integrator_bench.harness.ranking.records import clean_records
from integrator_bench.harness.run.execution import now, sample_record
from integrator_bench.harness.run.limits import Limits
from integrator_bench.harness.run.resample import WARMUPS, Block, run_blocks

#: rounds per block (per process; pyperf takes 3 values per worker process): with the
#: matrix's own sample, one block gives a margin the fewest paired samples it needs
#: (:data:`~integrator_bench.harness.ranking.margin.MIN_PAIRED`)
ROUNDS = 4
#: the most contenders' rounds a record gets
MAX_ROUNDS = 16
#: the share of the run's CPU the contenders may take in all (``ibench run``)
CPU_SHARE = 0.10


@dataclasses.dataclass(frozen=True)
class Contention:
    """How the contenders are settled (:func:`settle`).

    Attributes
    ----------
    targets : tuple of float
        The targets the answers are given at.
    measure : str
        The error they are measured in (``--error``).
    cpu_cap_s : float
        The CPU the blocks may use in all (module docstring).
    jobs : int
        Blocks at once.
    limits : Limits
        The memory cap of a block's process.
    deadline : float, optional
        A ``time.monotonic()`` value: no block starts that its predicted CPU
        would end past it (an advice's budget).
    """

    targets: tuple = reach.TARGETS
    measure: str = reach.DEFAULT_ERROR
    cpu_cap_s: float = math.inf
    jobs: int = 1
    limits: Limits = Limits()
    deadline: float | None = None


@dataclasses.dataclass
class Settled:
    """What :func:`settle` did: the records (the run's, those timed again replaced),
    the contests it opened and how many it left open, its blocks, the records
    timed again, the CPU its processes used and why it stopped."""

    records: pd.DataFrame
    contests: int = 0
    left_open: int = 0
    blocks: int = 0
    retimed: int = 0
    cpu_s: float = 0.0
    stopped: str = "all decided"

    def line(self) -> str:
        """One line for the run's summary."""
        if not self.contests:
            return "contenders: every answer clear of its runner-up; nothing timed again"
        return (f"contenders: {self.contests} answer{'s' * (self.contests != 1)} timed again "
                f"({self.retimed} records, {self.blocks} blocks, {self.cpu_s:.1f} s CPU); "
                f"{self.stopped}" + (f", {self.left_open} open" if self.left_open else ""))


def open_contests(records: pd.DataFrame, targets=reach.TARGETS,
                  measure: str = reach.DEFAULT_ERROR) -> dict:
    """``(problem, params) -> case ids`` to time again: per problem and parameter
    set, the records the open contests' lines (the cheapest and the contenders
    not yet settled) read their crossings off, over ``targets``.

    ``records`` are cleaned (:func:`~integrator_bench.harness.ranking.records.clean_records`).
    """
    out = {}
    for key, rows in records.groupby(["problem", "params"], sort=True):
        table = reach.target_table(rows, tuple(targets), measure)
        ids = set()
        for target in targets:
            name = reach.tag(target)
            found = reach.contest(table, name)
            if found is None:
                continue
            open_ = [i for i, m in found.margins.items() if not m.settled]
            if open_:
                for i in [found.top, *open_]:
                    ids.update(table[f"cases_{name}"].iloc[i])
        if ids:
            out[key] = ids
    return out


def settle(records: pd.DataFrame, cases, accept=None, how: Contention = Contention(),
           log=None) -> Settled:
    """Time the contenders of ``records`` again until their margins are decided.

    Parameters
    ----------
    records : pandas.DataFrame
        A run's records (every field).
    cases : iterable of Case
        The run's cases (those of the records timed again are looked up by id).
    accept : callable, optional
        Called with each record timed again, a new dict (the store's ``add``).
    how : Contention
        The targets, error, CPU cap, processes and deadline.
    log : callable, optional
        Progress lines.
    """
    targets, measure, jobs = how.targets, how.measure, how.jobs
    by_id = {c.case_id: c for c in cases}
    rows = {r["case_id"]: r for r in records.to_dict("records")}   # as stored, nulls NaN
    done = Settled(records)
    state = {"spent": 0.0, "planned": 0.0, "open": {}, "retimed": set(), "capped": False}

    def block_of(key, ids):
        """The next block of the contest ``key`` (None: none left, or over the cap)."""
        ids = sorted(i for i in ids if i in by_id and _rounds(rows[i]) < MAX_ROUNDS)
        if not ids:
            return None
        rounds = min(ROUNDS, MAX_ROUNDS - max(_rounds(rows[i]) for i in ids))
        cost = sum(float(rows[i]["cpu_s"]) for i in ids) * (rounds + WARMUPS)
        left = math.inf if how.deadline is None else how.deadline - time.monotonic()
        if state["spent"] + state["planned"] + cost > how.cpu_cap_s or \
                cost > left * max(jobs, 1):
            state["capped"] = True
            return None
        state["planned"] += cost
        return Block(tuple(by_id[i] for i in ids), rounds, cost)

    def then(block, got, cpu_s):
        """A block ended: its samples join the records; its contest's next block."""
        state["spent"] += cpu_s
        state["planned"] -= block.cpu_s
        done.blocks += 1
        key = (block.cases[0].problem, block.cases[0].params_json)
        if not isinstance(got, dict):
            if log:
                log(f"contenders: {block.cases[0].problem}: {got}")
            state["open"].pop(key, None)
            return []
        for case_id, new in got.items():
            if new:
                rows[case_id] = _extended(rows[case_id], new)
                state["retimed"].add(case_id)
                if accept:
                    accept(dict(rows[case_id]))
        mine = [r for r in rows.values() if (r["problem"], r["params"]) == key]
        still = open_contests(clean_records(pd.DataFrame(mine, columns=records.columns)),
                              targets, measure)
        state["open"].pop(key, None)
        state["open"].update(still)
        nxt = block_of(key, still[key]) if key in still else None
        return [nxt] if nxt is not None else []

    first = open_contests(clean_records(records), targets, measure)
    state["open"] = dict(first)
    blocks = sorted(filter(None, (block_of(k, ids) for k, ids in first.items())),
                    key=lambda b: b.cpu_s)
    if blocks and log:
        log(f"contenders: timing {sum(len(b.cases) for b in blocks)} records of "
            f"{len(blocks)} answers again, {ROUNDS} rounds at a time")
    run_blocks(blocks, how.limits, jobs, then)
    done.contests, done.cpu_s = len(first), state["spent"]
    done.retimed, done.left_open = len(state["retimed"]), len(state["open"])
    if state["open"]:
        done.stopped = (f"CPU cap {how.cpu_cap_s:.1f} s reached" if state["capped"]
                        else f"{MAX_ROUNDS} rounds reached")
    done.records = _replaced(records, rows)
    return done


def _rounds(row: dict) -> int:
    """How many contenders' rounds a record has (``contended``; null: none)."""
    value = row.get("contended")
    return 0 if value is None or pd.isna(value) else int(value)


def _extended(row: dict, new: list) -> dict:
    """A record timed again: its samples and their figures with ``new`` added."""
    old = json.loads(row["cpu_samples"]) if isinstance(row.get("cpu_samples"), str) \
        else [float(row["cpu_s"])]
    cpus = old + [float(c) for c in new]
    timing = sample_record(cpus, [math.nan])
    timing.pop("wall_s")          # the wall of the matrix's solves stays as it was
    out = {k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in row.items()}
    out.update(timing, contended=_rounds(row) + len(new), created=now())
    return out


def _replaced(records: pd.DataFrame, rows: dict) -> pd.DataFrame:
    """``records`` with each record timed again replaced by its new version."""
    out = records.copy()
    for i, case_id in zip(out.index, out["case_id"]):
        new = rows.get(case_id)
        if new is not None and new.get("contended"):
            for field in ("cpu_s", "cpu_s_min", "cpu_s_iqr", "repeat", "cpu_samples",
                          "contended", "created"):
                out.at[i, field] = new[field]
    return out



