"""What a raced store can say (harness/ranking/racing.py): which cases the race cut
and why, and for which targets the store is exact."""

from __future__ import annotations

import pandas as pd

from integrator_bench.harness.matrix.record import AFTER_DOMINATED, RACE_BOUND
from integrator_bench.harness.ranking import reach
from integrator_bench.harness.report.document import Block, Table


def race_block(records: pd.DataFrame, targets=()) -> Block | None:
    """The racing block of the status part: the ``dominated`` cases per problem and
    parameter set with the line and bound they were held against, the targets the
    store is exact at, and a warning for a target of ``targets`` tighter than the
    race's; None for a store with no dominated case."""
    cut = records[records["status"] == "dominated"]
    if cut.empty:
        return None
    race_targets = sorted(pd.to_numeric(cut["race_target"], errors="coerce").dropna().unique())
    loosest = max(race_targets) if race_targets else float("nan")
    tau = (pd.to_numeric(cut["race_bound_s"], errors="coerce")
           / pd.to_numeric(cut["race_cpu_s"], errors="coerce")).median()
    rows = []
    for (problem, params), group in cut.groupby(["problem", "params"], sort=True):
        stopped = int((group["reason"] == RACE_BOUND).sum())
        rows.append((problem, params, str(stopped),
                     str(int((group["reason"] == AFTER_DOMINATED).sum())),
                     ", ".join(sorted(set(group["race_line"].dropna()))),
                     f"{pd.to_numeric(group['race_bound_s'], errors='coerce').min():.3g}"))
    text = [f"{len(cut)} cases were cut by the race (status dominated): stopped at their "
            f"race bound, tau = {tau:.3g} times the least CPU a line of their problem needed "
            f"to reach the race target {', '.join(f'{t:g}' for t in race_targets)} "
            f"(reason {RACE_BOUND}), or not run after a looser case of their line was so "
            f"stopped (reason {AFTER_DOMINATED}). A dominated case is no answer and counts "
            f"beyond tau in the profiles.",
            f"The store is exact at every target at or looser than {loosest:g}: the answers, "
            f"the profile shares up to tau and the Pareto fronts below tau times the best "
            f"are an exhaustive run's, up to the noise of the CPU measured near the bound; "
            f"`ibench run --exhaustive` runs every case to its budget."]
    tighter = [t for t in targets if t < loosest]
    if tighter:
        text.append(f"The target {', '.join(reach.tag(t) for t in tighter)} is tighter than "
                    f"the race target {loosest:g}: lines may be missing from it (a case cut "
                    f"by the race could have reached it).")
    header = ["problem", "parameters", "stopped at the bound", "not run", "held against",
              "least bound (s)"]
    return Block(title="Cut by the race", text=text,
                 tables=[Table(header, rows, ("stopped at the bound", "not run",
                                              "least bound (s)"))])
