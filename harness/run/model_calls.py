"""A model's references, checked or computed outside the command's own process.

Whatever calls a problem's code -- its right-hand side, Jacobian, an FMU's C
functions, a plugin's problem -- before or beside the cases (the fingerprint
probe that checks a stored reference, a missing reference computed, the
stiffness analysis and the scheduler's stiffness bound) runs through
:func:`~integrator_bench.harness.forking.child.call` or
:func:`~integrator_bench.harness.forking.child.calls`: in a forked process, as a
case runs in its :class:`~integrator_bench.harness.run.isolation.Worker`, with the
same budget, memory cap and fault statuses (a
:class:`~integrator_bench.harness.errors.ModelFault`: ``the model crashed
(SIGSEGV) while its reference was computed``); the command goes on with its other
problems. :func:`reference` is a problem's reference so: read and checked, or
computed, in the child; stored from here.
"""

from __future__ import annotations

import functools
import warnings

from integrator_bench.harness.errors import ReferenceFailure
from integrator_bench.harness.forking.budget import DEFAULT_MEMORY_MB
from integrator_bench.harness.forking.child import call
from integrator_bench.harness.measure import references
from integrator_bench.problems.base import ProblemError


def reference(problem, directory=None, limit: float | None = None, progress=None,
              memory_mb: float | None = DEFAULT_MEMORY_MB, recompute: bool = False,
              what: str = "its reference was computed",
              tighten: float = 1.0) -> references.Reference:
    """``problem``'s reference: the stored one, its fingerprint checked, or (missing,
    stale, or with ``recompute``) one computed within ``limit`` wall seconds
    (:func:`~integrator_bench.harness.measure.references.compute_within`;
    ``progress(why)``, called once it is known why one is computed, gives the
    ``report`` of its progress), in a process of its own (:func:`call`, ``limit`` its CPU budget
    too); a computed one is stored from here, so a disk that cannot take it raises
    its OSError here, never as the model's fault. Raises ReferenceFailure,
    ProblemError or :class:`~integrator_bench.harness.errors.ModelFault`."""
    ref, why = call(functools.partial(_read_or_compute, problem, directory, limit, progress,
                                      recompute, tighten),
                    what, None if limit is None else max(limit, 1.0), memory_mb,
                    expected=(ReferenceFailure, ProblemError))
    if why is not None:
        if why not in (references.NOT_STORED, RECOMPUTE):
            warnings.warn(f"reference for {problem.label()} recomputed: {why}", stacklevel=2)
        references.save(ref, problem, directory)
    references.stored(problem, directory)   # read here once: inherited by forked workers
    return ref


#: why a reference asked to be recomputed is
RECOMPUTE = "asked to be recomputed"


def _read_or_compute(problem, directory, limit, progress, recompute: bool, tighten: float):
    """``(the stored reference, None)``, or ``(one computed, why)``: what the process
    of :func:`reference` does."""
    ref, why = (None, RECOMPUTE) if recompute else references.read(problem, directory)
    if ref is not None:
        return ref, None
    report = progress(why) if progress is not None else None
    return references.compute_within(problem, limit, report, tighten), why


