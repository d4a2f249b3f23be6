"""The end of ``ibench run``: a line per problem and parameter set, the totals,
the coverage line and where the report goes."""

from __future__ import annotations

import json
import textwrap
from pathlib import Path

from integrator_bench.harness.matrix import registry
from integrator_bench.problems.base import format_label


SUMMARY_COLUMNS = 100  # the widest line of the end-of-run summary
_LABEL_COLUMNS = 26    # the summary's problem column


def summary(df, store: Path | None = None, wall_s: float | None = None,
            cpu_s: float | None = None, error: str | None = None,
            contenders: str | None = None) -> str:
    """The end of ``ibench run``: a line per problem and parameter set, at most
    :data:`SUMMARY_COLUMNS` wide.

    Each line gives the problem (with the parameters that differ from their
    defaults), the counts of ``ok``, ``failed`` and ``timeout`` cases (and of
    ``untimed``, ``error``, ``crashed`` and ``skipped`` ones when there are
    any) and the line (integrator/formulation) that reached an error of
    the default target (:data:`~integrator_bench.harness.ranking.reach.DEFAULT_TARGET`,
    in ``error``, a key of :data:`~integrator_bench.harness.ranking.reach.ERRORS`,
    default theirs) on the least CPU: the report's answer line, from the same table
    (:func:`~integrator_bench.harness.ranking.reach.cheapest` of
    :func:`~integrator_bench.harness.ranking.reach.target_table`), ``≤`` marking
    an upper bound as the table does, the tolerance at the crossing, and the
    winner's margin with its interval, or the tie
    (:func:`~integrator_bench.harness.ranking.reach.answer_text`), on a line of
    its own below when it does not fit. Then a
    line for each adaptive line whose ok records are the same at every tolerance
    (:func:`integrator_bench.harness.ranking.records.unresponsive`: "does not
    respond to rtol"), the run's totals (:func:`totals`; with ``wall_s`` and ``cpu_s``, the run's
    wall time and its processes' CPU; the cases at the budget's edge), ``contenders``
    (what timing the contenders again did) and
    the coverage line (:func:`integrator_bench.harness.ranking.coverage.summary_line`).
    With ``store``, the last lines name the store, the command that makes the
    report and where it goes (the only lines that may be longer: by their paths).
    """
    from integrator_bench.harness.matrix.store import DEFAULT_STORE
    from integrator_bench.harness.ranking import reach
    from integrator_bench.harness.ranking.coverage import summary_line
    from integrator_bench.harness.ranking.records import clean_records, unresponsive

    error = error or reach.DEFAULT_ERROR
    lines = [f"{'problem':<{_LABEL_COLUMNS}} cases by status; cheapest integrator/formulation "
             f"to {reach.DEFAULT_TARGET:.0e} ({error}), CPU s".replace("e-0", "e-")]
    df = clean_records(df)
    for (name, params), rows in df.groupby(["problem", "params"], sort=True):
        counts = rows["status"].value_counts()
        tally = " ".join(f"{counts.get(s, 0):>3} {s}" for s in ("ok", "failed", "timeout"))
        tally += "".join(f" {counts[s]} {s}" for s in ("untimed", "error", "crashed", "skipped")
                         if counts.get(s))
        top = reach.cheapest(reach.target_table(rows, (reach.DEFAULT_TARGET,), error),
                             reach.DEFAULT_TARGET)
        label = fit_label(_short_label(name, json.loads(params)), _LABEL_COLUMNS, len(name))
        line = f"{label:<{_LABEL_COLUMNS}} {tally}  "
        if top is None:
            lines.append(line + "not reached")
            continue
        head, why, same = reach.answer_parts(top, _slashed)
        cpu = reach.cpu_cell(top["cpu_s"], top["how"])
        at = reach.tol_cell(top["tol"], top["mode"]).replace(" ", "=")
        whole = f"{line}{head} {cpu} {at} ({why}){same}"
        if len(whole) <= SUMMARY_COLUMNS:
            lines.append(whole)
            continue
        # too long: the line and its CPU on the problem's line (the tolerance where it
        # fits; a tie's lines below), the answer in words below, wrapped between words
        fits = [f for f in (f"{line}{head} {cpu} {at}", f"{line}{head} {cpu}")
                if len(f) <= SUMMARY_COLUMNS and not head.startswith("tie: ")]
        lines.append(fits[0] if fits else f"{line}{cpu} {at}"[:SUMMARY_COLUMNS])
        rest = f"({why}){same}" if fits else f"{head} ({why}){same}"
        lines += textwrap.wrap(rest, SUMMARY_COLUMNS, initial_indent=" " * (_LABEL_COLUMNS + 2),
                               subsequent_indent=" " * (_LABEL_COLUMNS + 4),
                               break_on_hyphens=False)
    lines += [f"{_short_label(line['problem'], json.loads(line['params']))}: "
              f"{line['label']}/{line['formulation']} does not respond to rtol (the same "
              f"counts and errors at {', '.join(f'{r:g}' for r in line['rtols'])})"
              [:SUMMARY_COLUMNS] for line in unresponsive(df)]
    lines += [*totals(df, wall_s, cpu_s), *([contenders] if contenders else []),
              summary_line(df, measure=error)]
    if store is not None:
        command = "ibench report" + ("" if store == DEFAULT_STORE else f" --store {store}")
        unsupported = int((df["status"] == "unsupported").sum())
        lines += [f"{len(df)} cases stored in {store}"
                  + (f" ({unsupported} unsupported, not counted above)" if unsupported else ""),
                  f"the report: {command}",
                  f"  (writes {Path(store).resolve().parent / 'report' / 'index.html'})"]
    return "\n".join(lines)


