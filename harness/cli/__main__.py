"""``python -m integrator_bench.harness.cli``: the same as ``ibench``."""

import sys

from integrator_bench.harness.cli import main

sys.exit(main())
