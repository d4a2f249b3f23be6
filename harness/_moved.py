"""The harness's modules that moved into subpackages, importable by their old names.

``import integrator_bench.harness.cases`` (or ``from integrator_bench.harness import
cases``) still works and gives the very module object of its new place,
:mod:`integrator_bench.harness.model.cases`, with a :class:`DeprecationWarning`
naming the new path. The old names are kept for one release.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
import types
import warnings

#: subpackage -> the modules that moved into it from ``harness/``
MOVES = {
    "model": ("registry", "cases", "record", "store", "provenance", "seed_numbers"),
    "measure": ("metrics", "counting", "references", "stiffness"),
    "run": ("execution", "isolation", "runner", "schedule", "dask_backend", "shipping",
            "streams"),
    "checks": ("verify", "verify_problems", "conformance", "method_checks"),
    "ranking": ("coverage",),
}
PACKAGE = "integrator_bench.harness"
#: old module name -> new module name
MOVED = {f"{PACKAGE}.{module}": f"{PACKAGE}.{package}.{module}"
         for package, modules in MOVES.items() for module in modules}


class _Alias(importlib.abc.Loader):
    """Loads an old name as the module of its new place."""

    def create_module(self, spec):
        return types.ModuleType(spec.name)  # a placeholder, replaced in exec_module

    def exec_module(self, module):
        new = MOVED[module.__name__]
        warnings.warn(f"{module.__name__} moved to {new}; the old name goes in the next "
                      "release", DeprecationWarning, stacklevel=2)
        # the import system returns whatever sys.modules holds under the old name
        sys.modules[module.__name__] = importlib.import_module(new)


class _Finder(importlib.abc.MetaPathFinder):
    def find_spec(self, fullname, path=None, target=None):
        if fullname in MOVED:
            return importlib.machinery.ModuleSpec(fullname, _Alias())
        return None


def install() -> None:
    """Put the finder on ``sys.meta_path`` once."""
    if not any(isinstance(f, _Finder) for f in sys.meta_path):
        sys.meta_path.insert(0, _Finder())
