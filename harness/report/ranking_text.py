"""The ranking as the report writes it: the target table's cells and caption,
and what a page ranks by.

The arithmetic is :mod:`integrator_bench.harness.ranking` (the crossings of
:mod:`~integrator_bench.harness.ranking.reach`, the costs of
:mod:`~integrator_bench.harness.ranking.cost`); here are only its words:
:func:`markdown_rows` and :func:`caption` of a
:func:`~integrator_bench.harness.ranking.reach.target_table`, each cost's
:data:`WORD` and :data:`AXIS`, and :func:`cost_text`.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from integrator_bench.harness.ranking.cost import COSTS, DEFAULT_COST, check_cost, without_work
from integrator_bench.harness.ranking.reach import (
    COUNTS, DEFAULT_ERROR, TARGETS, cpu_cell, measure_text, tag, tol_cell)

#: each cost's unit in a figure's value or an answer ("0.0021 s CPU", "0.0019 s work")
WORD = {"cpu": "CPU", "work": "work"}
#: each cost's axis in the figures
AXIS = {"cpu": "CPU time of the solve [s]",
        "work": "work of the method: evaluations x unit costs [s]"}


def cost_text(records: pd.DataFrame, cost: str = DEFAULT_COST) -> str:
    """What a page ranks by, in words, with the ``ok`` records left out under
    ``work`` for want of one."""
    text = f"Ranked by {cost}: {COSTS[check_cost(cost)]}."
    if cost == "work":
        text += (" Wherever a figure, table or profile below says CPU, read this work, in "
                 "seconds.")
        missing = without_work(records)
        if missing:
            text += (f" {missing} ok record{'s' * (missing != 1)} without work (a store of "
                     "older code, an FMU) are not ranked.")
    else:
        text += " ibench report --cost work ranks by the method's work instead."
    column = "work" if cost == "work" else "cpu_s"
    values = pd.to_numeric(records.loc[records["status"] == "ok", column], errors="coerce")
    infinite = int(np.isinf(values.to_numpy(dtype=float)).sum())
    if infinite:   # a damaged or edited store: shown as it is, in no answer or figure
        text += (f" {infinite} ok record{'s' * (infinite != 1)} with an infinite {column} "
                 "(a damaged or edited store) are shown as such in the tables and not ranked.")
    return text


def markdown_rows(table: pd.DataFrame, targets=TARGETS) -> tuple[list[str], list[list[str]]]:
    """Header and string cells of
    :func:`~integrator_bench.harness.ranking.reach.target_table`'s output, for Markdown or HTML."""
    header = ["integrator", "formulation"]
    for t in targets:
        header += [f"CPU [s] to {tag(t)}", f"at (to {tag(t)})", "nsteps", "nfev", "njev", "nlu"]
    header += ["least error"]
    body = []
    for r in table.to_dict("records"):
        fixed = " (fixed h)" if r["mode"] == "h" else ""
        cells = [str(r["label"]), f"{r['formulation']}{fixed}"]
        for t in targets:
            name = tag(t)
            cells.append(cpu_cell(r[f"cpu_{name}"], r[f"how_{name}"], r[f"tie_{name}"]))
            cells.append(tol_cell(r[f"tol_{name}"], r["mode"]))
            cells += ["–" if r[f"{n}_{name}"] is None or pd.isna(r[f"{n}_{name}"])
                      else str(int(r[f"{n}_{name}"])) for n in COUNTS]
        cells.append("–" if pd.isna(r["best_err"]) else f"{r['best_err']:.1e}")
        body.append(cells)
    return header, body


def caption(measure_words: str) -> str:
    """The target table's caption for the measure ``measure_words``
    (:func:`~integrator_bench.harness.ranking.reach.measure_text`)."""
    return (f"CPU seconds to reach a target error; the error is {measure_words}. Each line "
            "is its own Pareto front (a point another point of the line beats in both error "
            "and CPU is left out, so a tighter target never costs less): interpolated "
            "log-log between the two front points whose errors bracket the target; nsteps, "
            "nfev, njev, nlu and the tolerance at the crossing (at: rtol, or h) with the same "
            "weight. ≤: the line's cheapest point is already below the target (its CPU, an "
            "upper bound, never extrapolated), and the line is ranked by it here, in the "
            "answer and in the run's summary alike. tie: the line ties with the first: "
            "the 95 % interval of its margin over it (bootstrap over their paired timed "
            "solves; the median of the timed solves is the CPU) reaches 1. Least error: the "
            "line's least error. Records at the budget's edge (ok within 10 % of their "
            "budget) are no points. Sorted by "
            "CPU at the tightest target; the first row is the answer.")


CAPTION = caption(measure_text(DEFAULT_ERROR))
