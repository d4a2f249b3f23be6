"""What an integrator is handed for its counted solve: counted callables and watched inputs.

:func:`counted` copies a (converted) system so that every callable of the model
on it counts its calls where the model is called: the right-hand side or
residual (``nfev``), the Jacobian (``njev``), and every other one (projection,
mass matrix, constraints, event functions and resets) under its own name. The
counting function holds the model's callable in a closure, with no attribute
leading to it (``vars()`` of it is empty), and the copy carries no second form
of the problem (its ``mechanical`` or ``fmu`` form is dropped: the integrator
got the form it takes), so the calls an integrator can make through what it is
handed are the counted ones. :func:`watch_model` checks that claim on a run:
it sees every entry into the problem's own code and names one made outside a
counted call (``ibench check-plugin``'s ``counts`` line).

The arrays of the copy (``y0``, ``t_eval``, ``atol_scale``, ``error_mask``,
``yp0``, ``a0``, ...) are the integrator's own copies, and the copy remembers
them: :meth:`Counters.changed_inputs` names every input the integrator changed
in place or replaced (the record's reason ``input_modified``). Once the budget of
the solve running is spent (:mod:`~integrator_bench.harness.measure.tripwire`), every
counted callable raises :class:`~integrator_bench.harness.measure.tripwire.OverBudget`
instead of calling the model.
"""

from __future__ import annotations

import contextlib
import dataclasses
import inspect
import sys
import threading
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from integrator_bench.harness.measure.tripwire import SPENT, OverBudget

#: system fields that are not the model's callables: the harness's own output map
NOT_MODEL = ("output",)
#: nested forms of the problem, dropped from the copy an integrator is handed
NESTED = ("mechanical", "fmu")


class Tally:
    """Calls of one callable: their number ``n`` and ``last``, ``(first argument,
    value)`` of the latest (the time, for the functions of ``t``)."""

    __slots__ = ("n", "last")

    def __init__(self):
        self.n, self.last = 0, None


#: the most positional parameters a counting function is made with exactly; a callable
#: of more, or with defaults or ``*args``, is counted by a function taking ``*args``
MAX_ARITY = 8


def _template(arity: int):
    """The maker of counting functions of ``arity`` positional parameters
    (``None``: ``*args``)."""
    params = "*args" if arity is None else ", ".join(f"a{i}" for i in range(arity))
    first = "args[0] if args else None" if arity is None else ("a0" if arity else "None")
    source = (f"def make(fn, tally, spent=SPENT, over=OverBudget):\n"
              f"    def counted_call({params}):\n"
              f"        if spent[0]:\n"
              f"            raise over('the budget of the solve is spent')\n"
              f"        tally.n += 1\n"
              f"        out = fn({params})\n"
              f"        tally.last = ({first}, out)\n"
              f"        return out\n"
              f"    return counted_call\n")
    namespace = {"SPENT": SPENT, "OverBudget": OverBudget}
    exec(compile(source, __file__, "exec"), namespace)  # noqa: S102  (a fixed template)
    return namespace["make"]


_MAKERS = {arity: _template(arity) for arity in (*range(MAX_ARITY + 1), None)}


def _arity(fn) -> int | None:
    """The number of positional parameters of ``fn`` when it takes exactly that many
    (none with a default, no ``*args``, no keyword-only), else None."""
    try:
        params = inspect.signature(fn).parameters.values()
    except (TypeError, ValueError):
        return None
    kinds = (inspect.Parameter.POSITIONAL_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD)
    if any(p.kind not in kinds or p.default is not p.empty for p in params):
        return None
    arity = len(params)
    return arity if arity <= MAX_ARITY else None


