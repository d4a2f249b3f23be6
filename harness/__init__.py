"""The harness joins problems and integrators: cases, runner, metrics,
references, store, report and the ``ibench`` command line.

One BLAS thread per process unless the user chose otherwise: the matrix runs one
case per worker process, and nested threading only adds noise to CPU times.
"""

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
