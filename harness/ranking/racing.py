"""Racing: the cases that cannot change an answer stopped at tau times the best.

Once some line of a problem and parameter set has reached the race target (the
run's ``--race-target``, by default :data:`~.reach.DEFAULT_TARGET`, the
tightest target the report ranks at), every case of that problem and set still
to run gets a budget of CPU of at most :data:`TAU` times the least CPU any line
needed to reach it (its *lead*). A line "reached" the target as the ranking
says it (:func:`~.reach.cpu_to_reach`: its ok records' points,
:func:`~.reach.record_point`, their Pareto front and its crossing,
:func:`~.reach.reach_line`, interpolated, or its first point's CPU as an upper
bound), computed from the records the run has so far, each learned as it arrives
(:meth:`Race.learn`). The run engine
(:class:`~integrator_bench.harness.run.schedule.Schedule`) asks
:meth:`Race.bound` for each case it hands out; a case stopped at its bound is
recorded ``dominated`` (reason ``race_bound``), and the tighter cases of its line
``dominated`` without running (reason ``after_dominated``): a tighter tolerance
takes more work. A dominated case is never an answer (it is no point of its
line), and the performance profiles count it beyond tau.

What stays exact (docs/full-run.md, "Racing"): at every target ``T`` at or
looser than the race target, the lead reaches ``T`` for at most its CPU to the
race target, so a line whose CPU to ``T`` needs a case that cost more than tau
times the lead's is beyond tau times the best at ``T``: the answers (the
cheapest line, within tau of the lead), the profile shares up to tau and the
Pareto fronts below tau times the best are those of an exhaustive run, but for a
line whose crossing at ``T`` interpolates between a point below the bound and a
dominated one (its crossing could lie below tau; the raced store counts it
beyond). At a target tighter than the race target lines may be missing.
"""

from __future__ import annotations

import math
from collections import defaultdict

from integrator_bench.harness.ranking.reach import (DEFAULT_ERROR, DEFAULT_TARGET, reach_line,
                                                    record_point)
from integrator_bench.harness.ranking.records import LINE

#: how many times the lead's CPU a case may take under racing (``--tau``): the
#: performance profiles show up to 10x, so a line beyond 16x changes none of them
TAU = 16.0


class Race:
    """The leads of a run's problems, learned from its records as they arrive.

    Parameters
    ----------
    target : float
        The race target, an error in ``measure``.
    tau : float
        A case's bound is ``tau`` times its problem's lead.
    measure : str
        The error the lines reach the target in (``ibench run --error``).
    """

    def __init__(self, target: float = DEFAULT_TARGET, tau: float = TAU,
                 measure: str = DEFAULT_ERROR):
        self.target, self.tau, self.measure = target, tau, measure
        self.points: dict = defaultdict(list)  # line -> its points, (error, cpu_s)
        self.leads: dict = {}                  # (problem, params) -> (cpu_s, line name)

    @property
    def policy(self) -> str:
        """The race's rules, stored with each dominated record (``skip_policy``):
        ``--resume`` takes a dominated case as done only under the same race."""
        return f"race: target {self.target:g} ({self.measure}), tau {self.tau:g}"

    def learn(self, record) -> None:
        """Take one record: an ``ok`` one may make its line the lead of its problem
        (its line's points, :func:`~.reach.record_point`, and their crossing of the
        target, :func:`~.reach.reach_line`, as the ranking finds them)."""
        point = record_point(record, self.measure)
        if point is None:
            return
        points = self.points[tuple(record.get(c) for c in LINE)]
        points.append(point)
        cpu = reach_line([p[0] for p in points], [p[1] for p in points], self.target)["cpu_s"]
        key = (record.get("problem"), record.get("params"))
        if math.isfinite(cpu) and cpu > 0 and (key not in self.leads or cpu < self.leads[key][0]):
            self.leads[key] = (cpu, f"{record.get('label')} ({record.get('formulation')})")

    def bound(self, case) -> dict | None:
        """The race fields of ``case`` (``race_target``, ``race_cpu_s``,
        ``race_bound_s``, ``race_line``: the record's), or None while no line of
        its problem and parameter set has reached the target."""
        lead = self.leads.get((case.problem, case.params_json))
        if lead is None:
            return None
        return {"race_target": self.target, "race_cpu_s": lead[0],
                "race_bound_s": self.tau * lead[0], "race_line": lead[1]}

    def raced(self, problem: str, params: str) -> bool:
        """Whether a line of ``problem`` and ``params`` (JSON) has reached the target."""
        return (problem, params) in self.leads
