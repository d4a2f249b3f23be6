"""The ranking: which line reaches a target error for the least cost, from records alone.

The arithmetic the report, the advice and the run's summary share, so that all three
give one answer:

- :mod:`.records`: the records a ranking reads: cleaned (the newest of each case),
  the advice's kept apart, each line named with its settings, the lines that ignore
  their tolerance;
- :mod:`.reach`: the error measures, a line's points and its Pareto front, the CPU
  to reach a target (the crossing), the contest of the lines within 2x of the
  cheapest, the target table and its cheapest line (winner or tie), the answer in
  words, and the one default target (:data:`~.reach.DEFAULT_TARGET`);
- :mod:`.margin`: a line's margin over the cheapest, its interval from the paired
  timed solves, and the verdict;
- :mod:`.cost`: what lines are ranked by (the CPU of the solve, or the method's work);
- :mod:`.coverage`: whether a store still has points on both sides of a target;
- :mod:`.racing`: a run's race: each problem's lead (the least CPU a line needed to
  reach the race target) and the bound it sets its other cases.

May import: :mod:`integrator_bench.harness.matrix`, :mod:`integrator_bench.harness.measure`,
``errors``, ``paths``, ``version``, ``problems/`` and ``integrators/``; never the run
engine, the contenders, the report or the advice: they all import it.
"""
