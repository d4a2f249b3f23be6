"""The advice's answer as typed values, turned into its JSON object only at the edge.

:class:`Advice` is what :func:`~integrator_bench.harness.advise.advice.advise`
returns; :meth:`Advice.to_dict` is the ``--json`` object and ``advice.json``
(a contract: ``docs/advise.md`` and ``docs/command-line.md`` describe its keys),
and :mod:`.page` renders the same values as text and HTML. The lines of the
ranking (``lines``, ``winner``, ``runner_up``), the reference's facts, the
robustness check and the reproduction recipe are the certificate's parts
(:mod:`.evidence`), each turned into its JSON by its own ``to_dict``.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

from integrator_bench.harness.advise.evidence import (LineEntry, Reference, Reproduction,
                                                      Robustness)
from integrator_bench.harness.ranking.margin import Margin as _MarginText


@dataclass(frozen=True)
class Cost:
    """What the advice cost: from the command's start to the answer (references,
    search and robustness check; the CPU of this process and its workers), its
    cases and rounds, and the search's own wall and CPU seconds."""

    wall_s: float
    cpu_s: float
    cases: int
    search_cases: int
    robustness_cases: int
    rounds: int = 0
    search_wall_s: float = 0.0
    search_cpu_s: float = 0.0

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class Margin:
    """The runner-up's margin over the named line: the runner-up's CPU to the
    target over the named line's
    (:class:`~integrator_bench.harness.ranking.margin.Margin`: the medians of
    their paired samples, with the interval of that ratio at
    :data:`~integrator_bench.harness.ranking.margin.LEVEL`).

    Attributes
    ----------
    ratio : float or None
        The margin: of the paired samples' medians when there are any, else of
        the two lines' CPUs to the target (None: both are upper bounds, no
        ratio can be had).
    tie : bool
        The runner-up ties with the named line: it is not clearly slower, its
        interval reaching 1 or not measured (fewer than
        :data:`~integrator_bench.harness.ranking.margin.MIN_PAIRED` paired
        samples); False when it is clearly slower (its interval above 1) or out
        of contention (beyond :data:`~integrator_bench.harness.ranking.margin.BAND`).
    low, high : float or None
        The interval (None: not measured, or out of contention).
    paired : int
        The paired samples it rests on (0: out of contention, or no samples).
    line : str or None
        The runner-up, ``label (formulation)``.
    """

    ratio: float | None
    tie: bool
    low: float | None = None
    high: float | None = None
    paired: int = 0
    line: str | None = None

    @property
    def contended(self) -> bool:
        """Whether the runner-up was in contention (within the band): its margin
        was measured or could have been."""
        return self.tie or self.low is not None

    def text(self, over: bool = False) -> str:
        """``margin 1.04, 95 % 0.91-1.19`` as the report words it (with ``over``:
        ``margin 1.3 over B (ode), 95 % 1.2-1.4``;
        :meth:`integrator_bench.harness.ranking.margin.Margin.text`); ``margin
        1.3, interval not measured``; ``runner-up B (ode) at 3.1x`` out of
        contention."""
        if not self.contended:
            return f"runner-up {self.line} " + ("an upper bound too" if self.ratio is None
                                                 else f"at {self.ratio:.2g}x")
        measured = self.low is not None
        return _MarginText(self.line or "", math.nan if self.ratio is None else self.ratio,
                           self.low if measured else math.nan,
                           self.high if measured else math.nan, self.paired).text(over)

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class Contenders:
    """What timing the contenders again did before the advice answered
    (:func:`integrator_bench.harness.contend.rounds.settle`): the contests
    opened (0 or 1: the advice answers at one target), the records timed again,
    the blocks (processes) that timed them, their CPU seconds and the cap, why
    timing stopped, and whether the contest was left open; ``why`` says why
    nothing was timed (``--cost work``: the work has no noise; or the search
    left no record)."""

    contests: int = 0
    retimed: int = 0
    blocks: int = 0
    cpu_s: float = 0.0
    cap_s: float = 0.0
    stopped: str | None = None
    left_open: int = 0
    why: str | None = None

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class FamilyBest:
    """The best line of a family that reached the target: its ``label`` (the
    integrator with its changed settings, JSON ``integrator``), formulation, rtol
    and CPU."""

    label: str
    formulation: str
    rtol: float
    cpu_s: float

    def to_dict(self) -> dict:
        return {"integrator": self.label, "formulation": self.formulation, "rtol": self.rtol,
                "cpu_s": self.cpu_s}


#: an advice's statuses: a verified answer, a partial one (the budget ran out first),
#: none that held on every perturbed set, none at all
STATUSES = ("answer", "partial", "unverified", "none")


@dataclass(frozen=True)
class Asked:
    """What the answer answers, as it says it: the problem's label, the target and
    its measure, what lines are ranked by, the scored components and the budget."""

    problem: str
    target: float
    measure: str
    ranked_by: str
    scored: tuple
    budget_s: float


