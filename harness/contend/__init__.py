"""The contenders measured until their margin is known.

After a run's matrix (``ibench run``) and before an advice answers (``ibench
advise``), :func:`~.rounds.settle` takes the lines whose CPU to reach a target
is within :data:`~integrator_bench.harness.ranking.margin.BAND` of the
cheapest's and times the records their crossings are read off again, in rounds
that alternate between those lines in one process
(:mod:`integrator_bench.harness.run.resample`), until every margin's interval
is decided or a cap is reached; the new samples join the records, stored
anew, so the report, the summary and the advice read them alike.

May import: :mod:`integrator_bench.harness.matrix`,
:mod:`integrator_bench.harness.measure`, :mod:`integrator_bench.harness.run`,
:mod:`integrator_bench.harness.ranking`, the base modules, ``problems/`` and
``integrators/``; imported by the advice and the command line.
"""
