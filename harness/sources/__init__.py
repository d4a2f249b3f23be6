"""The source documents ("seed 000" ... "seed 004", docs/sources.md) beside the project's runs.

A room of their own, above the ranking and the report, so that the core that every
run uses knows no seed:

- :mod:`.runs`: the runs that stand for the seeds' stated ratios and criterion (seed
  000's CPU ratios, seed 001's stiffness criterion), each a :class:`~.runs.Ladder`
  of tolerances or steps;
- :mod:`.numbers`: the seeds' published tables transcribed row by row, the closest
  configuration of each, the verdicts and the one rule that gives them, and the
  ``seeds`` preset's cases (:func:`~.numbers.preset_cases`, handed to
  :func:`integrator_bench.harness.matrix.cases.expand` by ``ibench run``:
  :func:`~.numbers.listed_cases`);
- :mod:`.claims`: the seeds' claims side by side, each judged from its parts;
- :mod:`.page`: the report's part "The sources, number by number" and
  ``docs/seed-numbers.md`` (its document with the records it was made from), which
  ``ibench report`` hands the report (:func:`~.page.appendix`).

May import: :mod:`integrator_bench.harness.matrix`, :mod:`integrator_bench.harness.measure`,
:mod:`integrator_bench.harness.ranking`, :mod:`integrator_bench.harness.report` (the
page's types and renderer), ``errors``, ``paths``, ``version``, ``forking``,
``problems/`` and ``integrators/``; never the run engine. Imported by the command line
only (``ibench report`` and ``ibench run``'s ``seeds`` preset).
"""
