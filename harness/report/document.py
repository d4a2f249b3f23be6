"""The report as data: the types the builders make and the renderers walk.

A :class:`Report` holds a :class:`ProblemSection` per problem and parameter
set, and the parts before and after them. A :class:`Part` is a titled piece
(a caption, the names of the metrics it defines, :class:`Block` s of text,
figures and :class:`Table` s of text or :class:`Cell` s). The builders are in
:mod:`~integrator_bench.harness.report.sections`; the renderers,
:mod:`~integrator_bench.harness.report.markdown` and
:mod:`~integrator_bench.harness.report.html`, know these types only.
"""

from __future__ import annotations

import dataclasses

import pandas as pd

from integrator_bench.harness.ranking.reach import TARGETS
from integrator_bench.harness.report.ranking_text import WORD
from integrator_bench.harness.tables import NULL


@dataclasses.dataclass
class Cell:
    """A table cell with more than text: a hover ``title`` and a status class ``css``
    (HTML only), a link ``href`` to a file beside the page, or ``code``."""

    text: str
    title: str = ""
    css: str = ""
    href: str = ""
    code: bool = False


@dataclasses.dataclass
class Table:
    """Header and rows of text cells (str, None for a missing value, or :class:`Cell`);
    ``right`` names the right-aligned columns (indexes or titles); the page shows
    the first ``fold`` rows and folds the rest, and ``first_bold`` bolds row one."""

    header: list
    rows: list
    right: tuple = ()
    fold: int | None = None
    first_bold: bool = False


@dataclasses.dataclass
class Block:
    """A subsection: an optional ``title``, paragraphs, bullet ``items``, a figure
    file beside the page, interactive figures (``plots``: specifications of
    :mod:`~integrator_bench.harness.report.interactive`, drawn on the HTML page,
    the static ``figure`` then folded under them) and tables; ``folded``: closed
    under its title on the page."""

    title: str = ""
    text: list = dataclasses.field(default_factory=list)
    items: list = dataclasses.field(default_factory=list)
    figure: str = ""
    alt: str = ""
    tables: list = dataclasses.field(default_factory=list)
    folded: bool = False
    plots: list = dataclasses.field(default_factory=list)


@dataclasses.dataclass
class Part:
    """A titled part of a section; with no blocks it shows ``empty``, or nothing when
    that is empty too. The ``caption`` says in plain text what the part shows;
    ``defines`` names the page's metric definitions
    (:data:`integrator_bench.harness.report.html.DEFINITIONS`), which the page
    shows in place of the caption."""

    key: str
    title: str
    caption: str = ""
    defines: tuple = ()
    blocks: list = dataclasses.field(default_factory=list)
    empty: str = ""
    formats: tuple = ("md", "html")
    in_index: bool = False

    @property
    def shown(self) -> bool:
        return bool(self.blocks or self.empty)


@dataclasses.dataclass
class ProblemInfo:
    """What the registry says of a problem with the parameters that ran; ``error``
    when it could not be built (no longer registered, a file gone)."""

    description: str = ""
    source: str = ""
    dimension: str = NULL
    time_span: str = NULL
    formulations: list = dataclasses.field(default_factory=list)
    stiffness: str = ""
    error: str = ""


