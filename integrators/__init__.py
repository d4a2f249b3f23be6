"""Integrator registry: one module per backend or method family.

The interface is in :mod:`integrator_bench.integrators.base`. Integrators know numerics and
nothing about particular problems. Built-ins are registered through the
``integrator_bench.integrators`` entry-point group in pyproject.toml, exactly as
plugins are.
"""
