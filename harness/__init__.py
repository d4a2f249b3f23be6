"""The harness joins problems and integrators: cases, execution of one case,
isolation in a worker process, scheduling (runner, Dask), metrics, references,
store, report, verification and the ``ibench`` command line; its exceptions
are in :mod:`integrator_bench.harness.errors`.

One BLAS thread per process unless the user chose otherwise: the matrix runs one
case per worker process, and nested threading only adds noise to CPU times.
"""

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
