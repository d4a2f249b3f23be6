"""The report as data: the types the builders make and the renderers walk.

A :class:`Report` holds a :class:`ProblemSection` per problem and parameter
set, and the parts before and after them. A :class:`Part` is a titled piece
(a caption, the names of the metrics it defines, :class:`Block` s of text,
figures and :class:`Table` s of text or :class:`Cell` s); an :class:`Appendix` is a part
drawn from above the report with its own document. The builders are in
:mod:`~integrator_bench.harness.report.sections`; the renderers,
:mod:`~integrator_bench.harness.report.markdown` and
:mod:`~integrator_bench.harness.report.html`, know these types only.
"""

from __future__ import annotations

import dataclasses

import pandas as pd

from integrator_bench.harness.ranking.reach import TARGETS, tag
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
class Appendix:
    """A part a package above the report draws from the records, shown after the
    sections, and a Markdown document of its own written beside ``index.md`` (the
    sources' part and ``sources.md``:
    :func:`integrator_bench.harness.sources.page.appendix`); no document when
    ``text`` is empty."""

    part: Part
    file: str
    text: str


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
    settings, and ``formulation``; None: no line reaches it), and how sure that is:
    a winner only when the noise cannot reverse it, else a tie
    (:func:`~integrator_bench.harness.ranking.reach.cheapest`)."""

    target: float
    label: str | None = None
    formulation: str | None = None
    cpu_s: float | None = None
    #: ``winner``, ``tie`` or ``unmeasured`` (harness/ranking/margin.py verdict)
    verdict: str = ""
    #: the answer's lines in words: ``A (ode)``, or ``tie: A (ode), B (ode)``
    lines: str = ""
    #: the margin in words: ``margin 1.3, 95 % 1.2-1.4``, ``only line``, ``runner-up 3.1x``
    why: str = ""
    #: which tied lines run one library code: ``"; A (ode) and B (ode) are one code, C"``
    same: str = ""
    #: the margin for the answers' table: ``1.3x (95 % 1.2-1.4)``, ``only line``
    short: str = ""
    #: how the target was reached (reach.HOW): "at most" is shown ``≤``
    how: str = ""
    #: the tolerance at the crossing, as ``rtol 3.2e-07`` or ``h 0.001``
    at: str = ""
    #: the error measured, in words (reach.measure_text)
    measure: str = "error"
    #: what ``cpu_s`` is (harness/ranking/cost.py COSTS): the CPU, or the method's work
    cost: str = "cpu"

    def cpu_text(self) -> str:
        """``≤ 0.00074 s CPU at rtol 0.001`` or ``0.0021 s CPU at rtol 3.2e-07``
        (``s work`` when the answer ranks by the method's work)."""
        at = f" at {self.at}" if self.at and self.at != NULL else ""
        return (f"{'≤ ' if self.how == 'at most' else ''}{self.cpu_s:.3g} s "
                f"{WORD[self.cost]}{at}")

    def margin(self) -> str:
        """The margin for the answers' table: ``1.3x (95 % 1.2-1.4)``, ``tie, 1.04x
        (95 % 0.91-1.19)``, ``only line``, ``runner-up 3.1x`` (``""`` when no line
        reaches the target)."""
        if self.cpu_s is None:
            return ""
        return f"tie, {self.short}" if self.verdict == "tie" else self.short

    def sentence(self, strong=None, plain=None) -> str:
        """The answer line after ``Answer:``, markdown and HTML alike: the line or the
        tie, its CPU (the cheapest's, by its median), the margin and what the noise
        lets be said. ``strong`` marks the answer's lines (markdown ``**``, HTML
        ``<b>``) and ``plain`` escapes the rest (HTML); both default to the text as is."""
        strong = strong or (lambda t: t)
        plain = plain or (lambda t: t)
        what = plain(f"an error of {tag(self.target)} ({self.measure})")
        if self.cpu_s is None:
            return f"no line reaches {what} within its measured range"
        if self.verdict == "tie":
            return (f"a tie to reach {what}: {strong(self.lines.removeprefix('tie: '))}"
                    + plain(f"; the cheapest by its median, {self.label} ({self.formulation}), "
                            f"{self.cpu_text()}, {self.why}: within the noise of the timing, "
                            f"none of them is cheaper{self.same}"))
        return (f"cheapest to reach {what}: {strong(self.lines)}"
                + plain(f", {self.cpu_text()}, {self.why}{self.same}"))


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
    #: the records as stored of the group's undriven twin (a driven problem's
    #: parameters with its drive stopped: harness/report/driving.py), or None
    twin: pd.DataFrame | None = None
