"""How the checkout's folders become the installed packages: the one module that knows.

The design card fixes three folders at the top of the checkout, installed under one
root package (``package-dir`` in ``pyproject.toml``, which the build reads):

========================  ==============================
folder                    package
========================  ==============================
``problems/``             ``integrator_bench.problems``
``integrators/``          ``integrator_bench.integrators``
``harness/``              ``integrator_bench.harness``
========================  ==============================

Everything that must know the mapping without the build's help asks here: the data
directory's rule (:mod:`.paths`, which tells a checkout from an installed wheel) and the
asv suite (``benchmarks/_snapshot.py``, which imports a working tree's folders under
the packages' names before anything installed is imported, and so loads this file by
its path). The module therefore imports nothing of the project.
``tests/project/test_layout.py`` holds :data:`FOLDERS` to ``pyproject.toml``.
"""

from __future__ import annotations

import importlib.util
import sys
import tomllib
import types
from pathlib import Path

#: the distribution's name (``pyproject.toml``'s ``project.name``)
DISTRIBUTION = "integrator-bench"
#: the root package every folder installs under
ROOT = "integrator_bench"
#: folder of the checkout -> the package it installs as
FOLDERS = {folder: f"{ROOT}.{folder}" for folder in ("problems", "integrators", "harness")}


def checkout_root(package_dir: Path) -> Path | None:
    """The checkout that the folder ``package_dir`` (one of :data:`FOLDERS`) lies in,
    or None for an installed copy.

    A checkout has, beside the folder, a ``pyproject.toml`` naming
    :data:`DISTRIBUTION`; an installed wheel has the root package's folder there
    instead.
    """
    root = Path(package_dir).resolve().parent
    try:
        with open(root / "pyproject.toml", "rb") as f:
            name = tomllib.load(f).get("project", {}).get("name")
    except (OSError, tomllib.TOMLDecodeError):
        return None
    return root if name == DISTRIBUTION else None


def import_folders(checkout: Path) -> None:
    """Bind ``checkout``'s folders to their packages' names in this process.

    After this, ``import integrator_bench.harness...`` imports ``checkout/harness``
    whatever is installed. Call it before anything imports the installed packages.
    """
    root = types.ModuleType(ROOT)
    root.__path__ = []
    sys.modules[ROOT] = root
    for folder, name in FOLDERS.items():
        spec = importlib.util.spec_from_file_location(
            name, Path(checkout) / folder / "__init__.py",
            submodule_search_locations=[str(Path(checkout) / folder)])
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        setattr(root, folder, module)
        spec.loader.exec_module(module)
