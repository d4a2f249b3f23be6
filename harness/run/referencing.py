"""A run's references made ready before its cases start: every problem given its
reference, or the reason it has none (:func:`prepare_references`), and the record of
a case left without one (:func:`no_reference_record`).

Every model's code runs outside the command's process, through
:mod:`~integrator_bench.harness.run.model_calls`.
"""

from __future__ import annotations

import dataclasses
import functools
import time

from integrator_bench.harness.errors import ModelFault, ReferenceFailure
from integrator_bench.harness.forking import child, in_parallel
from integrator_bench.harness.forking.budget import DEFAULT_MEMORY_MB
from integrator_bench.harness.matrix.line import ProblemSpec
from integrator_bench.harness.matrix.record import NO_REFERENCE, CaseStatus
from integrator_bench.harness.measure import references
from integrator_bench.harness.run import model_calls
from integrator_bench.harness.run.execution import MESSAGE_CHARS, base_record, finish
from integrator_bench.harness.run.streams import stdout_to_stderr
from integrator_bench.problems.base import ProblemError


@dataclasses.dataclass(frozen=True)
class Missing:
    """Why a problem has no reference (:func:`prepare_references`), and what its
    cases are recorded as: ``error``, or ``crashed`` / ``timeout`` when its
    model crashed or hung while the reference was checked or computed
    (:class:`~integrator_bench.harness.errors.ModelFault`)."""

    why: str
    status: str = CaseStatus.ERROR.value


#: what a fault's message says the model was doing while a stored reference was checked
CHECKING = "its stored reference was checked (the fingerprint probe)"


def prepare_references(cases, reference_dir=None, log=None,
                       limit: float | None = references.REFERENCE_TIMEOUT, jobs: int = 1,
                       deadline: float | None = None,
                       memory_mb: float | None = DEFAULT_MEMORY_MB,
                       build=ProblemSpec.build) -> dict:
    """Make sure the problem of every case of ``cases`` has a usable reference.

    Every model's code runs outside this process
    (:mod:`~integrator_bench.harness.run.model_calls`, each call within ``limit``
    CPU seconds and the backstops of a case's budget, its address space capped
    at ``memory_mb``): the stored references are checked against their
    problems' fingerprints one after the other in one forked process, then
    read here without calling the model
    (:func:`~integrator_bench.harness.measure.references.stored`), so that the
    workers forked later inherit them. A missing or stale one is computed within
    ``limit`` wall seconds (None: no limit) and, with a ``deadline`` (a
    ``time.monotonic()`` value), within what is left of it when its computation
    starts; its progress logged every 2 s; one that cannot be computed within
    that (or at all) is not stored. Several are computed side by side, ``jobs``
    at a time (:func:`~integrator_bench.harness.forking.in_parallel`), each in
    a process of its own: the perturbed parameter sets of an advice, a sweep of
    new parameter sets. ``build(spec)`` gives each problem (default: built here;
    a session's, built once).

    Returns
    -------
    dict
        The case's spec (:class:`~integrator_bench.harness.matrix.line.ProblemSpec`) ->
        :class:`Missing`, for those that have no reference.
    """
    seen, problems = set(), []
    for case in cases:
        if case.spec in seen or case.settled:
            continue
        seen.add(case.spec)
        problems.append((case.spec, build(case.spec)))
    checked = child.calls(
        [functools.partial(_unusable, problem, reference_dir) for _, problem in problems],
        CHECKING, limit, memory_mb, expected=(ProblemError,))
    missing, todo = {}, []
    for (key, problem), why in zip(problems, checked):
        if isinstance(why, Exception):
            missing[key] = _missing(problem, why, log)
        elif why:
            todo.append((key, problem, why))
        else:
            references.stored(problem, reference_dir)   # read here: inherited by the workers
    calls = [functools.partial(_reference, problem, why, reference_dir, limit, log, deadline,
                               memory_mb)
             for _, problem, why in todo]
    with stdout_to_stderr():  # C solvers' messages never among the records
        whys = in_parallel(calls, jobs)
    missing.update({key: why for (key, _, _), why in zip(todo, whys) if why is not None})
    return missing


def _unusable(problem, reference_dir) -> str:
    """Why ``problem``'s stored reference cannot be used ("" when it can): what the
    fingerprint probe says, in the process :func:`prepare_references` forks."""
    return references.read(problem, reference_dir)[1]


def _missing(problem, exc: Exception, log) -> Missing:
    """The :class:`Missing` of a problem whose reference failed with ``exc``,
    logged."""
    status = getattr(exc, "status", CaseStatus.ERROR.value)
    if log:
        log(f"ibench: no reference for {problem.label()}: {exc}; its cases are "
            f"recorded {status} (reason {NO_REFERENCE}), not run")
    return Missing(str(exc), status)


def reference_progress(problem, why: str, limit: float | None, log):
    """Log (when ``log`` is given) that ``problem``'s reference is computed, and
    why; return the ``report(t, percent, elapsed)`` that logs its progress
    (:func:`~integrator_bench.harness.measure.references.compute_within`)."""
    limit_text = "" if limit is None else f", limit {limit:g} s"
    if log:
        log(f"computing reference for {problem.label()} ({why}{limit_text})")

    def report(t, percent, elapsed, label=problem.label()):
        if log:
            log(f"  reference for {label}: t={t:.6g} ({percent:.3g} % of the span) "
                f"after {elapsed:.0f} s{limit_text}")
    return report


def _reference(problem, why: str, reference_dir, limit, log, deadline=None,
               memory_mb=DEFAULT_MEMORY_MB) -> Missing | None:
    """Compute and store ``problem``'s reference in a process of its own
    (:func:`prepare_references`): None when done, else why it has none."""
    if deadline is not None:
        left = deadline - time.monotonic()
        if left <= 0:
            return Missing(f"not computed: no time left ({why})")
        limit = left if limit is None else min(limit, left)
    try:
        model_calls.reference(problem, reference_dir, limit, memory_mb=memory_mb,
                              progress=lambda why: reference_progress(problem, why, limit, log))
    except (ReferenceFailure, ProblemError, ModelFault) as exc:
        # no reference, no start to have one from, or a model that failed
        return _missing(problem, exc, log)
    return None


def no_reference_record(case, missing: Missing) -> dict:
    """The record of a case whose problem has no reference: reason
    ``no_reference``, status ``error`` (``crashed`` or ``timeout`` when its model
    crashed or hung), nothing run."""
    return finish(base_record(case), CaseStatus(missing.status),
                  f"not run: no reference for the problem ({missing.why})"[:MESSAGE_CHARS],
                  NO_REFERENCE)

