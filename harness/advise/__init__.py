"""``ibench advise``: the cheapest integrator, settings, formulation and rtol to a
target error on one model, found by measurement within a budget and certified.

What lives here:

* :mod:`.candidates`: the lines worth trying (every registered adaptive
  integrator, with the seeds' setting variants, on every formulation the model
  offers) and those the evidence rules out before anything runs, each with why;
* :mod:`.search`: the budgeted successive-halving search that runs the
  candidates loose to tight through the run engine (every round a batch of the
  advice's one :class:`integrator_bench.harness.run.runner.Session`: every run a
  record in the store, reused when the code version matches) and calibrates
  each surviving line's rtol to the target;
* :mod:`.certificate`: the evidence for the answer (the reference's
  verification, the ranking and the verdict by the report's rule, the winner's
  and runner-up's measured runs and margin, robustness on
  perturbed parameter sets, the best of each family, what the search cost and
  what a user needs to reproduce the error outside the harness);
* :mod:`.answer`: the answer as typed values (:class:`~.answer.Advice`), its
  ``to_dict`` the ``--json`` object;
* :mod:`.page`: the terminal table and the offline HTML page with the
  work-precision diagram.

It may import the harness's matrix and run modules (cases, runner, references,
stiffness, schedule, store, record), the ranking
(:mod:`integrator_bench.harness.ranking`: the crossing arithmetic, the verdict, the
costs, the records' names), the contenders' rounds
(:mod:`integrator_bench.harness.contend`: the search's contenders timed again
before the advice answers) and the integrators' and problems' declarations, never
the report; nothing in the rest of the harness imports it except the command line.
"""