@dataclasses.dataclass
class Answer:
    """The cheapest line to reach ``target`` (``label``, the integrator with its
    settings, and ``formulation``; None: no line reaches it), and the lines that
    tie with it (``"label (formulation)"``; see
    :func:`~integrator_bench.harness.ranking.reach.tie`)."""

    target: float
    label: str | None = None
    formulation: str | None = None
    cpu_s: float | None = None
    ties: list = dataclasses.field(default_factory=list)
    spread_known: bool = True
    #: how the target was reached (reach.HOW): "at most" is shown ``≤``
    how: str = ""
    #: the tolerance at the crossing, as ``rtol 3.2e-07`` or ``h 0.001``
    at: str = ""
    #: the error measured, in words (reach.measure_text)
    measure: str = "error"
    #: the next line of the table that reaches the target, ``"label (formulation)"``
    #: ("" when no other line does), its CPU over the answer's (NaN when both are upper
    #: bounds), how sure that ratio is (reach.cpu_ratio: "=", "≥"; "" unknown) and
    #: whether it ties with the answer
    runner_up: str = ""
    ratio: float = float("nan")
    sure: str = ""
    runner_up_ties: bool = False
    #: what ``cpu_s`` is (harness/ranking/cost.py COSTS): the CPU, or the method's work
    cost: str = "cpu"

    def cpu_text(self) -> str:
        """``≤ 0.00074 s CPU at rtol 0.001`` or ``0.0021 s CPU at rtol 3.2e-07``
        (``s work`` when the answer ranks by the method's work)."""
        at = f" at {self.at}" if self.at and self.at != NULL else ""
        return (f"{'≤ ' if self.how == 'at most' else ''}{self.cpu_s:.3g} s "
                f"{WORD[self.cost]}{at}")

    def margin(self) -> str:
        """The answer's margin over the runner-up, short (the answers' table):
        ``1.8x`` (the runner-up takes 1.8 times its CPU; ``≥ 1.8x`` when the
        answer's CPU is an upper bound), ``tie``, ``only line`` or ``unknown``."""
        if self.cpu_s is None:
            return ""
        if not self.runner_up:
            return "only line"
        if self.runner_up_ties:
            return "tie"
        if self.ratio != self.ratio:
            return "unknown"
        return f"{'≥ ' if self.sure == '≥' else ''}{self.ratio:.2g}x"

    def margin_note(self) -> str:
        """The margin for the answer line: ``"; the runner-up, B (ode), takes 1.8x
        its CPU"``, that no other line reaches the target, or ``""`` (a tie:
        :meth:`tie_note` says it)."""
        if self.cpu_s is None or self.runner_up_ties:
            return ""
        if not self.runner_up:
            return "; no other line reaches it"
        if self.ratio != self.ratio:
            return (f"; the runner-up, {self.runner_up}, is an upper bound too: no margin "
                    "can be told")
        return f"; the runner-up, {self.runner_up}, takes {self.margin()} its CPU"

    def tie_note(self) -> str:
        """``"; a tie with B (ode), C (i3) ..."`` for the answer line, a note that
        the spread is unknown (no tie can be told), or ``""``."""
        if self.ties:
            return (f"; a tie with {', '.join(self.ties)} (CPU within their spread: none of "
                    "them is cheaper)")
        if not self.spread_known:
            return ("; its CPU spread is unknown (fewer than 4 timed solves: "
                    "--repeat 4 or more tells ties)")
        return ""


@dataclasses.dataclass
class ProblemSection:
    """One problem and parameter set: its files are ``<anchor>.png/.csv/.md``."""

    anchor: str
    title: str
    problem: str
    label: str
    rows: pd.DataFrame
    figure: str | None
    info: ProblemInfo
    answer: Answer
    parts: list


@dataclasses.dataclass
class Report:
    """The whole report: ``before`` and ``after`` the problems' sections."""

    n_records: int
    dropped: int
    sections: list
    before: list
    after: list
    #: records of advice runs, kept apart from the sections (sections.advice_part)
    apart: int = 0

    def count_text(self) -> str:
        """``12 records (0 superseded repeats dropped)``, and the advice's kept apart."""
        apart = (f"; {self.apart} records of ibench advise runs kept apart (Advice records)"
                 if self.apart else "")
        return f"{self.n_records} records ({self.dropped} superseded repeats dropped){apart}."


@dataclasses.dataclass
class Group:
    """What a part builder gets: a group's cleaned records, its target table
    (:func:`~integrator_bench.harness.ranking.reach.target_table`), the family
    of each (label, formulation), its figure and whether the Markdown keeps
    unsupported cases."""

    rows: pd.DataFrame
    ranked: pd.DataFrame
    families: dict
    figure: str | None
    off_axis: str = ""
    #: the interactive work-precision figure (interactive.work_precision), or None
    plot: dict | None = None
    include_unsupported: bool = False
    #: what the figure and the target table measure, in words (reach.measure_text)
    measure: str = ""
    #: the target errors of the table, loosest first; the answer is at the last
    targets: tuple = TARGETS
    #: what the figure, tables and answer rank by (harness/ranking/cost.py COSTS)
    cost: str = "cpu"
    #: the group's records as stored (``rows`` hold the cost ranked by in ``cpu_s``)
    stored: pd.DataFrame | None = None
