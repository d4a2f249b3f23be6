"""Reference solutions: computed and verified by the project, never typed in.

For each problem and parameter set the reference is either the exact solution
(``Problem.exact``), cross-checked against a tight numerical solution, or the
solution of one method at tight tolerance, verified against a second,
independent method (different formulation or different integrator). Stored in
``<reference dir>/<problem>/<params>.npz`` (times and canonical components)
with ``.json`` metadata: methods, tolerances, per-component agreement digits,
the claim (the floor of the smallest agreement), code version, the problem's
definition fingerprint and a checksum of the data. A reference whose problem
definition changed, or whose data no longer matches its checksum, is never
used: it is recomputed. So is one whose files cannot be read at all (a flipped
byte in the archive, a truncated download).

Events. For a problem whose system has state events the metadata also holds
the reference's event sequence, ``events`` (``[[t, name], ...]`` in time
order), the canonical state right after each, ``event_states``, and
``event_digits``, the agreement of two event sequences in time,
``-log10(max |t_a - t_b| / span)`` over events matched by kind and order
(:func:`~integrator_bench.harness.measure.metrics.event_time_digits`). An exact
problem's events are its ``exact_events()`` (``(t, name, y_after)`` in
canonical components), checked against the tight numerical run; otherwise they
are the first reference run's, checked against the second, and the two runs
must come from integrators of different ``event_locator`` (the segment
runner's locator, which scipy's codes and the in-house steppers share;
SUNDIALS' root finding; ODEPACK's; Assimulo's; fmpy's), so that the crossings
are located by different code. Sequences that differ in count or kind are a
:class:`~integrator_bench.harness.errors.ReferenceFailure`. A reference whose
metadata has no ``events`` has none: every reference stored before events
existed stays valid.

Where (``harness.paths``): references are read from ``REFERENCE_DIR``
(``IBENCH_REFERENCE_DIR``, else ``<data dir>/reference``; in a checkout the
committed ``results/reference/``) and, for a problem with none there, from the
read-only copies shipped in the wheel (``SHIPPED_REFERENCE_DIR``). Computed
references are written to ``REFERENCE_DIR`` only, never beside the installed code;
those of a problem from a plugin to ``PLUGIN_REFERENCE_DIR`` instead (:func:`home`:
``<data dir>/plugin-reference``, untracked in a checkout).
A Dask worker reads none of these: its case comes with the reference the client
verified (:class:`Handed`, given where a folder would be), and nothing is read
from its disk or computed there.
"""

from __future__ import annotations

import hashlib
import json
import warnings
import zipfile
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.errors import ReferenceFailure, ReferenceOverBudget
from integrator_bench.harness.measure.metrics import agreement_digits, event_time_digits
from integrator_bench.harness.paths import (PLUGIN_REFERENCE_DIR, REFERENCE_DIR,
                                            SHIPPED_REFERENCE_DIR, file_name,
                                            inside, write_atomically)
from integrator_bench.harness.version import code_version
from integrator_bench.integrators.base import Status
from integrator_bench.integrators.driver import Budget, budgeted
from integrator_bench.problems.base import Problem, format_value
from integrator_bench.problems.system import Unsupported, convert

# Radau IIA (implicit, order 5) checked by DOP853 (explicit, order 8): independent
# methods; at rtol 1e-13 they agree to 11 or more digits on every built-in problem.
DEFAULT_METHODS = (("ode", "scipy-Radau", 1e-13), ("ode", "scipy-DOP853", 1e-13))
EXACT_CHECK = ("ode", "scipy-DOP853", 1e-13)
#: the tightest rtol a reference method is run at (about where double precision ends)
TIGHTEST = 1e-13
NOT_STORED = "no stored reference"
#: wall seconds a reference may take to compute during ``ibench run`` (``--reference-timeout``)
REFERENCE_TIMEOUT = 300.0


@dataclass
class Reference:
    t: np.ndarray
    Y: np.ndarray
    meta: dict

    @property
    def id(self) -> str:
        return f"{self.meta['label']}@{self.meta['checksum'][:12]}"

    @property
    def has_events(self) -> bool:
        """Whether the reference records an event sequence (its problem has events)."""
        return "events" in self.meta

    @property
    def events(self) -> list[tuple[float, str, np.ndarray]]:
        """``(t, name, canonical state after)`` of each reference event; [] without."""
        states = self.meta.get("event_states") or [[]] * len(self.meta.get("events", []))
        return [(float(t), str(name), np.asarray(y, float))
                for (t, name), y in zip(self.meta.get("events", []), states)]


