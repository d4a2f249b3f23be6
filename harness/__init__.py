"""The harness joins problems and integrators, measures, stores and reports.

Its subpackages, each an ``__init__`` saying what lives there and what it may import:

- :mod:`.matrix`: what is run and kept: the registry, lines and problem specs, cases
  and presets, the record, the store, provenance, the source documents' rows;
- :mod:`.measure`: errors, counting the model's calls, references, stiffness;
- :mod:`.run`: the run engine: one case, isolation, the pool, scheduling, Dask;
- :mod:`.checks`: verification of integrators and problems, plugin conformance;
- :mod:`.ranking`: the error measures, the CPU to reach a target, margins and their
  intervals, the cheapest line or the tie, the costs, coverage: the arithmetic the
  report, the advice and the run's summary share;
- :mod:`.contend`: the contenders of an answer timed again until their margin is known;
- :mod:`.report`: ``ibench report``'s figures, tables and pages, from records alone;
- :mod:`.advise`: ``ibench advise``, the cheapest line to a target found by measurement;
- :mod:`.cli`: the ``ibench`` command line, a module per command.

Beside them, small modules every subpackage may use: :mod:`.errors` (the
exceptions), :mod:`.paths` (where data lives), :mod:`.version` (the code version),
:mod:`.forking` (forked processes, and the one parallel map), :mod:`.layout` (which
folder of the checkout installs as which package) and :mod:`.tables` (text and
markdown tables).

One BLAS thread per process unless the user chose otherwise: the matrix runs one
case per worker process, and nested threading only adds noise to CPU times.
"""

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
