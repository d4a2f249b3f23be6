"""Names a model or a user chooses never place a file outside its folder.

The hostile FMU (``tests/fmu_hostile``, built from C sources by the ``hostile_fmu``
fixture) names its state and its parameter ``../../../../escaped/pwned/x`` and
``.../k``: a harness putting those names into reference file names unescaped
writes outside the data directory."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

from integrator_bench.harness.paths import file_name, inside

IBENCH = [sys.executable, "-m", "integrator_bench.harness.cli"]
STATE, PARAMETER = "../../../../escaped/pwned/x", "../../../../escaped/pwned/k"   # fmu_hostile's


def _files(root: Path) -> set[Path]:
    return {p for p in root.rglob("*") if p.is_file() or p.is_symlink()}


@pytest.mark.parametrize("name", ["..", ".", "../../x", "a/b", "/etc/passwd", "a\\b", "x\0y",
                                  ".hidden", "", "é<script>", "x" * 400])
def test_a_file_name_from_any_name_stays_inside_its_folder(tmp_path, name):
    made = file_name(name)
    path = inside(tmp_path, made)
    assert path.parent == tmp_path and "/" not in made and "\0" not in made
    assert made and not made.startswith(".")
    assert len(made.encode()) < 200


def test_names_of_safe_characters_keep_their_file_names():
    """Every committed reference's file name is unchanged by the escaping."""
    for name in ("spring_pendulum", "k=1e+06,t_end=1", "start.x=1.99588", "fmu=b536e738"):
        assert file_name(name) == name
    assert file_name("a/b") != file_name("a%2Fb")      # distinct names stay distinct


@pytest.mark.parametrize("names", [("..",), ("a", ".."), ("a/../../b",), ()])
def test_inside_refuses_what_leaves_the_folder(tmp_path, names):
    with pytest.raises(ValueError, match="does not name a file inside"):
        inside(tmp_path, *names)


def test_an_fmu_with_traversal_names_writes_nothing_outside_the_data_directory(hostile_fmu,
                                                                                tmp_path):
    """``ibench run`` of the hostile FMU with its parameter and state start set
    computes and saves a reference, the store and nothing else: every file it
    writes lies under the data directory."""
    data = tmp_path / "a" / "b" / "c" / "d" / "data"
    env = {**os.environ, "IBENCH_DATA_DIR": str(data),
           "IBENCH_REFERENCE_DIR": str(data / "reference")}
    spec = f"fmu:path={hostile_fmu},{PARAMETER}=2,start.{STATE}=0.5"
    r = subprocess.run([*IBENCH, "run", "-p", spec, "-i", "scipy-RK45", "--rtol", "1e-6",
                        "--json"], capture_output=True, text=True, env=env, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert '"status": "ok"' in r.stdout, r.stdout
    written = _files(tmp_path)
    assert written and all(data in p.parents for p in written), sorted(written)
    saved = [p for p in written if p.suffix == ".npz"]
    assert len(saved) == 1 and saved[0].parent == data / "reference" / "fmu", saved