@dataclass(frozen=True)
class Handed:
    """The reference handed to a Dask worker with its case, given to :func:`read`
    and :func:`load` in place of a folder: the client's, read and verified before
    the run, or None with the client's reason (``why``). Nothing is read from the
    worker's disk, and a missing reference is never computed there."""

    reference: Reference | None
    why: str = ""

    def read(self, problem: Problem) -> tuple[Reference | None, str]:
        """The handed reference when it is ``problem``'s, or (None, why not)."""
        ref = self.reference
        if ref is None:
            return None, (f"no reference was handed to this Dask worker ({self.why}); "
                          "a worker never computes one")
        if ref.meta.get("fingerprint") != problem.fingerprint():
            return None, (f"the reference handed to this Dask worker ({ref.id}) is of another "
                          "problem definition than the worker's")
        return Reference(ref.t, ref.Y, dict(ref.meta)), ""


# file names longer than this (a problem with many parameters) are shortened
MAX_STEM = 120


def paths(problem: Problem, directory: Path | None = None) -> tuple[Path, Path]:
    """The .npz and .json files of ``problem``'s reference.

    The stem lists every parameter (``k=v,...``); when that is longer than
    ``MAX_STEM`` characters (file systems stop at 255), it lists the parameters
    that differ from their defaults, as many as fit in ``MAX_STEM`` (a set that
    changes most of them, such as a perturbed one, lists the first few),
    followed by a hash of all of them. The problem's name and each ``k=v`` are
    made file names by :func:`~integrator_bench.harness.paths.file_name` (an FMU
    variable named ``../../x`` is ``%2E.%2F..%2Fx``), and both files are checked
    to lie inside ``directory`` (:func:`~integrator_bench.harness.paths.inside`).
    """
    directory = inside(directory or home(problem), file_name(problem.name))
    stem = file_stem(problem)
    return inside(directory, f"{stem}.npz"), inside(directory, f"{stem}.json")


def home(problem: Problem) -> Path:
    """Where ``problem``'s references are kept when no folder is given: ``REFERENCE_DIR``
    for the project's own problems (and any not from the registry), ``PLUGIN_REFERENCE_DIR``
    for a problem a plugin registered (its class's ``origin`` is not the project's), so
    that a checkout's committed ``results/reference/`` holds the project's alone."""
    from integrator_bench.harness.matrix.registry import BUILT_IN

    origin = getattr(problem, "origin", BUILT_IN)
    return REFERENCE_DIR if origin == BUILT_IN else PLUGIN_REFERENCE_DIR


def file_stem(problem: Problem) -> str:
    """The file name (without suffix) of ``problem``'s parameters, as :func:`paths`
    describes it: one of its own for each parameter set, within ``MAX_STEM`` characters."""
    params = problem.key_params()
    items = {k: file_name(f"{k}={format_value(v)}") for k, v in sorted(params.items())}
    stem = ",".join(items.values()) or "default"
    if len(stem) > MAX_STEM:
        defaults = {p.name: p.default for p in problem.parameters}
        changed = ""
        for k, item in items.items():
            if params[k] != defaults.get(k) and len(changed) + len(item) + 1 <= MAX_STEM:
                changed = f"{changed},{item}" if changed else item
        digest = hashlib.sha256(json.dumps(params, sort_keys=True).encode()).hexdigest()
        stem = f"{changed or 'default'}-{digest[:10]}"
    return stem


def _checksum(t, Y) -> str:
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(t, float).tobytes())
    h.update(np.ascontiguousarray(Y, float).tobytes())
    return h.hexdigest()


def solve_canonical(problem: Problem, formulation: str, integrator: str, rtol: float):
    """Canonical components at the output times from one tight run, and its events.

    Returns
    -------
    Y : ndarray, shape (m, n_canonical)
    events : list of (float, str, ndarray)
        The Solution's events, each with the canonical state right after it.
    """
    system = problem.formulate(formulation)
    icls = registry.get_integrator(integrator)
    try:
        system = convert(system, icls)
    except Unsupported as exc:
        raise ReferenceFailure(f"{problem.name}/{formulation}: {exc}") from None
    sol = icls().solve(system, rtol=rtol, atol=system.atol(rtol))
    if not sol.success or sol.t.size != system.t_eval.size:
        if sol.status is Status.OVER_BUDGET:
            raise ReferenceOverBudget(f"{integrator} on {problem.label()} {sol.message}")
        raise ReferenceFailure(f"{integrator} failed on {problem.label()}: {sol.message}")
    return np.asarray(system.output(sol.t, sol.y), float), canonical_events(system, sol.events)


