"""The run engine: from cases to records in the store.

- :mod:`.execution`: one case in one process: the counted solve, the timed solve, the
  record;
- :mod:`.isolation`: a case in a worker process with its time and memory limits;
- :mod:`.runner`: :class:`~.runner.Session`, batches of cases run in one
  :class:`~.context.RunContext`, each record committed as it arrives;
- :mod:`.loop`: the one scheduling loop, :func:`~.loop.drive`, over either pool:
  :mod:`.local_pool` (forked workers of this process) or :mod:`.dask_backend`;
- :mod:`.referencing`: every problem of a batch given its reference before its cases run;
- :mod:`.schedule`: which cases to run first and which evidence rules out;
- :mod:`.raced`: a case handed out under its race bound, its record settled (the race
  itself is the ranking's, handed in by the command);
- :mod:`.plan` and :mod:`.progress`: a run's predicted cost before it starts, its time
  left while it runs;
- :mod:`.shipping`: what travels with a case to a Dask worker;
- :mod:`.streams`: a C library's output kept off the user's terminal and ``--json``;
- :mod:`.resample`: cases timed again in alternating rounds, a forked process per block
  (the contenders' rounds, :mod:`integrator_bench.harness.contend`).

May import: :mod:`integrator_bench.harness.matrix`, :mod:`integrator_bench.harness.measure`,
``errors``, ``paths``, ``version``, ``problems/`` and ``integrators/``.
"""
