"""The report's Markdown: ``<slug>.md`` per problem and ``index.md``.

Renders the parts (:mod:`integrator_bench.harness.report.document`) whose
``formats`` include ``"md"``; every table goes through
:func:`integrator_bench.harness.tables.markdown_lines`. A part is
``## title``, its caption, then its blocks (``### title``, paragraphs, bullet
items, ``![alt](figure)``, tables). ``index.md`` gathers the ``in_index``
parts of every section under one heading each, a ``###`` subsection per problem.

Names come from plugins, FMUs and users: outside code spans ``<``, ``>`` and ``&``
are written as character references (:func:`escaped`), so a name such as
``<script>`` shows as text wherever the Markdown is rendered, never as HTML.
"""

from __future__ import annotations

import re

from integrator_bench.harness.report.document import (
    Answer, Block, Cell, Part, ProblemInfo, ProblemSection, Report, Table)
from integrator_bench.harness.tables import markdown_lines

TITLE = "Integrator benchmark report"
#: a code span (CommonMark 0.31, sect. 6.1: a run of backticks, then the same run)
_CODE_SPAN = re.compile(r"(`+)(?:(?!\1).)*?\1", re.S)
_HTML = str.maketrans({"&": "&amp;", "<": "&lt;", ">": "&gt;"})


def escaped(text: str) -> str:
    """``text`` with ``&``, ``<`` and ``>`` outside code spans as ``&amp;``,
    ``&lt;`` and ``&gt;`` (inside a code span they show as written anyway)."""
    out, end = [], 0
    for m in _CODE_SPAN.finditer(text):
        out += [text[end:m.start()].translate(_HTML), m.group(0)]
        end = m.end()
    return "".join(out) + text[end:].translate(_HTML)


def cell(value):
    """A cell's Markdown: a link ``[text](href)``, code in backticks, else the value."""
    if not isinstance(value, Cell):
        return value
    if value.href:
        return f"[{value.text}]({value.href})"
    return f"`{value.text}`" if value.code else value.text


def table(t: Table) -> list[str]:
    return markdown_lines(t.header, ([cell(c) for c in row] for row in t.rows), t.right)


def block(b: Block, level: str = "###") -> list[str]:
    lines = [f"{level} {b.title}", ""] if b.title else []
    if b.figure:
        lines += [f"![{b.alt}]({b.figure})", ""]
    for text in b.text:
        lines += [text, ""]
    if b.items:
        lines += [f"- {item}" for item in b.items] + [""]
    for t in b.tables:
        lines += table(t) + [""]
    return lines


def body(part: Part, level: str = "###") -> list[str]:
    """The blocks of a part, or its ``empty`` text."""
    if not part.blocks:
        return [part.empty, ""]
    return [line for b in part.blocks for line in block(b, level)]


def part(p: Part, level: str = "##") -> list[str]:
    if "md" not in p.formats or not p.shown:
        return []
    head = [f"{level} {p.title}", ""] + ([p.caption, ""] if p.caption else [])
    return head + body(p, level + "#")


def answer_line(a: Answer) -> str:
    """The answer line: the cheapest line to the target (or the tie), its CPU, the
    tolerance at the crossing and its margin over the runner-up
    (:meth:`Answer.sentence`)."""
    return f"Answer: {a.sentence(strong=lambda t: f'**{t}**')}."


def info(i: ProblemInfo) -> list[str]:
    if i.error and not i.description:
        lines = [f"({i.error})"]
    else:
        lines = [i.description, f"Source: {i.source}",
                 f"Dimension: {i.dimension}; time span: {i.time_span}; formulations (system "
                 f"kind, index): {', '.join(i.formulations) or i.error}."]
    if i.stiffness:
        lines.append(f"Stiffness: {i.stiffness}")
    return [x for line in lines for x in (line, "")]


def problem_page(s: ProblemSection) -> str:
    """The ``<slug>.md`` of one section: the answer on top, then the description
    and the parts (the figure first)."""
    lines = [f"# {s.title}", "", answer_line(s.answer), ""] + info(s.info)
    for p in s.parts:
        lines += part(p)
    return escaped("\n".join(lines).rstrip("\n") + "\n")


def index(r: Report) -> str:
    """``index.md``: the parts before, the gathered ``in_index`` parts, the parts after."""
    lines = [f"# {TITLE}", ""]
    if not r.n_records:
        lines += ["No records.", ""]
    else:
        lines += [r.count_text(), ""]
    for p in r.before:
        lines += part(p)
    keys = dict.fromkeys(p.key for s in r.sections for p in s.parts
                         if p.in_index and "md" in p.formats)
    for key in keys:
        found = [(s, p) for s in r.sections for p in s.parts if p.key == key and p.shown]
        if not found:
            continue
        first = found[0][1]
        lines += [f"## {first.title}", ""] + ([first.caption, ""] if first.caption else [])
        for s, p in found:
            lines += [f"### {s.title}", ""] + body(p, "####")
    for p in r.after:
        lines += part(p)
    return escaped("\n".join(lines).rstrip("\n") + "\n")
