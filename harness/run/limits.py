"""What one case may take, decided once by the command that runs it: :class:`Limits`.

The defaults live here and nowhere else: a case's CPU budget
(:data:`DEFAULT_BUDGET_S`), its timed solves
(:data:`~integrator_bench.harness.run.execution.MAX_SAMPLES`), its memory
(:data:`DEFAULT_MEMORY_MB`) and a missing reference's time
(:data:`~integrator_bench.harness.measure.references.REFERENCE_TIMEOUT`). A command
(:class:`~integrator_bench.harness.run.context.RunContext`) fills them from its
options and its preset; the workers that run the cases
(:mod:`~integrator_bench.harness.run.isolation`, the Dask tasks) take the one object.
"""

from __future__ import annotations

from dataclasses import dataclass

from integrator_bench.harness.forking.budget import DEFAULT_MEMORY_MB  # noqa: F401  (a Limits default; its users import it here)
from integrator_bench.harness.measure.references import REFERENCE_TIMEOUT
from integrator_bench.harness.run.execution import MAX_SAMPLES

DEFAULT_BUDGET_S = 60.0     # a case's budget, in CPU seconds of its worker


@dataclass(frozen=True)
class Limits:
    """What one case may take: the defaults of a command's cases, decided here only.

    Attributes
    ----------
    budget_s : float
        A case's budget, in CPU seconds of its worker (all its samples): a case
        past it is recorded ``timeout``
        (:class:`~integrator_bench.harness.run.isolation.Worker` for the
        backstops of a case that hangs). None given: :data:`DEFAULT_BUDGET_S`.
    repeat : int
        The most timed solves per case (fewer once they add up to
        :data:`~integrator_bench.harness.run.execution.MIN_CPU_S`). None given:
        :data:`~integrator_bench.harness.run.execution.MAX_SAMPLES`.
    memory_mb : float or None
        Address space in MiB a case may allocate on top of what its worker
        inherits (RLIMIT_AS); None for no limit.
    reference_timeout : float or None
        Wall seconds a missing reference may take to compute (None: no limit);
        the cases of a problem left without one are recorded ``error`` with
        reason ``no_reference``, not run.
    """

    budget_s: float = DEFAULT_BUDGET_S
    repeat: int = MAX_SAMPLES
    memory_mb: float | None = DEFAULT_MEMORY_MB
    reference_timeout: float | None = REFERENCE_TIMEOUT

    def __post_init__(self):
        # None stands for "not given": the command's option, or its preset's, left unset
        if self.budget_s is None:
            object.__setattr__(self, "budget_s", DEFAULT_BUDGET_S)
        if self.repeat is None:
            object.__setattr__(self, "repeat", MAX_SAMPLES)

    def budget_of(self, case) -> float:
        """``case``'s budget of CPU seconds: :attr:`budget_s`, or the case's own
        ``budget_s`` where that is less (a race bound, :mod:`~integrator_bench.harness.ranking.racing`)."""
        own = getattr(case, "budget_s", None)
        return self.budget_s if own is None else min(own, self.budget_s)