def _counting(fn, tally):
    """``fn`` counting its calls in ``tally``; ``fn`` is reachable only through
    the closure (no attribute of the returned function holds it).

    The counting function takes the positional parameters ``fn`` takes
    (:func:`_arity`), so that a library that reads its callback's parameters
    (f2py's callbacks in Assimulo's Fortran codes, Assimulo's problems, which
    pass switches to a function that takes them) calls it as it would call
    ``fn``."""
    return _MAKERS[_arity(fn) if fn is not None else None](fn, tally)


#: the code of every counting function, by which :func:`watch_model` knows a counted call
COUNTED_CODES = frozenset(make(None, None).__code__ for make in _MAKERS.values())


class Counters(dict):
    """``{"nfev": Tally or None, "njev": Tally or None}``, after the kind's ``counted``
    declaration (``problems/system.py``), with every tally in ``calls`` (by the
    system's attribute name: ``"fun"``, ``"project"``, ``"events[0].value"``) and
    the inputs handed in ``inputs``."""

    def __init__(self):
        super().__init__(nfev=None, njev=None)
        self.calls: dict[str, Tally] = {}
        self.inputs: dict[str, tuple] = {}

    def wrap(self, name, fn, key=None):
        """``fn`` counted under ``name`` (and under ``key``, nfev or njev, when given)."""
        tally = self.calls[name] = Tally()
        if key is not None:
            self[key] = tally
        return _counting(fn, tally)

    def changed_inputs(self, system) -> str | None:
        """``"system.y0 changed in place (y0[2]: 0.1 -> 0.35); system.atol_scale
        replaced"``: every input of ``system`` (as :func:`counted` handed it) the
        integrator changed; None when it changed none."""
        found = []
        for name, (value, copy) in self.inputs.items():
            now = getattr(system, name, None)
            if now is not value:
                found.append(f"system.{name} replaced")
                continue
            where = _difference(name, value, copy)
            if where:
                found.append(f"system.{name} changed in place ({where})")
        return "; ".join(found) or None


def _difference(name, value, copy) -> str | None:
    """Where ``value`` differs from its ``copy`` (``"y0[2]: 0.1 -> 0.35"``), or None."""
    if sp.issparse(value):
        same = all(np.array_equal(getattr(value, a), getattr(copy, a))
                   for a in ("data", "indices", "indptr") if hasattr(value, a))
        return None if same and value.shape == copy.shape else "its entries"
    if isinstance(value, np.ndarray):
        if value.shape != copy.shape:
            return f"shape {copy.shape} -> {value.shape}"
        differ = ~((value == copy) | (np.isnan(value) & np.isnan(copy))
                   if value.dtype.kind == "f" else value == copy)
        if not differ.any():
            return None
        i = np.unravel_index(int(np.argmax(differ)), value.shape)
        index = ", ".join(str(int(k)) for k in i)
        more = int(differ.sum()) - 1
        return (f"{name}[{index}]: {copy[i].item()!r} -> {value[i].item()!r}"
                + (f", and {more} more" if more else ""))
    return None if value == copy else f"{copy!r} -> {value!r}"


def _own(value):
    """A private copy of an input array (sparse matrices too); scalars as they are."""
    if sp.issparse(value):
        return value.copy()
    if isinstance(value, np.ndarray):
        return np.array(value, copy=True)
    return value


def counted(system):
    """A copy of ``system`` whose model callables count their calls, with inputs of its own.

    Returns the copy and its :class:`Counters`: ``counters["nfev"]`` and
    ``counters["njev"]`` are the tallies of the callables the kind's ``counted``
    declares (None when the system has no such callable), ``counters.calls``
    every tally. The copy's arrays are copies the integrator may read and
    :meth:`Counters.changed_inputs` compares after the run.
    """
    counters, changes = Counters(), {}
    for f in dataclasses.fields(system):
        value = getattr(system, f.name)
        if f.name in NESTED:
            changes[f.name] = None
        elif f.name in NOT_MODEL or value is None:
            continue
        elif callable(value):
            changes[f.name] = counters.wrap(f.name, value, system.counted.get(f.name))
        elif f.name == "events":
            changes["events"] = tuple(_counted_event(counters, i, e) for i, e in enumerate(value))
        elif isinstance(value, np.ndarray) or sp.issparse(value):
            changes[f.name] = _own(value)
    copy = dataclasses.replace(system, **changes)
    for f in dataclasses.fields(copy):
        value = getattr(copy, f.name)
        if f.name not in NESTED and not callable(value) and not isinstance(value, tuple):
            counters.inputs[f.name] = (value, _own(value))
    return copy, counters


