"""The working tree's registry, as plain names: the axes of the asv suite.

asv discovers the benchmarks once, in one environment, and then runs every
other commit's environment by *position* in the parameter lists. The lists
must therefore be the same in every environment, whatever the commit that is
installed there registers. They are taken here from the working tree (the
checkout that holds ``benchmarks/``): the entry points of its
``pyproject.toml`` (how a problem or an integrator is registered), plus those
of any other installed package (plugins), with each problem's benchmark
parameter sets and formulations read from the working tree's own problem
classes. A case that a commit cannot run is skipped there (NotImplementedError
in ``setup``).

The snapshot is computed in a subprocess in which the working tree's folders
are imported as ``integrator_bench.problems`` (and ``.integrators``,
``.harness``), not the installed commit's packages and cached under
``.asv/suite/``, keyed by the files it depends on, so that all environments of
a run share it even when one of them could not import a new problem.

Run as ``python -m benchmarks._snapshot`` it prints the snapshot as JSON.
"""

from __future__ import annotations

import hashlib
import importlib
import json
import os
import subprocess
import sys
import tomllib
import warnings
from importlib.metadata import entry_points
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
GROUPS = {"problems": "integrator_bench.problems",
          "integrators": "integrator_bench.integrators"}


#: where a module of the harness lives, newest layout first: its subpackages, the flat
#: ``integrator_bench.harness`` of the commits before them, the top-level ``harness`` of
#: the oldest (asv installs whichever commit it benchmarks)
LAYOUTS = tuple(f"integrator_bench.harness.{p}" for p in ("matrix", "model", "measure", "run", "checks",
                                                           "report")) + (
    "integrator_bench.harness", "harness")


def harness_module(name: str):
    """The harness's module ``name`` (``"cases"``, ``"runner"``, ...) of the installed
    commit, whatever its layout (:data:`LAYOUTS`); None when that commit has none.
    A module that exists but cannot import what it needs raises as it would."""
    for prefix in LAYOUTS:
        full = f"{prefix}.{name}"
        try:
            return importlib.import_module(full)
        except ModuleNotFoundError as exc:
            missing = exc.name or ""
            if not (full == missing or full.startswith(missing + ".")):
                raise
    return None


def _registered(group: str) -> dict[str, str]:
    """``name -> "module:attr"``: the working tree's entry points, then plugins'."""
    conf = tomllib.loads((REPO / "pyproject.toml").read_text())
    names = dict(conf["project"].get("entry-points", {}).get(group, {}))
    for ep in entry_points(group=group):
        dist = getattr(ep, "dist", None)
        if dist is not None and dist.metadata["Name"] != _layout().DISTRIBUTION:
            names.setdefault(ep.name, ep.value)
    return dict(sorted(names.items()))


def _layout():
    """The working tree's ``harness/layout.py``, loaded by its path (nothing of the
    project may be imported before the folders are bound)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("_ibench_layout", REPO / "harness" / "layout.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def import_working_tree() -> None:
    """Make ``integrator_bench.<folder>`` the working tree's folders in this process
    (``harness/layout.py``'s :func:`import_folders`)."""
    _layout().import_folders(REPO)


def compute() -> dict:
    """The snapshot, from the classes importable here (run with the working tree first on the path)."""
    from integrator_bench.problems.base import format_label

    problems = {}
    for name, target in _registered(GROUPS["problems"]).items():
        module, _, attr = target.partition(":")
        try:
            cls = getattr(importlib.import_module(module), attr)
            sets = [format_label(name, cls(**p).params) for p in cls.benchmark_parameters]
        except Exception as exc:  # a problem that cannot load stays out, loudly
            print(f"benchmarks: problem {name!r} left out: {type(exc).__name__}: {exc}",
                  file=sys.stderr)
            continue
        problems[name] = {"sets": sets, "formulations": list(cls.formulations)}
    return {"problems": problems,
            "integrators": sorted([*_registered(GROUPS["integrators"]), *_variants()])}


#: integrators with settings that asv tracks beside the registered ones: the full
#: preset's variants (harness/matrix/cases.py SEED_VARIANTS) but HHT at alpha 0, which on
#: the index-3 forms fails only after minutes (no damping of the constraint forces)
ASV_VARIANTS = ("cvode-bdf:max_order=2", "ida:max_order=2", f"hht:alpha={-1 / 3!r}",
                "assimulo-cvode-bdf:max_order=2", "assimulo-ida:max_order=2")


def _variants() -> list[str]:
    """:data:`ASV_VARIANTS`, whether installed or not (asv's axes are the same in
    every environment): asv's benchmark names carry the settings. Empty at a
    commit from before settings."""
    cases = harness_module("cases")
    if cases is None or not hasattr(cases, "parse_integrator_spec"):
        return []
    return list(ASV_VARIANTS)


def _key() -> str:
    h = hashlib.sha256()
    files = ([REPO / "pyproject.toml", Path(__file__), REPO / "harness" / "matrix" / "cases.py"]
             + sorted((REPO / "problems").rglob("*.py")))
    for path in files:
        h.update(str(path.relative_to(REPO)).encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def snapshot() -> dict:
    """The cached snapshot of the working tree's registry (computed when missing)."""
    path = REPO / ".asv" / "suite" / f"{_key()}.json"
    if path.exists():
        return json.loads(path.read_text())
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(REPO)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]))
    proc = subprocess.run([sys.executable, "-m", "benchmarks._snapshot"], cwd=REPO, env=env,
                          capture_output=True, text=True)
    if proc.returncode != 0:
        raise RuntimeError(f"benchmarks: reading the registry failed:\n{proc.stderr}")
    if proc.stderr.strip():
        warnings.warn(proc.stderr.strip(), stacklevel=2)
    data = json.loads(proc.stdout)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(f".{os.getpid()}.tmp")
    tmp.write_text(json.dumps(data, indent=1) + "\n")
    tmp.replace(path)
    return data


if __name__ == "__main__":
    import_working_tree()
    json.dump(compute(), sys.stdout)
