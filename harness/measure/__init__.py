"""Measurement: what a solution is worth and what it cost.

- :mod:`.metrics`: errors against the reference (final, largest and root-mean-square
  over the output times, mixed and relative), events matched, constraint drift;
- :mod:`.counting`: counting every call of the model, whatever the integrator reports;
- :mod:`.references`: the verified reference solutions (two independent methods,
  computed within a budget, cached and checked);
- :mod:`.stiffness`: the Jacobian's spectrum along the reference.

May import: :mod:`integrator_bench.harness.matrix`, ``errors``, ``paths``, ``version``,
``problems/`` and ``integrators/``.
"""
