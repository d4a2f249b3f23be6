"""Problems: the physics, and nothing about solvers.

The machinery lives here, one module per concern: :mod:`.base` (the interface and
rules every problem keeps), :mod:`.system` (the forms handed to integrators),
:mod:`.mechanical` and :mod:`.symbolic` (a constrained mechanism from M, f and g),
:mod:`.formulations` (every formulation generated from it) with :mod:`.partitioning`,
:mod:`.tangent` and :mod:`.linalg`, :mod:`.second_order` (an unconstrained
mechanical model), :mod:`.fmu` (an FMU file as a problem) and :mod:`.fmu_build`
(the project's own FMUs, from ``fmu_sources/``). The built-in models are in
:mod:`.models`, one module each, registered through the ``integrator_bench.problems``
entry-point group in pyproject.toml exactly as plugins are.

A module here imports numpy, scipy, sympy, fmpy and other modules of this package,
never :mod:`integrator_bench.integrators` or :mod:`integrator_bench.harness`; the
machinery never imports :mod:`.models`.
"""
