"""Discovery of problems and integrators through entry points.

Built-ins and plugins are registered the same way, through the entry-point
groups ``integrator_bench.problems`` and ``integrator_bench.integrators``.
Loading is defensive, as xarray loads its backends: an entry point that fails to
import, reuses a name or does not meet the interface becomes a warning naming
the package and the reason, never a crash. A built-in whose optional dependency
is not installed (an extra such as ``[assimulo]``) is absent: :func:`absent`
names it, and one warning line per missing package says why. Discovery is cached;
:func:`refresh` forgets the cache. :func:`register` adds a class at run time
(tests use it for deliberately broken integrators). A problem class that loads
but raises when it is built (its consistent start, its compiled model) is left
out of :func:`built_problems`, what the commands that take every problem go
through, with a warning naming it and why. An unknown name raises
:class:`~integrator_bench.harness.errors.UnknownName`; a plugin that cannot be
loaded is a :class:`~integrator_bench.harness.errors.RegistryWarning` (both
importable from here too).
"""

from __future__ import annotations

import sys
import warnings
from importlib.metadata import entry_points

from integrator_bench.harness.errors import ModelFault, RegistryWarning, UnknownName
from integrator_bench.harness.matrix import builds
from integrator_bench.harness.matrix.builds import BUILT_IN  # the origin of the project's own
from integrator_bench.integrators.base import Integrator
from integrator_bench.problems.base import Problem
from integrator_bench.problems.fmu import FmuProblem

GROUPS = {"problems": "integrator_bench.problems",
          "integrators": "integrator_bench.integrators"}
BASES = {"problems": Problem, "integrators": Integrator}
BUILTIN_DIST = "integrator-bench"

_cache: dict[str, dict[str, type]] = {}
_absent: dict[str, dict[str, str]] = {}
_built: dict[type, object] = {}    # problem class -> its default instance, or why it failed
_extra: dict[str, dict[str, type]] = {"problems": {}, "integrators": {}}

__all__ = ["GROUPS", "BASES", "BUILTIN_DIST", "BUILT_IN", "FAMILIES", "RegistryWarning",
           "UnknownName", "refresh", "register", "unregister", "problems", "built_problems",
           "integrators",
           "formulations", "get_problem_class", "get_integrator"]


def _origin(ep) -> str:
    dist = getattr(ep, "dist", None)
    if dist is None or dist.metadata["Name"] == BUILTIN_DIST:
        return BUILT_IN
    return f"{dist.metadata['Name']} {dist.version}"


def _extra_of(dist, module: str) -> str:
    """The extra of ``dist`` that brings ``module``'s distribution (named after it), or ""."""
    for req in (dist.requires or []) if dist is not None else []:
        name, _, marker = req.partition(";")
        if name.strip().lower().startswith(module.lower()) and "extra ==" in marker:
            return marker.split("extra ==")[1].strip().strip("'\"")
    return ""


def _warn_absent(kind: str, absent: dict[str, str], dists: dict) -> None:
    """One line per missing package: the built-ins absent without it."""
    for module in sorted(set(absent.values())):
        names = sorted(n for n, m in absent.items() if m == module)
        extra = _extra_of(dists.get(module), module)
        hint = f" (pip install 'integrator-bench[{extra}]')" if extra else ""
        warnings.warn(f"{kind} {', '.join(names)} absent: the optional package {module!r} "
                      f"is not installed{hint}", RegistryWarning, stacklevel=3)


def _load(kind: str) -> dict[str, type]:
    found: dict[str, type] = {}
    absent: dict[str, str] = {}
    dists: dict = {}
    base = BASES[kind]
    # built-ins first, so a plugin reusing a built-in name is the one refused
    eps = sorted(entry_points(group=GROUPS[kind]), key=lambda e: (_origin(e) != BUILT_IN, e.name))
    for ep in eps:
        origin = _origin(ep)
        try:
            cls = ep.load()
        except ModuleNotFoundError as exc:
            if not _optional_missing(ep, origin, exc):
                _warn_failed(kind, ep, origin, exc)
                continue
            module = exc.name.partition(".")[0]
            absent[ep.name], dists[module] = module, getattr(ep, "dist", None)
            continue
        except Exception as exc:  # a broken plugin must never stop the host
            _warn_failed(kind, ep, origin, exc)
            continue
        _warn_replaced(kind, ep, origin)
        problem = _interface_problem(cls, base, ep.name)
        if problem is None and ep.name in found:
            problem = f"name already registered by {found[ep.name].origin}"
        if problem:
            warnings.warn(f"{kind[:-1]} plugin {ep.name!r} from {origin} ignored: {problem}",
                          RegistryWarning, stacklevel=2)
            continue
        cls.origin = origin
        found[ep.name] = cls
    _absent[kind] = absent
    _warn_absent(kind, absent, dists)
    return found


def _optional_missing(ep, origin, exc) -> bool:
    """Whether ``exc`` is a built-in module of this package missing a package of its
    own (an optional dependency), not a broken entry point."""
    return (origin == BUILT_IN and bool(exc.name) and ep.value.startswith("integrator_bench.")
            and not exc.name.startswith("integrator_bench"))


