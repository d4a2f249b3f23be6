"""Problem registry: one module per problem; the interface is in :mod:`integrator_bench.problems.base`.

Problems know physics and nothing about solvers. Built-in problems are
registered through the ``integrator_bench.problems`` entry-point group in
pyproject.toml, exactly as plugins are.
"""