def _slashed(row) -> str:
    """``label/formulation``: how the summary names a line."""
    return f"{row['label']}/{row['formulation']}"


def fit_label(label: str, width: int, keep: int = 0) -> str:
    """``label`` in at most ``width`` characters: a longer one keeps its start (at
    least ``keep`` characters, the problem's name, as room allows) and its end,
    where parameter sets and files differ (``fmu:path…BouncingBall3.fmu``), around
    an ellipsis."""
    if len(label) <= width:
        return label
    head = min(max((width - 1) // 3, keep), width - 9)
    return label[:head] + "…" + label[len(label) - (width - 1 - head):]


def totals(df, wall_s: float | None = None, cpu_s: float | None = None) -> list[str]:
    """Two or three lines: wall time, CPU (the processes' with ``cpu_s``, and the
    solves' own, the sum of ``cpu_s``) and the skipped cases' share of those that
    could run (all but ``unsupported``), with how many each reason skipped
    (:data:`~integrator_bench.harness.run.schedule.SKIP_REASONS`); the counts by
    status; the cases at the budget's edge (``budget_edge``, and the timeouts),
    when there are any."""
    import pandas as pd

    from integrator_bench.harness.matrix.record import BUDGET_EDGE, STATUSES

    counts = df["status"].value_counts()
    runnable = len(df) - int(counts.get("unsupported", 0))
    skipped = int(counts.get("skipped", 0))
    solves = pd.to_numeric(df["cpu_s"], errors="coerce").sum()
    parts = ([f"wall {wall_s:.0f} s"] if wall_s is not None else [])
    parts.append(f"CPU {cpu_s:.0f} s (solves {solves:.0f} s)" if cpu_s is not None
                 else f"CPU of the solves {solves:.0f} s")
    why = (df.loc[df["status"] == "skipped", "reason"].value_counts() if "reason" in df
           else pd.Series(dtype=int))
    reasons = f" ({', '.join(f'{n} {r}' for r, n in why.items())})" if len(why) else ""
    parts.append(f"skipped {100 * skipped / runnable:.0f} % of {runnable} runnable{reasons}"
                 if runnable else "nothing runnable")
    edge = int((pd.to_numeric(df["budget_edge"], errors="coerce") == 1).sum())
    timeouts = int(counts.get("timeout", 0))
    at_edge = ([f"budget's edge: {edge} ok within {BUDGET_EDGE * 100:.0f} % of it, {timeouts} "
                "timeouts: may flip in a rerun; no answer rests on one"]
               if edge + timeouts else [])
    return ["; ".join(parts),
            "cases: " + ", ".join(f"{counts[s]} {s}" for s in STATUSES if counts.get(s)),
            *at_edge]


def _short_label(name: str, params: dict) -> str:
    """``name:key=value,...`` with the parameters that differ from the problem's
    defaults (all of them for a problem the registry does not list)."""
    cls = registry.problems().get(name)
    defaults = {p.name: p.default for p in getattr(cls, "parameters", ())}
    return format_label(name, {k: v for k, v in params.items()
                               if k not in defaults or v != defaults[k]})
