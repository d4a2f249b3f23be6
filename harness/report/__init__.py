"""The report: ``ibench report``'s figures, tables and pages from result records.

:func:`write_report` (:mod:`~integrator_bench.harness.report.write`) writes,
per problem and parameter set, a work-precision figure (PNG), a table (CSV)
and a Markdown page, and for the whole store ``index.md`` and ``index.html``.
The modules, in the order they depend on each other:

``tables``
    the one Markdown table writer, and the terminal's plain table;
``names``
    groups and lines, their names on disk and on the page, a group's table;
``ranking_text``
    the target table's cells and caption, what a page ranks by, in words (the
    arithmetic is :mod:`integrator_bench.harness.ranking`);
``comparison``
    the formulations compared (Sudarsan and Keerthi's tables);
``profiles``
    performance and data profiles of every integrator across the problems;
``scaling``
    the scaling measurements' JSON schema, reader and writer;
``style``
    colour, marker and panel (family) of each integrator;
``document``
    the report as data: a typed section per problem made of parts;
``sections``
    the builders of the parts (the one place where a part is added);
``markdown``, ``html``
    the two renderers of those parts;
``figures``
    the work-precision and scaling figures (matplotlib);
``write``
    :func:`write_report`, which joins them, with the part a package above it
    draws (``appendix``: the sources' part, :mod:`integrator_bench.harness.sources`,
    which ``ibench report`` hands it).

May import: :mod:`integrator_bench.harness.matrix`, :mod:`integrator_bench.harness.measure`
(the references and spectra some parts are set beside), :mod:`integrator_bench.harness.ranking`
(the crossings, costs and records it draws), ``errors``, ``paths``,
``version``, ``problems/`` and ``integrators/``; never the run engine: a report is drawn
from the records, it runs no case.

``write_report`` is imported on first use, so that the command line's other
commands (which use ``tables``) do not load matplotlib.
"""

from __future__ import annotations


def __getattr__(name: str):
    if name == "write_report":
        from integrator_bench.harness.report.write import write_report

        return write_report
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