def canonical_events(system, events) -> list[tuple[float, str, np.ndarray]]:
    """A Solution's ``events`` with each state mapped to canonical components."""
    return [(float(t), str(name),
             np.asarray(system.output(np.array([t]), np.asarray(y, float)[None, :]), float)[0])
            for t, name, y in events]


def _family(integrator: str) -> str:
    """Whose code locates the integrator's events (its declared ``event_locator``)."""
    return registry.get_integrator(integrator).event_locator


def _event_meta(problem: Problem, events: list, check: list, what: str) -> dict:
    """The metadata of a reference's event sequence ``events``, checked against
    ``check`` (see the module docstring)."""
    try:
        agree = event_time_digits(check, events, problem.t_span[1] - problem.t_span[0])
    except ValueError as exc:
        raise ReferenceFailure(f"{problem.label()}: {what}: {exc}") from None
    return {"events": [[t, name] for t, name, _ in events],
            "event_states": [[float(x) for x in y] for _, _, y in events],
            "event_digits": float(np.round(agree, 2))}


def methods_of(problem: Problem, tighten: float = 1.0) -> list[tuple] | None:
    """The problem's reference methods ``(formulation, integrator, rtol)`` with each
    rtol times ``tighten`` (never below :data:`TIGHTEST`); None when ``tighten``
    changes none of them (they are at the tightest already)."""
    methods = list(getattr(problem, "reference_methods", DEFAULT_METHODS))
    tighter = [(f, i, max(r * tighten, TIGHTEST)) for f, i, r in methods]
    return None if tighten != 1.0 and tighter == methods else tighter


def compute(problem: Problem, tighten: float = 1.0) -> Reference:
    """Compute a reference, its agreement digits and, for a problem with state
    events, its event sequence and their agreement (not stored); ``tighten``
    scales the rtols of its methods (:func:`methods_of`). A problem scored on
    components of the user's (``score=``) has the reference of the problem
    without it (:meth:`~integrator_bench.problems.base.Problem.unscored`)."""
    problem = problem.unscored()
    t = problem.t_eval
    methods = methods_of(problem, tighten) or methods_of(problem)
    exact = problem.exact(t)
    if exact is not None:
        Y = np.asarray(exact, float)
        exact_check = getattr(problem, "exact_check", EXACT_CHECK)   # a problem may name its own
        check, check_events = solve_canonical(problem, *exact_check)
        used = [{"method": "exact"}, dict(zip(("formulation", "integrator", "rtol"), exact_check))]
        has_events = bool(problem.formulate(exact_check[0]).events)
        exact_events = getattr(problem, "exact_events", None)
        if has_events and exact_events is None:
            raise ReferenceFailure(f"{problem.label()}: an exact problem with events must "
                                   "give exact_events()")
        events = exact_events() if has_events else []
        what = f"exact events against {exact_check[1]}"
    else:
        (fa, ia, ra), (fb, ib, rb) = methods[:2]
        has_events = bool(problem.formulate(fa).events)
        if has_events and _family(ia) == _family(ib):
            raise ReferenceFailure(
                f"{problem.label()}: reference methods {ia} and {ib} are of one integrator "
                f"family of event location ({_family(ia)}); a problem with events needs two")
        Y, events = solve_canonical(problem, fa, ia, ra)
        check, check_events = solve_canonical(problem, fb, ib, rb)
        used = [dict(formulation=f, integrator=i, rtol=r) for f, i, r in methods[:2]]
        what = f"events of {ia} against {ib}"
    err = problem.component_index(problem.error_components)
    digits = agreement_digits(check, Y, problem.atol_scale_vector())
    meta = {
        "problem": problem.name,
        "params": problem.params,
        "label": problem.label(),
        "fingerprint": problem.fingerprint(),
        "methods": used,
        "agreement_digits": dict(zip(problem.components, map(float, np.round(digits, 2)))),
        "claimed_digits": int(np.floor(digits[err].min())),
        "code_version": code_version(),
        "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "checksum": _checksum(t, Y),
        "final": dict(zip(problem.components, map(float, Y[-1]))),
    }
    if has_events:
        meta.update(_event_meta(problem, events, check_events, what))
    return Reference(t, Y, meta)


