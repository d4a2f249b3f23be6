"""The asv suite as asv itself builds and imports it, in its own environment.

The dashboard tests run asv with ``--python=same`` (this venv, which has every
extra), so they cannot see a module of ``benchmarks/`` that asv's own
environment cannot import. Here a clone of the committed tree is built as the
README's commands build it (``asv machine --yes``, then ``asv run --quick``,
which creates asv's virtualenv, installs the project's wheel as
``asv.conf.json`` says and discovers every module of ``benchmarks/``), on two
benchmarks of one case: CVODE through scikit-sundae and through Assimulo, so
that the extra the environment installs is checked too. Over a minute (the
environment's packages come from pip's cache after the first time).
"""

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
TINY = r"^cases\.two_mass\.time_solve\(.*'ode', '(cvode-bdf|assimulo-cvode-bdf)', 'loose'\)"


# minutes on a fresh machine (asv builds its environment from the wheel): `pytest -m slow`
@pytest.mark.slow
def test_readme_commands_build_and_import_the_suite_in_asvs_own_environment(tmp_path):
    assert shutil.which("git"), "git is needed to clone the committed tree"
    clone = tmp_path / "clone"
    subprocess.run(["git", "clone", "-q", str(REPO), str(clone)], check=True)
    asv = [sys.executable, "-m", "asv"]
    subprocess.run([*asv, "machine", "--yes", "--machine", "ci"], cwd=clone, check=True,
                   capture_output=True)
    proc = subprocess.run([*asv, "run", "--quick", "--machine", "ci", "-b", TINY, "HEAD^!"],
                          cwd=clone, text=True, capture_output=True, timeout=1200)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0 and "Failed to build" not in out, out[-6000:]
    assert "Discovering benchmarks" in out and "--python=same" not in out
    results, = (clone / ".asv" / "results" / "ci").glob("*-virtualenv-*.json")
    data = json.loads(results.read_text())
    columns = data["result_columns"]
    values, params = (data["results"]["cases.two_mass.time_solve"][columns.index(k)]
                      for k in ("result", "params"))
    first_set, integrators = params[0][0], params[2]
    timed = {}
    for i, integ in enumerate(integrators):
        if integ in ("'cvode-bdf'", "'assimulo-cvode-bdf'"):
            # row-major over (set, formulation, integrator, tolerance); 'loose' is first
            index = (params[0].index(first_set) * len(params[1]) * len(integrators)
                     + i) * len(params[3])
            timed[integ] = values[index]
    assert set(timed) == {"'cvode-bdf'", "'assimulo-cvode-bdf'"}
    for integ, seconds in timed.items():
        # a number: set up and timed in asv's environment (NaN would be a skip or failure)
        assert seconds is not None and seconds == seconds and 0 < seconds < 5, (integ, seconds)
