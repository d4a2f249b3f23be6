"""The cost a ranking ranks by: the CPU of the code, or the work of the method.

``ibench report --cost cpu`` (the default) ranks every figure, table, answer and
profile by ``cpu_s``, what a code costs in this Python stack; ``--cost work``
ranks them by ``work``, the CPU seconds the same counted evaluations take at the
problem's unit costs (:mod:`~integrator_bench.harness.measure.unit_costs`): what
the method would cost with no overhead of its code's own, the figure for a
reader who will run the method in a compiled simulator. Its functions take
records with every field
(:func:`~integrator_bench.harness.ranking.records.clean_records`).
:func:`by_cost` puts the chosen figure in the ``cpu_s`` column the ranking
arithmetic reads (:mod:`~integrator_bench.harness.ranking.reach`), so one
arithmetic serves both;
a record without ``work`` (a store of older code, an FMU, a case whose counted
solve did not end) has none to rank by and is left out under ``work``, and
every page says how many (:func:`without_work`). The work has no measured
spread, so no two lines tie under it.

:func:`overhead_table` is each code's overhead factor per problem, the median
over its ``ok`` cases of ``overhead = cpu_s / work``.
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd

from integrator_bench.harness.ranking.margin import MIN_PAIRED

#: the costs a report or an advice can rank by, with what they are in words
COSTS = {
    "cpu": "CPU seconds of the solve (cpu_s, the median of its timed solves): what the code "
           "costs in this Python stack",
    "work": "the method's work (work: its counted evaluations, factorizations and solves "
            "times the problem's unit costs measured on this machine): what the method costs "
            "with no overhead of its code's own, the CPU it would take in compiled code",
}
DEFAULT_COST = "cpu"
#: each cost in a few words, for a heading
SHORT = {"cpu": "the CPU of the solve here (cpu_s)",
         "work": "the method's work (its counted evaluations times the problem's unit costs)"}


def check_cost(cost: str) -> str:
    """``cost`` when it is one of :data:`COSTS`, else ValueError naming the choices."""
    if cost not in COSTS:
        raise ValueError(f"--cost {cost!r} is not a cost; valid: {', '.join(COSTS)}")
    return cost


def by_cost(records: pd.DataFrame, cost: str = DEFAULT_COST) -> pd.DataFrame:
    """``records`` ranked by ``cost``: as they are for ``cpu``; for ``work`` a copy
    with ``cpu_s`` and ``cpu_s_min`` the ``work`` (NaN where there is none: not
    ranked), ``cpu_s_iqr`` NaN (the work has no measured spread) and
    ``cpu_samples`` the work itself, :data:`~.margin.MIN_PAIRED` times: counted,
    not timed, it is the same at every solve, so a margin in work is exact."""
    check_cost(cost)
    if cost == "cpu" or records is None or not len(records):
        return records
    work = pd.to_numeric(records["work"], errors="coerce").astype(float)
    exact = [json.dumps([w] * MIN_PAIRED) if np.isfinite(w) and w > 0 else None for w in work]
    return records.assign(cpu_s=work, cpu_s_min=work, cpu_s_iqr=np.nan, cpu_samples=exact)


def without_work(records: pd.DataFrame) -> int:
    """How many ``ok`` records have no ``work`` (not ranked under ``--cost work``)."""
    if records is None or not len(records):
        return 0
    ok = records[records["status"] == "ok"]
    return int(pd.to_numeric(ok["work"], errors="coerce").isna().sum())


def overhead_table(records: pd.DataFrame) -> pd.DataFrame:
    """Each code's overhead factor on each problem: the median over its ``ok``
    records of ``overhead`` (``cpu_s / work``), with their number.

    Returns
    -------
    pandas.DataFrame
        Columns ``problem``, ``params``, ``label`` (the line's integrator with its
        settings), ``overhead`` and ``cases``, sorted by problem, params and
        overhead; empty without an ``ok`` record with one.
    """
    columns = ["problem", "params", "label", "overhead", "cases"]
    if records is None or not len(records):
        return pd.DataFrame(columns=columns)
    ok = records.loc[records["status"] == "ok", ["problem", "params", "label", "overhead"]]
    ok["overhead"] = pd.to_numeric(ok["overhead"], errors="coerce")
    ok = ok[ok["overhead"].notna()]
    if ok.empty:
        return pd.DataFrame(columns=columns)
    table = (ok.groupby(["problem", "params", "label"])["overhead"]
             .agg(overhead="median", cases="size").reset_index())
    return table.sort_values(["problem", "params", "overhead"], kind="stable",
                             ignore_index=True)[columns]