def _counted_event(counters, i, event):
    wrapped = {"value": counters.wrap(f"events[{i}].value", event.value)}
    if event.reset is not None:
        wrapped["reset"] = counters.wrap(f"events[{i}].reset", event.reset)
    return dataclasses.replace(event, **wrapped)


# ------------------------------------------------------------------ the model's view

#: the problems package: every file of it is the model's code but the systems' plumbing
_PROBLEMS = Path(__file__).resolve().parents[1] / "problems"
_PLUMBING = str(_PROBLEMS / "system.py")
#: the pseudo-file of the code ``sympy.lambdify`` generates (the symbolic problems' matrices)
GENERATED = "<lambdifygenerated"


def model_files(problem) -> frozenset[str]:
    """The source files of ``problem``'s model: the problems package (but the
    systems' plumbing, ``problems/system.py``) and every module of its class's
    ancestry (a plugin's problem lives in its own package)."""
    files = {str(p) for p in _PROBLEMS.glob("*.py")}
    for cls in type(problem).__mro__:
        try:
            files.add(str(Path(inspect.getsourcefile(cls)).resolve()))
        except (TypeError, OSError):
            continue
    files.discard(_PLUMBING)
    return frozenset(files)


@dataclasses.dataclass
class ModelView:
    """What :func:`watch_model` saw: entries into the model's code made inside a
    counted call (``counted``) and outside one (``unseen``), with the first
    caller outside (``first``: ``"file.py:42 in step"``)."""

    counted: int = 0
    unseen: int = 0
    first: str | None = None

    def verdict(self) -> str | None:
        """None when every evaluation of the model was counted, else what was not."""
        if not self.unseen:
            return None
        return (f"the model was evaluated {self.unseen} time{'s' * (self.unseen > 1)} "
                f"outside the counted callables it was handed (first from {self.first})")


@contextlib.contextmanager
def watch_model(files):
    """Watch every call of the model's code (the source ``files``, and the code
    ``sympy.lambdify`` generated for the symbolic problems) inside the block.

    A call into those files from code outside them is an *entry*: counted
    when a counting function of :func:`counted` is on the stack, else unseen
    (the integrator reached the model through a path the harness does not
    count). Watched with :func:`sys.setprofile` in this thread and in threads
    started inside the block; slow, for checks only, never for a timed run.

    Yields
    ------
    ModelView
    """
    view, local = ModelView(), threading.local()

    def model(filename):
        return filename in files or filename.startswith(GENERATED)

    def profile(frame, event, arg):
        if event == "call":
            code = frame.f_code
            if code in COUNTED_CODES:
                local.depth = getattr(local, "depth", 0) + 1
            elif model(code.co_filename):
                back = frame.f_back
                if back is not None and model(back.f_code.co_filename):
                    return
                if getattr(local, "depth", 0) > 0:
                    view.counted += 1
                else:
                    view.unseen += 1
                    if view.first is None and back is not None:
                        view.first = (f"{Path(back.f_code.co_filename).name}:{back.f_lineno} "
                                      f"in {back.f_code.co_name}")
        elif event == "return" and frame.f_code in COUNTED_CODES:
            local.depth -= 1

    old = sys.getprofile()
    threading.setprofile(profile)
    sys.setprofile(profile)
    try:
        yield view
    finally:
        sys.setprofile(old)
        threading.setprofile(None)
