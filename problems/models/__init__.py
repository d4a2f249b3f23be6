"""The built-in problems: one module per model, each a :class:`~integrator_bench.problems.base.Problem`.

Each model is registered under the ``integrator_bench.problems`` entry-point group in
pyproject.toml, exactly as a plugin's problem is; nothing else finds it. A model
imports the machinery of :mod:`integrator_bench.problems` (``base``, ``system``,
``mechanical``, ``symbolic``, ``second_order``, ...) and, where one builds on another,
that model (``chain_bushing`` and ``cvt_chain`` on ``chain_drive``); never an
integrator or the harness. The machinery imports no model.
"""
