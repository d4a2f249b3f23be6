"""studies/advise_quality.py: the matrix runs, and is read on, the advice's parameter set."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "studies"))
import advise_quality  # noqa: E402

from integrator_bench.harness.matrix.cases import parse_problem_spec  # noqa: E402


def test_a_bare_name_stands_for_its_first_set_as_the_advice_takes_it():
    spec = advise_quality.first_set("spring_pendulum")
    assert spec.startswith("spring_pendulum:k=")
    assert parse_problem_spec(spec) == parse_problem_spec("spring_pendulum")[:1]
    assert advise_quality.first_set("two_mass:c2=1000") == "two_mass:c2=1000"
    assert advise_quality.first_set("pendulum") == "pendulum"   # one set, no parameters


def test_the_best_line_is_read_on_the_advice_s_parameter_set_only(tmp_path):
    store = tmp_path / "m.sqlite"
    env = {**os.environ, "IBENCH_DATA_DIR": str(tmp_path / "data"),
           "IBENCH_REFERENCE_DIR": str(ROOT / "results" / "reference")}
    got = subprocess.run([Path(sys.executable).parent / "ibench", "run", "-p",
                          "spring_pendulum", "-i", "scipy-RK45", "--rtol", "1e-4", "1e-6",
                          "--repeat", "1", "--store", store],
                         capture_output=True, text=True, timeout=300, env=env)
    assert got.returncode == 0, got.stderr
    first, second = (s.params_dict for s in parse_problem_spec("spring_pendulum"))  # both in the store
    a, b = (advise_quality.best_line(store, 1e-3, "max", p) for p in (first, second))
    assert a is not None and b is not None and a["cpu_s"] != b["cpu_s"]
    assert advise_quality.best_line(store, 1e-3, "max", {**first, "k": 1.0}) is None
