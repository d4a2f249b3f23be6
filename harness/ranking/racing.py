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
times the lead's, and no cheaper point of it to interpolate from, is beyond tau
times the best at ``T``. A case whose line could still cross ``T`` between a point
under the bound and itself is therefore not raced (:meth:`Race.open_crossing`):
the answers, the profile shares up to tau and the Pareto fronts below tau times
the best are an exhaustive run's, up to the noise of the CPU measured near the
bound. At a target tighter than the race target lines may be missing.
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
        its problem and parameter set has reached the target, and for a case whose
        line's crossing of a target at or looser than the race's could still lie
        within tau of the lead (:meth:`open_crossing`)."""
        lead = self.leads.get((case.problem, case.params_json))
        if lead is None or self.open_crossing(case, self.tau * lead[0]):
            return None
        return {"race_target": self.target, "race_cpu_s": lead[0],
                "race_bound_s": self.tau * lead[0], "race_line": lead[1]}

    def open_crossing(self, case, bound: float) -> bool:
        """Whether ``case`` could decide a crossing within ``bound``: its line has
        points, none of them reaches the race target and none costs more than
        ``bound``. Its crossing of a target at or looser than the race's would then
        be interpolated between its dearest point so far (under the bound) and a
        tighter one, and may lie under the bound however much the tighter one
        costs: such a case runs to its budget. Cut safely: the first point of a line
        (its crossing, if any, at most its own CPU), a case past its line's
        crossing of the race target, and one of a line already dearer than the
        bound."""
        points = self.points.get((case.problem, case.params_json, case.line.label,
                                  case.formulation, case.mode))
        if not points:
            return False
        err, cpu = zip(*points)
        reached = math.isfinite(reach_line(err, cpu, self.target)["cpu_s"])
        return not reached and max(cpu) <= bound

    def raced(self, problem: str, params: str) -> bool:
        """Whether a line of ``problem`` and ``params`` (JSON) has reached the target."""
        return (problem, params) in self.leads