@dataclass(frozen=True)
class Advice:
    """One advice's answer (module docstring).

    Attributes
    ----------
    asked : Asked
    candidates : int
        Lines considered, the ruled-out ones included.
    ruled_out : tuple of RuledOut
        The lines ruled out before running, each with why
        (:class:`~integrator_bench.harness.advise.candidates.RuledOut`).
    status : str
        One of :data:`STATUSES`.
    cost : Cost
    why : str or None
        Why the answer is partial, unverified or none.
    reference : Reference or None
        The reference's verification (None: no good one, the advice stopped there).
    lines : tuple of LineEntry
        Every line of the search, best first (the certificate's entries).
    families : dict
        Family -> :class:`FamilyBest`.
    robustness : Robustness or None
        The robustness check (its perturbed sets, what was checked, why not).
    contenders : Contenders or None
        What timing the contenders again did (None: the search was not made).
    winner, runner_up : LineEntry or None
        Entries of ``lines`` (the winner's ``run`` at the rtol it held at): the
        line the advice names (the top line of the verdict, which in a tie is
        the cheapest by the medians) and the next cheapest line the verdict
        was taken over (:func:`~.certificate.verdict`).
    margin : Margin or None
        The runner-up's margin over the winner (None: no runner-up).
    verdict : str or None
        ``winner`` (every contender's interval lies above 1) or ``tie`` (some
        contender is not clearly slower, its interval reaching 1 or not
        measured: those lines are ``tied``); None without a winner
        (:func:`integrator_bench.harness.ranking.margin.verdict`).
    tied : tuple of str
        The lines in the tie, ``label (formulation)``, the winner first (empty
        unless the verdict is a tie).
    same_code : dict
        The library codes two or more of the tied lines run through different
        wrappers, each with its lines (``{"label", "formulation"}``):
        :func:`integrator_bench.harness.ranking.reach.same_code`.
    verified_sets : int or None
        Perturbed sets the winner held on (0 when it was not checked).
    reproduce : Reproduction or None
        What a user needs to get the winner's error outside the harness.
    """

    asked: Asked
    candidates: int
    ruled_out: tuple
    status: str
    cost: Cost
    why: str | None = None
    reference: Reference | None = None
    lines: tuple = ()
    families: dict | None = None
    robustness: Robustness | None = None
    contenders: Contenders | None = None
    winner: LineEntry | None = None
    runner_up: LineEntry | None = None
    margin: Margin | None = None
    verdict: str | None = None
    tied: tuple = ()
    same_code: dict = field(default_factory=dict)
    verified_sets: int | None = None
    reproduce: Reproduction | None = None

    def __post_init__(self):
        if self.status not in STATUSES:
            raise ValueError(f"status {self.status!r}; valid: {', '.join(STATUSES)}")

    def is_winner(self, entry: LineEntry) -> bool:
        """Whether ``entry`` (one of :attr:`lines`) is the winner's line."""
        return self.winner is not None and entry.key == self.winner.key

    def is_tied(self, entry: LineEntry) -> bool:
        """Whether ``entry`` (one of :attr:`lines`) is in the tie (the winner too)."""
        return entry.name in self.tied

    def is_runner_up(self, entry: LineEntry) -> bool:
        """Whether ``entry`` (one of :attr:`lines`) is the runner-up's line."""
        return self.runner_up is not None and entry.key == self.runner_up.key

    def to_dict(self) -> dict:
        """The ``--json`` object: its keys in the order they have always had, the
        newer ones (``contenders``; ``verdict``, ``tied`` and ``same_code``)
        after the key they belong with (an advice without a reference stops
        after ``cost``; one without a winner has no ``winner`` ... ``reproduce``)."""
        a = self.asked
        out = {"problem": a.problem, "target": a.target, "measure": a.measure,
               "ranked_by": a.ranked_by, "scored": list(a.scored), "budget_s": a.budget_s,
               "candidates": self.candidates, "ruled_out": [asdict(r) for r in self.ruled_out]}
        if self.reference is None:
            return {**out, "status": self.status, "cost": self.cost.to_dict(), "why": self.why}
        out.update(reference=self.reference.to_dict(), lines=[e.to_dict() for e in self.lines],
                   families={f: b.to_dict() for f, b in (self.families or {}).items()},
                   robustness=_dict_of(self.robustness), cost=self.cost.to_dict(),
                   contenders=_dict_of(self.contenders))
        if self.winner is not None:
            out.update(winner=self.winner.to_dict(), runner_up=_dict_of(self.runner_up),
                       margin=_dict_of(self.margin), verdict=self.verdict,
                       tied=list(self.tied), same_code=self.same_code,
                       verified_sets=self.verified_sets, reproduce=_dict_of(self.reproduce))
        out.update(status=self.status, why=self.why)
        return out


def _dict_of(part) -> dict | None:
    """``part.to_dict()``, or None for no part."""
    return None if part is None else part.to_dict()