def claimed_digits(ref: Reference, problem: Problem) -> int:
    """The digits ``ref`` claims on ``problem``'s error components: its stored
    claim (taken on the declared ones), or for a problem scored on components of
    the user's (``score=``) the floor of the least agreement among those."""
    if problem.score is None:
        return int(ref.meta["claimed_digits"])
    agree = ref.meta["agreement_digits"]
    return int(np.floor(min(agree[c] for c in problem.error_components)))


def save(ref: Reference, problem: Problem, directory: Path | None = None) -> None:
    """Write the reference's data and metadata, each to a temporary file first and
    then renamed into place (atomically, ``os.replace``), the metadata (with the
    data's checksum) last: an interrupted save leaves the old files or the new
    ones, never half a file. The temporary names are unique to the save
    (:func:`~integrator_bench.harness.paths.write_atomically`), so two processes
    saving one reference at once do not write into, or rename away, each other's."""
    npz, js = paths(problem, directory)
    _verified.pop((npz, js), None)
    npz.parent.mkdir(parents=True, exist_ok=True)

    def write_npz(part):
        with open(part, "wb") as f:
            np.savez(f, t=ref.t, Y=ref.Y)

    write_atomically(npz, write_npz)
    write_atomically(js, lambda part: part.write_text(
        json.dumps(ref.meta, indent=1, sort_keys=True) + "\n"))


def compute_within(problem: Problem, seconds: float | None, report=None,
                   tighten: float = 1.0) -> Reference:
    """:func:`compute` (``tighten`` as it takes it) with its solves stopped past
    ``seconds`` wall seconds in all (None: no limit): past it a
    :class:`ReferenceFailure` naming the limit. ``report(t, percent, elapsed)`` is
    called every 2 s with the progress of the solve under way
    (:class:`~integrator_bench.integrators.driver.Budget`)."""
    if seconds is None:
        return compute(problem, tighten)
    with budgeted(Budget(seconds, report=report)):
        try:
            return compute(problem, tighten)
        except ReferenceOverBudget as exc:
            raise ReferenceOverBudget(f"reference not computed within its limit of "
                                      f"{seconds:g} s ({exc})") from None


def read(problem: Problem, directory: Path | Handed | None = None
         ) -> tuple[Reference | None, str]:
    """The stored reference, or (None, why it cannot be used).

    With ``directory`` None: the one in ``REFERENCE_DIR``, else the one shipped
    with the package (``SHIPPED_REFERENCE_DIR``, absent in a checkout). With a
    :class:`Handed` reference: that one (:meth:`Handed.read`), nothing from disk.
    """
    if isinstance(directory, Handed):
        return directory.read(problem)
    ref, why = _read(problem, directory)
    if directory is None and why == NOT_STORED and SHIPPED_REFERENCE_DIR is not None:
        return _read(problem, SHIPPED_REFERENCE_DIR)
    return ref, why


# (npz, json) -> (their stat signature, Reference): each file read and verified once per
# process, and by a forked worker not at all (it inherits the runner's, read beforehand)
_verified: dict = {}


# what reading a damaged .npz (a zip archive of .npy files) or .json can raise
_UNREADABLE = (OSError, ValueError, KeyError, EOFError, TypeError, zipfile.BadZipFile)


def _read_files(npz: Path, js: Path) -> tuple[dict, np.ndarray, np.ndarray]:
    """The metadata and the t and Y arrays of a stored reference, or one of
    :data:`_UNREADABLE` when a file is damaged (a flipped byte, a cut download)."""
    meta = json.loads(js.read_text())
    if not isinstance(meta, dict):
        raise ValueError(f"{js.name} holds a {type(meta).__name__}, not an object")
    with np.load(npz, allow_pickle=False) as data:
        t, Y = data["t"], data["Y"]
    return meta, t, Y


def _read(problem: Problem, directory: Path | None) -> tuple[Reference | None, str]:
    ref, why = _files(problem, directory)
    if ref is None:
        return None, why
    if ref.meta.get("fingerprint") != problem.fingerprint():
        return None, "the problem definition changed since the reference was computed"
    return Reference(ref.t, ref.Y, dict(ref.meta)), ""


