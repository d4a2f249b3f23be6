"""A problem plugin installed for a test as a distribution is: a module and a
``.dist-info`` folder with its entry points, in a folder the test puts on
``PYTHONPATH`` of the commands it runs (tests of faulty models and builds)."""

from __future__ import annotations

from pathlib import Path

#: the source of ``Decay``, ``x' = -x`` on [0, 1] with its reference's error measured on
#: ``x``: what a faulty test problem derives from (its ``rhs`` calls ``self.fault(y)``
#: past the start when it defines one)
DECAY = '''
import numpy as np
from integrator_bench.problems.base import Problem


class Decay(Problem):
    description = "x' = -x (a test plugin's faulty problem)"
    source = "tests/plugin_dist.py"
    components = ("x",)
    t_span = (0.0, 1.0)
    parameters = ()
    benchmark_parameters = ({},)
    error_components = ("x",)
    atol_scale = 1.0

    def initial_state(self):
        return np.array([1.0])

    def rhs(self, t, y):
        if t > 0.0 and hasattr(self, "fault"):
            return self.fault(y)
        return -y

    def jac(self, t, y):
        return -np.eye(1)
'''


def install(root: Path, module: str, source: str, problems: dict) -> Path:
    """Write ``module`` (``DECAY`` then ``source``) and the distribution
    ``ibench-<module>`` registering ``problems`` (entry-point name -> class name of
    ``module``) into ``root``; return ``root``."""
    (root / f"{module}.py").write_text(DECAY + source)
    info = root / f"ibench_{module}-0.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(
        f"Metadata-Version: 2.1\nName: ibench-{module.replace('_', '-')}\nVersion: 0.0\n")
    (info / "entry_points.txt").write_text("[integrator_bench.problems]\n" + "".join(
        f"{name} = {module}:{cls}\n" for name, cls in problems.items()))
    return root