def replaced_by(package: str) -> list[str]:
    """``module.name`` of each function or class of this project's modules (those
    imported) that is now one of ``package``'s: what a plugin of that top-level
    package replaced when it loaded (a harness function a ranking depends on, an
    integrator's helper), found by the defining module of what each name holds."""
    found = []
    for name, module in list(sys.modules.items()):
        if not name.startswith("integrator_bench.") or module is None:
            continue
        for attr, value in list(vars(module).items()):
            owner = getattr(value, "__module__", None) if callable(value) else None
            if isinstance(owner, str) and (owner == package or owner.startswith(package + ".")):
                found.append(f"{name}.{attr}")
    return sorted(found)


def _warn_replaced(kind, ep, origin) -> None:
    """A loud warning naming what the plugin ``ep`` replaced in this project's modules
    as it loaded (:func:`replaced_by`): its results are no longer the harness's."""
    package = ep.value.split(":")[0].split(".")[0]
    if package == "integrator_bench":
        return
    for target in replaced_by(package):
        warnings.warn(f"{kind[:-1]} plugin {ep.name!r} from {origin} replaced {target} "
                      "as it loaded: the harness's measurements and rankings are no longer "
                      "its own while it is installed", RegistryWarning, stacklevel=3)


def _warn_failed(kind, ep, origin, exc) -> None:
    warnings.warn(f"{kind[:-1]} plugin {ep.name!r} from {origin} failed to load: "
                  f"{type(exc).__name__}: {exc}", RegistryWarning, stacklevel=3)


def absent(kind: str = "integrators") -> dict[str, str]:
    """Built-ins of ``kind`` left out because an optional package is missing:
    ``{name: package}``."""
    _registry(kind)
    return dict(_absent.get(kind, {}))


def _interface_problem(cls, base, name) -> str | None:
    if not (isinstance(cls, type) and issubclass(cls, base)):
        return f"{cls!r} is not a subclass of {base.__module__}.{base.__name__}"
    if cls.name != name:
        return f"class name attribute {cls.name!r} differs from entry-point name {name!r}"
    return None


def _registry(kind: str) -> dict[str, type]:
    if kind not in _cache:
        _cache[kind] = _load(kind)
    merged = dict(_cache[kind])
    merged.update(_extra[kind])
    return merged


def refresh() -> None:
    """Forget cached discovery: the next lookup reads the entry points again."""
    _cache.clear()
    _absent.clear()
    _built.clear()
    builds.forget()


def register(cls: type, origin: str = "runtime") -> type:
    """Register ``cls`` (a Problem or Integrator subclass) under ``cls.name``."""
    kind = "problems" if issubclass(cls, Problem) else "integrators"
    cls.origin = origin
    _extra[kind][cls.name] = cls
    return cls


def unregister(name: str) -> None:
    for reg in _extra.values():
        reg.pop(name, None)


def problems() -> dict[str, type[Problem]]:
    return _registry("problems")


def built_problems() -> dict:
    """The registered problems built at their defaults, ``{name: instance}``, their
    initial state made (a mechanism's consistent start, a symbolic model's
    compiled functions); one from outside the project as the
    :class:`~integrator_bench.harness.matrix.stand_in.StandIn` of its build in a
    process of its own (:func:`~integrator_bench.harness.matrix.builds.build`). One that
    raises, crashes or hangs is left out with a :class:`RegistryWarning` naming
    it, its origin and the fault, so that every other problem and every command
    that takes them all still works (``ibench list problems``, a run that names
    no problem). Built once per process (:func:`refresh` forgets)."""
    out = {}
    for name, cls in problems().items():
        if cls not in _built:
            try:
                problem = builds.build(cls, {})
                if isinstance(problem, Problem):   # a stand-in's was made in its trial
                    problem.initial_state()
                _built[cls] = problem
            except ModelFault as exc:   # raised, crashed or hung in its trial build
                _built[cls] = str(exc)
            except Exception as exc:  # a broken plugin must never stop the host
                _built[cls] = f"{type(exc).__name__}: {exc}"
            if isinstance(_built[cls], str):
                warnings.warn(f"problem {name!r} from {getattr(cls, 'origin', '?')} skipped: "
                              f"it failed to build: {_built[cls]}", RegistryWarning,
                              stacklevel=2)
        if not isinstance(_built[cls], str):
            out[name] = _built[cls]
    return out


def integrators() -> dict[str, type[Integrator]]:
    return _registry("integrators")


def formulations() -> list[str]:
    """Every formulation some registered problem offers."""
    seen = []
    for cls in problems().values():
        for f in cls.formulations:
            if f not in seen:
                seen.append(f)
    return seen


#: problems made from their parameters alone (a file), never run without them:
#: named on the command line, not listed among the registered problems
FAMILIES: dict[str, type[Problem]] = {FmuProblem.name: FmuProblem}


def get_problem_class(name: str) -> type[Problem]:
    reg = problems()
    if name in reg:
        return reg[name]
    if name in FAMILIES:
        return FAMILIES[name]
    valid = [*reg, *(f"{f}:path=FILE" for f in FAMILIES)]
    raise UnknownName(f"unknown problem {name!r}; valid: {', '.join(valid)}")


def get_integrator(name: str) -> type[Integrator]:
    reg = integrators()
    if name not in reg:
        raise UnknownName(f"unknown integrator {name!r}; valid: {', '.join(reg)}")
    return reg[name]