def _files(problem: Problem, directory: Path | None) -> tuple[Reference | None, str]:
    """The stored reference of ``problem``'s name and parameters with its data
    verified against its checksum (once per process while its files are
    unchanged), or (None, why not); its fingerprint is not checked (no call of
    the model)."""
    npz, js = paths(problem, directory)
    try:
        signature = tuple((st.st_mtime_ns, st.st_ctime_ns, st.st_size, st.st_ino)
                          for st in (npz.stat(), js.stat()))
    except OSError:
        return None, NOT_STORED
    cached = _verified.get((npz, js))
    if cached is not None and cached[0] == signature:  # unchanged files, checksum verified
        return cached[1], ""
    try:
        meta, t, Y = _read_files(npz, js)
    except _UNREADABLE as exc:  # a damaged file: as unusable as a failed checksum
        return None, f"stored files cannot be read ({type(exc).__name__}: {exc})"
    if _checksum(t, Y) != meta.get("checksum"):
        return None, "stored data does not match its checksum"
    t.flags.writeable = Y.flags.writeable = False  # shared by every later reader
    _verified[(npz, js)] = (signature, Reference(t, Y, meta))
    return _verified[(npz, js)][1], ""


def stored(problem: Problem, directory: Path | None = None) -> tuple[Reference | None, str]:
    """:func:`read` without the check of the problem's fingerprint: the files
    stored under ``problem``'s name and parameters, verified against their
    checksum, read into this process once (a forked worker inherits them).
    Calls none of the model's code: what the command's own process reads once
    the fingerprint was checked in a process of its own
    (:mod:`~integrator_bench.harness.run.model_calls`); whoever uses the
    reference checks the fingerprint (the case's worker does)."""
    ref, why = _files(problem, directory)
    if directory is None and why == NOT_STORED and SHIPPED_REFERENCE_DIR is not None:
        ref, why = _files(problem, SHIPPED_REFERENCE_DIR)
    return (None, why) if ref is None else (Reference(ref.t, ref.Y, dict(ref.meta)), "")


def load(problem: Problem, directory: Path | Handed | None = None,
         compute_missing: bool = True, limit: float | None = None, report=None) -> Reference:
    """The reference for ``problem``; recomputed (within ``limit`` wall seconds,
    :func:`compute_within`, ``report`` its progress) and stored when stale or
    missing, with a warning when it was stale (never for a :class:`Handed` one:
    ReferenceFailure, as without ``compute_missing``)."""
    ref, why = read(problem, directory)
    if ref is not None:
        return ref
    if not compute_missing or isinstance(directory, Handed):
        raise ReferenceFailure(f"{problem.label()}: {why}")
    if why != NOT_STORED:
        warnings.warn(f"reference for {problem.label()} recomputed: {why}", stacklevel=2)
    ref = compute_within(problem, limit, report)
    save(ref, problem, directory)
    return ref


def check(problem: Problem, directory: Path | None = None) -> tuple[bool, str]:
    """Recompute and compare with what the stored metadata claims.

    Fails when the stored reference is unusable, when the recomputed methods
    agree to fewer digits than claimed, or when the stored data and the
    recomputation differ by more than the claim. For a reference with events,
    also when the recomputed event sequence differs from the stored one in count
    or kinds, or when the recomputed runs' event times, or the stored against
    the recomputed ones, agree to fewer digits than the floor of the stored
    ``event_digits``.
    """
    problem = problem.unscored()
    ref, why = read(problem, directory)
    if ref is None:
        return False, why
    new = compute(problem)
    claim = ref.meta["claimed_digits"]
    err = problem.component_index(problem.error_components)
    now = new.meta["claimed_digits"]
    stored_vs_new = float(agreement_digits(new.Y[:, err], ref.Y[:, err],
                                           problem.atol_scale_vector()[err]).min())
    ok = now >= claim and stored_vs_new >= claim
    text = (f"claimed {claim} digits; recomputed methods agree to {now}, "
            f"stored vs recomputed {stored_vs_new:.1f}")
    if ref.has_events or new.has_events:
        event_ok, event_text = _check_events(problem, ref, new)
        ok, text = ok and event_ok, f"{text}; {event_text}"
    return ok, text


def _check_events(problem: Problem, ref: Reference, new: Reference) -> tuple[bool, str]:
    """Whether the recomputed event sequence keeps the stored claim, and why."""
    span = problem.t_span[1] - problem.t_span[0]
    claim = int(np.floor(ref.meta.get("event_digits", 0.0)))
    try:
        stored_vs_new = event_time_digits(new.events, ref.events, span)
    except ValueError as exc:
        return False, f"events: stored vs recomputed: {exc}"
    now = new.meta.get("event_digits", 0.0)
    return (now >= claim and stored_vs_new >= claim,
            f"{len(ref.events)} events, claimed {claim} digits in time; recomputed runs "
            f"agree to {now:.1f}, stored vs recomputed {stored_vs_new:.1f}")
