"""The asv suite of integrator-bench (asv's ``benchmark_dir``), and nothing else.

asv imports every module of this folder in its own environment, where the
project is installed from its wheel with the extra ``[assimulo]`` only
(``asv.conf.json``), possibly at an old commit. So a module here imports at
module level nothing that an optional extra provides (Assimulo, Dask, the
dashboard tools' websocket client): the standard library, ``asv_runner`` and the
core package at most (``cases.py``, with a fallback for the oldest layout); what
an extra provides is imported inside functions, and a combination the installed
commit cannot run raises NotImplementedError in ``setup``. ``tests/benchmarks/test_asv_suite.py`` imports every module here with the
optional extras hidden, and ``tests/benchmarks/test_asv_environment.py`` builds the project
in asv's own environment and discovers the suite.

- ``cases.py``: the suite generated from the registries (one class per problem);
- ``_snapshot.py``: the registries' names, the same axes in every environment;
- ``chain_scaling_asv.py`` and ``chain_pieces.py``: the chain drive's cost against
  its size (the pieces ``studies/chain_scaling.py`` also times).

Study scripts live in ``studies/``, the dashboard's publishing and checking
tools in ``tools/``. See the README's "Performance over commits" for the commands.
"""
