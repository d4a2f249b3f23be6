"""The non-editable install: a built wheel in a fresh environment, and the data-directory rule.

The wheel is built from a copy of the packaged sources (so the checkout gets no
build artefacts) and installed, not editable, into a new virtual environment
beside a distribution named ``integrators`` that owns a top-level
``integrators`` package. The new environment gets numpy, scipy and the other
dependencies through a ``.pth`` line naming the test interpreter's
site-packages (no network, no copies); that directory holds the editable
install of this checkout too, but its import hook lives in a ``.pth`` file that
a plain path line does not process, and its metadata comes after the new
environment's, so the test asserts that the wheel's copy is the one imported.
"""

import hashlib
import json
import os
import shutil
import subprocess
import sys
import textwrap
import tomllib
from pathlib import Path

import numpy
import pytest

from integrator_bench.harness import paths

from integrator_bench.harness.measure import references

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.record import CaseStatus

REPO = Path(__file__).resolve().parents[2]
STAND_IN = {  # another distribution owning the top-level name ``integrators``
    "pyproject.toml": """\
        [build-system]
        requires = ["setuptools>=68"]
        build-backend = "setuptools.build_meta"
        [project]
        name = "integrators"
        version = "0.0.7"
        [tool.setuptools]
        packages = ["integrators"]
    """,
    "integrators/__init__.py": "OWNER = 'the integrators distribution'\n",
}


# ---- the rule, in this process ------------------------------------------------------

def test_this_checkout_keeps_its_data_in_results():
    assert paths.checkout_root() == REPO
    assert paths.data_dir(environ={}) == REPO / "results"
    assert paths.shipped_reference_dir() is None


def test_installed_copy_uses_the_working_directory_or_the_variable(tmp_path):
    harness = tmp_path / "site-packages" / "integrator_bench" / "harness"
    harness.mkdir(parents=True)
    assert paths.checkout_root(harness) is None
    assert paths.data_dir(harness, environ={}, cwd=tmp_path / "w") == tmp_path / "w" / "results"
    env = {"IBENCH_DATA_DIR": str(tmp_path / "d")}
    assert paths.data_dir(harness, environ=env, cwd=tmp_path) == tmp_path / "d"
    assert paths.shipped_reference_dir(harness) == harness.parent / "reference_data"


def test_a_pyproject_of_another_project_is_not_a_checkout(tmp_path):
    (tmp_path / "harness").mkdir()
    (tmp_path / "pyproject.toml").write_text('[project]\nname = "something-else"\n')
    assert paths.checkout_root(tmp_path / "harness") is None
    (tmp_path / "pyproject.toml").write_text('[project]\nname = "integrator-bench"\n')
    assert paths.checkout_root(tmp_path / "harness") == tmp_path


# ---- the wheel ----------------------------------------------------------------------

def _packaged_sources(dest: Path) -> Path:
    """Copy what the wheel is built from: pyproject.toml's package folders, setup.py, readme."""
    config = tomllib.loads((REPO / "pyproject.toml").read_text())
    folders = config["tool"]["setuptools"]["package-dir"].values()
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
    for name in ("pyproject.toml", "setup.py", config["project"]["readme"]):
        shutil.copy2(REPO / name, dest / name)
    for folder in folders:
        shutil.copytree(REPO / folder, dest / folder, ignore=ignore)
    return dest


def _run(*cmd, cwd=None, env=None, timeout=600):
    out = subprocess.run([str(c) for c in cmd], cwd=cwd, env=env, capture_output=True,
                         text=True, timeout=timeout)
    assert out.returncode == 0, f"{cmd}\n{out.stdout}\n{out.stderr}"
    return out.stdout


def _tree(root: Path) -> dict:
    """Every file under ``root`` with the hash of its content."""
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def env(tmp_path_factory):
    """A fresh venv with the wheel and the ``integrators`` stand-in installed."""
    tmp = tmp_path_factory.mktemp("wheel")
    (tmp / "src").mkdir()
    src = _packaged_sources(tmp / "src")
    stand_in = tmp / "stand_in"
    for name, text in STAND_IN.items():
        (stand_in / name).parent.mkdir(parents=True, exist_ok=True)
        (stand_in / name).write_text(textwrap.dedent(text))
    dist = tmp / "dist"
    _run(sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", dist, src, stand_in,
         timeout=900)
    venv = tmp / "venv"
    _run(sys.executable, "-m", "venv", "--without-pip", venv)
    python = venv / "bin" / "python"
    _run(sys.executable, "-m", "pip", "--python", python, "install", "-q", "--no-deps",
         *sorted(dist.glob("*.whl")))
    site = Path(_run(python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])")
                .strip())
    (site / "ibench_test_dependencies.pth").write_text(
        str(Path(numpy.__file__).resolve().parents[1]) + "\n")
    environ = {k: v for k, v in os.environ.items()
               if k != "PYTHONPATH" and not k.startswith("IBENCH_")}
    return {"venv": venv, "python": python, "site": site, "environ": environ, "tmp": tmp,
            "wheel": next(dist.glob("integrator_bench-*.whl"))}


