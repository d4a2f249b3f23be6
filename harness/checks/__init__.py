"""Checks of the integrators and the problems themselves.

- :mod:`.verify`: observed order, stability intervals and declared properties
  (``ibench verify``);
- :mod:`.verify_problems`: the problems' own checks (energy, constraints);
- :mod:`.method_checks`: the checks that one method passes, shared by verify;
- :mod:`.conformance`: ``ibench check-plugin``, the rules a plugin must keep.

May import: :mod:`integrator_bench.harness.matrix`, :mod:`integrator_bench.harness.measure`,
:mod:`integrator_bench.harness.run`, ``errors``, ``paths``, ``version``, ``problems/``
and ``integrators/``.
"""
