"""Tables as text: the one Markdown renderer, and the terminal's plain table.

Every Markdown table the harness writes (the report's per-problem tables and
index, the formulation comparison, the runs' provenance) goes through
:func:`markdown_lines`; ``ibench list`` prints :func:`text_table`. Callers
format their values (digits, units) and hand over the cells.
"""

from __future__ import annotations

NULL = "–"  # a missing value (None, NaN, empty) in a Markdown cell


def _md_cell(value) -> str:
    empty = isinstance(value, str) and not value
    nan = isinstance(value, float) and value != value
    if value is None or empty or nan:
        return NULL
    return _md_text(value)


def _md_text(value) -> str:
    """One line, with the pipes that would end the cell escaped."""
    return " ".join(str(value).splitlines()).replace("|", r"\|")


def markdown_lines(header, rows, right=()) -> list[str]:
    """The lines of a GitHub-flavoured Markdown table.

    Parameters
    ----------
    header : sequence
        Column titles (an empty title stays empty).
    rows : iterable of sequences
        Cells, one sequence per row; a cell is written with ``str`` on one
        line, ``|`` escaped; None, NaN and ``""`` become ``–``.
    right : collection
        Column indexes or titles to right-align (numbers); the others are
        left-aligned.

    Returns
    -------
    list of str
        The header line, the alignment line and one line per row.
    """
    header = list(header)
    align = ["---:" if i in right or title in right else "---"
             for i, title in enumerate(header)]
    lines = ["| " + " | ".join(_md_text(h) for h in header) + " |",
             "|" + "|".join(align) + "|"]
    lines += ["| " + " | ".join(_md_cell(c) for c in row) + " |" for row in rows]
    return lines


def markdown_table(header, rows, right=()) -> str:
    """:func:`markdown_lines` joined, ending with a newline."""
    return "\n".join(markdown_lines(header, rows, right)) + "\n"


def text_table(header, rows) -> str:
    """A plain table for a terminal: columns padded to their widest cell, two
    spaces apart, no trailing spaces."""
    header = [str(h) for h in header]
    rows = [[str(c) for c in row] for row in rows]
    widths = [max([len(h)] + [len(r[i]) for r in rows]) for i, h in enumerate(header)]
    return "\n".join("  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip()
                     for r in [header] + rows)