def test_wheel_ships_the_packages_and_references_only(env):
    import zipfile
    names = zipfile.ZipFile(env["wheel"]).namelist()
    top = {n.split("/")[0] for n in names}
    assert top == {"integrator_bench", env["wheel"].name.split("-py3")[0] + ".dist-info"}
    shipped = sorted(n.removeprefix("integrator_bench/reference_data/") for n in names
                     if n.startswith("integrator_bench/reference_data/"))
    committed = sorted(str(p.relative_to(REPO / "results" / "reference"))
                       for p in (REPO / "results" / "reference").glob("*/*")
                       if p.suffix in (".npz", ".json"))
    assert shipped == committed and shipped
    # every module of the three packages, their subpackages (the report, the models) included
    modules = {f"integrator_bench/{folder}/{p.relative_to(REPO / folder)}"
               for folder in ("problems", "integrators", "harness")
               for p in (REPO / folder).rglob("*.py")}
    assert {"integrator_bench/harness/report/write.py",
            "integrator_bench/problems/models/pendulum.py"} <= modules <= set(names)


def test_installed_wheel_runs_beside_another_integrators_package(env):
    """``ibench list`` and a small ``ibench run`` from an empty working directory:
    records ok, references read from the shipped package data (or, where the
    committed one is stale, computed into ./results/reference), the store in
    ./results, nothing written into the environment, ``integrators`` untouched."""
    venv, site, environ = env["venv"], env["site"], env["environ"]
    work = env["tmp"] / "work"
    work.mkdir()
    before = _tree(venv)

    where = json.loads(_run(env["python"], "-c", textwrap.dedent("""\
        import importlib.metadata as md, json, integrators
        from integrator_bench.harness import paths
        from integrator_bench.harness.matrix import registry
        print(json.dumps({"integrators": [integrators.OWNER, integrators.__file__,
                                          md.version("integrators")],
                          "harness": registry.__file__,
                          "dist": str(md.distribution("integrator-bench").locate_file("")),
                          "data": str(paths.DATA_DIR), "store": str(paths.DEFAULT_STORE),
                          "shipped": str(paths.SHIPPED_REFERENCE_DIR)}))
        """), cwd=work, env=environ))
    assert where["integrators"] == ["the integrators distribution",
                                    str(site / "integrators" / "__init__.py"), "0.0.7"]
    assert Path(where["harness"]).is_relative_to(site)
    assert Path(where["dist"]) == site
    assert where["data"] == str(work / "results")
    assert where["store"] == str(work / "results" / "ibench.sqlite")
    shipped = Path(where["shipped"])
    assert shipped == site / "integrator_bench" / "reference_data"

    listed = {i["name"] for i in json.loads(_run(venv / "bin" / "ibench", "list", "integrators",
                                                 "--json", cwd=work, env=environ))}
    assert {"rk4", "scipy-RK45"} <= listed and listed == set(registry.integrators())

    out = _run(venv / "bin" / "ibench", "run", "--preset", "full", "-p", "two_mass",
               "-i", "rk4", "-i", "scipy-RK45", "--rtol", "1e-6", "--h", "1e-3", "--json",
               cwd=work, env=environ)
    records = [json.loads(line) for line in out.splitlines()]
    assert len(records) == 8  # 2 parameter sets (full preset) x 2 integrators x (rtol, h)
    runnable = [r for r in records if (r["integrator"] == "rk4") == (r["h"] is not None)]
    assert len(runnable) == 4 and all(r["status"] == CaseStatus.OK for r in runnable), records
    assert all(r["status"] == CaseStatus.UNSUPPORTED for r in records if r not in runnable), records
    assert (work / "results" / "ibench.sqlite").is_file()

    n_shipped = 0
    for r in runnable:
        problem = registry.get_problem_class(r["problem"])(**json.loads(r["params"]))
        committed_ok = references.read(problem, REPO / "results" / "reference")[0] is not None
        npz, js = references.paths(problem, work / "results" / "reference")
        source = shipped / js.relative_to(work / "results" / "reference")
        if committed_ok:  # read from the package data, nothing computed
            assert not js.exists()
            n_shipped += 1
        else:  # stale in the commit: recomputed into the data directory
            assert npz.exists() and js.exists()
            source = js
        meta = json.loads(source.read_text())
        assert r["reference"] == f"{meta['label']}@{meta['checksum'][:12]}"
    assert n_shipped, "no committed two_mass reference is current: nothing read from the wheel"
    assert _tree(venv) == before


def test_installed_wheel_writes_new_references_to_the_data_dir(env):
    """A reference the wheel does not ship is computed into ``IBENCH_DATA_DIR``."""
    data = env["tmp"] / "data"
    environ = dict(env["environ"], IBENCH_DATA_DIR=str(data))
    before = _tree(env["venv"])
    _run(env["venv"] / "bin" / "ibench", "reference", "-p", "two_mass:c2=5", "--json",
         cwd=env["tmp"], env=environ)
    written = sorted(p.name for p in (data / "reference" / "two_mass").iterdir())
    assert written == ["c1=0.1,c2=5,k1=10,k2=10000.json", "c1=0.1,c2=5,k1=10,k2=10000.npz"]
    assert _tree(env["venv"]) == before
