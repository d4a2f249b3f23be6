"""The run engine's side of racing: a case handed out under its race bound, and
its record once it comes back.

The race itself (which line leads each problem, and the bound it sets) is the
ranking's (:class:`integrator_bench.harness.ranking.racing.Race`), handed to the
run in its :class:`~integrator_bench.harness.run.context.RunContext`; the
:class:`~integrator_bench.harness.run.schedule.Schedule` calls these functions.
"""

from __future__ import annotations

import dataclasses

from integrator_bench.harness.matrix.record import (AFTER_DOMINATED, RACE_BOUND, TIMEOUT,
                                                    CaseStatus)
from integrator_bench.harness.run.execution import base_record, budget_edge, finish

#: how many lines of each problem and parameter set, the predicted cheapest, run
#: before the others while it has no lead (the race's scouts)
SCOUTS = 3


def policy_of(skip_policy: str | None, race) -> str | None:
    """The run's policy, stored with its skipped and dominated records: the skip
    rules (None: ``--no-skip``) and the race's (none: ``--exhaustive``)."""
    parts = [p for p in (skip_policy, getattr(race, "policy", None)) if p]
    return "; ".join(parts) or None


def under_bound(case, race, budget_s: float | None):
    """``(case to hand out, its race fields or None)``: ``case`` with a budget of its
    race bound when the race gives one below ``budget_s`` (the run's budget)."""
    fields = race.bound(case) if race is not None else None
    if fields is None or (budget_s is not None and fields["race_bound_s"] >= budget_s):
        return case, None
    return dataclasses.replace(case, budget_s=fields["race_bound_s"]), fields


def settle(record, fields: dict, budget_s: float | None, policy: str | None):
    """The record of a case run under its race bound (``fields``): past the bound
    (a ``timeout``) it is ``dominated``, reason ``race_bound``; its ``budget_s`` is
    the run's (``budget_s``) and its ``budget_edge`` taken against it, as an
    exhaustive run's, so that a raced ``ok`` record ranks as it would there."""
    record.update(fields)
    if record.get("status") == TIMEOUT:
        lead = (f"{fields['race_bound_s']:.3g} s of CPU: the race bound, tau times the "
                f"{fields['race_cpu_s']:.3g} s {fields['race_line']} needed to reach "
                f"{fields['race_target']:g}")
        finish(record, CaseStatus.DOMINATED,
               f"stopped at {lead} ({record.get('message') or 'timeout'})", RACE_BOUND)
        record["skip_policy"] = policy
    record["budget_s"] = budget_s
    record["budget_edge"] = budget_edge(record)
    return record


def dominated_record(case, record: dict, policy: str | None) -> dict:
    """The ``dominated`` record, not run, of a case tighter than ``record`` (its line's,
    stopped at its race bound), reason ``after_dominated``."""
    out = finish(base_record(case), CaseStatus.DOMINATED,
                 f"not run: {record.get('case_id')} of this line was stopped at its race "
                 f"bound ({record.get('race_bound_s'):.3g} s of CPU); a tighter tolerance "
                 f"takes more work", AFTER_DOMINATED)
    out.update({k: record.get(k) for k in ("race_target", "race_cpu_s", "race_bound_s",
                                           "race_line")},
               decided_by=record.get("case_id"), skip_policy=policy)
    return out


def scouts(lines: dict, predict) -> set:
    """The :data:`SCOUTS` lines of each problem and parameter set with the least
    predicted CPU (``predict(line) -> seconds``): those a race runs first, so
    that each problem has a lead early."""
    by_problem: dict = {}
    for key in lines:
        by_problem.setdefault(key.problem, []).append(key)
    out = set()
    for keys in by_problem.values():
        out.update(sorted(keys, key=predict)[:SCOUTS])
    return out
