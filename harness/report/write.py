"""Writing the report: figures, CSV and Markdown per problem, ``index.md``, ``index.html``.

:func:`write_report` cleans the records
(:func:`~integrator_bench.harness.ranking.records.clean_records`), draws each
group's work-precision figure and the scaling figures
(:mod:`~integrator_bench.harness.report.figures`), the problems' pages, the
summary and the part a package above the report draws (:attr:`ReportOptions.appendix`:
the sources' part) on forked processes, one
per core (:func:`~integrator_bench.harness.forking.in_parallel`: the drawing
is most of a report's time), builds the typed report
(:mod:`~integrator_bench.harness.report.sections`) and writes it through the
two renderers (:mod:`~integrator_bench.harness.report.markdown`,
:mod:`~integrator_bench.harness.report.html`).
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pandas as pd

from integrator_bench.harness.paths import remove_parts, write_atomically
from integrator_bench.harness.forking import in_parallel
from integrator_bench.harness.ranking import reach
from integrator_bench.harness.ranking.cost import COSTS, DEFAULT_COST, by_cost, check_cost
from integrator_bench.harness.ranking.records import clean_records, split_advice
from integrator_bench.harness.report import figures, html, interactive, markdown
from integrator_bench.harness.report.names import group_order, group_table, params_label, slug
from integrator_bench.harness.report.scaling import load_scaling
from integrator_bench.harness.report.document import Appendix, Group
from integrator_bench.harness.report.driving import twin_params
from integrator_bench.harness.report.profiles import profile_data
from integrator_bench.harness.report.sections import (build_report, problem_section,
                                                      scaling_part, summary_part)
from integrator_bench.harness.report.style import styles


#: the summary page's figure (:func:`~integrator_bench.harness.report.figures.profiles_figure`)
PROFILES_PNG = "profiles.png"


@dataclass(frozen=True)
class ReportOptions:
    """How :func:`write_report` writes a report (``ibench report``'s options).

    Attributes
    ----------
    include_unsupported : bool
        Keep ``unsupported`` cases in the Markdown tables (the CSV always has them).
    stiffness : dict, optional
        Problem name -> text of its stiffness figures, shown on the page when given.
    scaling_dir : pathlib.Path, optional
        Where the scaling measurements are
        (:func:`~integrator_bench.harness.report.scaling.load_scaling`); default
        ``<data dir>/scaling`` (:mod:`integrator_bench.harness.paths`). With
        any ``*.json`` there, ``index.md`` and ``index.html`` get a "Scaling"
        part and ``scaling_<name>.png`` is written.
    error : str
        The error every figure, table, answer and profile ranks by, a key of
        :data:`~integrator_bench.harness.ranking.reach.ERRORS` (``final``,
        ``max``, ``rms``).
    jobs : int, optional
        Processes drawing the problems' pages and the summary at once
        (:func:`~integrator_bench.harness.forking.in_parallel`; None: one per
        core, 1: one after the other in this
        process). The files are the same whatever ``jobs``.
    target : float, optional
        The one target error of the tables, answers and profiles (``ibench report
        --target``); default :data:`~integrator_bench.harness.ranking.reach.TARGETS`,
        the answers at the tightest, except on the page of a problem that declares
        precision levels (:func:`problem_targets`: A02's IFToMM 1e-1 and 1e-3).
    cost : str
        What every figure, table, answer and profile ranks by (``ibench report
        --cost``): ``cpu`` (``cpu_s``) or ``work`` (the method's work), a key of
        :data:`~integrator_bench.harness.ranking.cost.COSTS`
        (:func:`~integrator_bench.harness.ranking.cost.by_cost`). Every page says
        which, each problem shows its codes' overhead factors, and the summary
        has the performance profiles by both (the other's in ``profiles_<cost>.png``).
    appendix : callable, optional
        The cleaned records -> an
        :class:`~integrator_bench.harness.report.document.Appendix` or None: a part
        a package above the report draws from them, made on one of the processes
        that draw the pages and shown after the advice's records, its document
        written beside ``index.md`` (``ibench report`` gives the sources' part and
        ``sources.md``, :func:`integrator_bench.harness.sources.page.appendix`).
        None: no such part.
    """

    include_unsupported: bool = False
    stiffness: dict | None = None
    scaling_dir: Path | None = None
    error: str = reach.DEFAULT_ERROR
    jobs: int | None = None
    target: float | None = None
    cost: str = DEFAULT_COST
    appendix: Callable[[pd.DataFrame], Appendix | None] | None = None


def write_report(df: pd.DataFrame, out_dir: Path, runs: pd.DataFrame | None = None,
                 options: ReportOptions | None = None, **chosen) -> list[Path]:
    """Write figures, tables, ``index.md`` and ``index.html`` for a DataFrame of records.

    Parameters
    ----------
    df : pandas.DataFrame
        Result records, one row per case, with the columns of
        ``integrator_bench.harness.matrix.record.FIELDS``. Of repeated cases (same ``KEY_FIELDS``)
        only the newest by ``created`` is kept. The records an advice stored
        (``ibench advise``, :func:`~integrator_bench.harness.ranking.records.split_advice`
        by ``runs``) are kept apart: they count in no section, answer, table or
        profile, and a part after the sections shows them as the advice's.
    out_dir : pathlib.Path
        Output directory, created if needed.
    runs : pandas.DataFrame, optional
        The store's runs (``integrator_bench.harness.matrix.store.load_runs``): their provenance
        becomes a "Runs" part of ``index.md`` and ``index.html``.
    options : ReportOptions, optional
        How the report is written (default: :class:`ReportOptions`'s defaults).
    **chosen
        Fields of :class:`ReportOptions` by keyword (``error="max"``, ``jobs=1``,
        ...), over ``options``'s.

    Returns
    -------
    list of pathlib.Path
        Per group (problem and params, sorted) its ``<slug>.png`` (absent when
        every case is unsupported), ``<slug>.csv`` and ``<slug>.md``, the
        summary's ``profiles.png`` and ``profiles_<other cost>.png`` (when some
        case ran), then the
        scaling figures, then ``index.md`` and ``index.html``, then the
        appendix's document when there is one (``options.appendix``; the sources'
        ``sources.md``, copied to ``docs/seed-numbers.md``). An empty DataFrame gives the scaling figures and
        the two indexes. Interrupted or failed, it leaves no temporary file in
        ``out_dir`` (:func:`~integrator_bench.harness.paths.remove_parts`).
    """
    options = dataclasses.replace(options or ReportOptions(), **chosen)
    check_cost(options.cost)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    try:
        return _write(df, out_dir, runs, options)
    except BaseException:
        # a drawing process killed partway through a write (Ctrl-C, a full disk in
        # another) leaves its temporary file: none stays
        remove_parts(out_dir)
        raise


def _write(df, out_dir: Path, runs, options: ReportOptions) -> list[Path]:
    """:func:`write_report`'s work, into the existing ``out_dir``."""
    from integrator_bench.harness.matrix import registry
    from integrator_bench.harness.paths import DATA_DIR

    error, target, cost = options.error, options.target, options.cost
    scaling = load_scaling(DATA_DIR / "scaling" if options.scaling_dir is None
                           else options.scaling_dir)
    scaling_items = [(data, figures.scaling_figure(data, out_dir)) for data in scaling]
    goals = reach.TARGETS if target is None else (float(target),)
    own, advice = split_advice(df, runs)
    records = clean_records(own)
    style = styles([*registry.integrators(), *records["label"]],
                   dict(zip(records["label"], records["integrator"])))
    groups = records.groupby(["problem", "params"], sort=False)
    pages, used = [], set()
    for key in sorted(groups.groups, key=group_order):
        name = base = slug(*key)
        n = 1
        while name in used:
            n += 1
            name = f"{base}_{n}"
        used.add(name)
        twin = twin_key(key, groups.groups)
        pages.append(functools.partial(_problem_page, groups.get_group(key), name, out_dir,
                                       style, options, goals if target is not None else
                                       problem_targets(key[0], goals),
                                       None if twin is None else groups.get_group(twin)))
    ran = bool((records["status"] != "unsupported").any())
    summary_job = [functools.partial(_summary, records, style, out_dir, error, goals, cost)] \
        if ran else []
    # the appendix and its document beside the pages, not after them
    appendix_job = [functools.partial(options.appendix, records)] \
        if options.appendix is not None and len(records) else []
    jobs = pages + summary_job + appendix_job
    done = in_parallel(jobs, options.jobs,
                       cost=[len(page.args[0]) for page in pages]
                       + [len(records)] * (len(jobs) - len(pages)))
    sections = [section for section, _ in done[:len(pages)]]
    written = [path for _, paths in done[:len(pages)] for path in paths]
    summary = None
    if ran:
        summary, pngs = done[len(pages)]
        written += pngs
    appendix = done[-1] if appendix_job else None
    made_after = [appendix and appendix.part,
                  scaling_part(scaling_items) if scaling_items else None]
    report = build_report(records, len(own) - len(records), sections, runs,
                          summary=summary, advice=clean_records(advice),
                          made_after=made_after, targets=goals)
    index, page = out_dir / "index.md", out_dir / "index.html"
    library = [interactive.write_library(out_dir)] if html.has_plots(report) else []
    write_atomically(index, lambda part: part.write_text(markdown.index(report),
                                                         encoding="utf-8"))
    write_atomically(page, lambda part: part.write_text(html.page(report), encoding="utf-8"))
    document = [out_dir / appendix.file] if appendix is not None and appendix.text else []
    for path in document:   # the appendix alone (docs/seed-numbers.md is copied from it)
        write_atomically(path, lambda part: part.write_text(appendix.text, encoding="utf-8"))
    return (written + [out_dir / png for _, png in scaling_items] + library + [index, page]
            + document)


def twin_key(key: tuple, keys) -> tuple | None:
    """Of the groups ``keys`` (``(problem, params)`` each), the one of the undriven
    twin of group ``key`` (:func:`~integrator_bench.harness.report.driving.twin_params`),
    or None (not driven, no twin declared, the twin not run, the problem not
    registered)."""
    from integrator_bench.harness.matrix import registry
    from integrator_bench.harness.ranking.records import params_dict

    problem, params = key
    cls = registry.problems().get(problem)
    twin = None if cls is None else twin_params(cls, params_dict(params))
    return next((k for k in keys if twin is not None and k[0] == problem
                 and params_dict(k[1]) == twin), None)


def _problem_page(stored, name, out_dir, style, options: ReportOptions, goals, twin=None):
    """One group's figure, CSV and Markdown page: ``(its section, the files written)``;
    the figure and tables rank by ``options.cost`` (the CSV keeps the records as stored);
    ``twin``, the records of its undriven twin's group (what the driving costs)."""
    error, cost = options.error, options.cost
    rows = by_cost(stored, cost)
    problem, params = rows["problem"].iloc[0], rows["params"].iloc[0]
    label = params_label(params)
    title = f"{problem} ({label})" if label else problem
    ranked = reach.target_table(rows, goals, measure=error)
    fig = figures.work_precision_figure(rows, title, style, error, ranked, cost)
    png = None if fig is None else figures.save(fig, out_dir / f"{name}.png")
    run = rows[rows["status"] != "unsupported"]
    plot = interactive.work_precision(run, ranked, style, title, error, cost) if png else None
    group = Group(rows=rows, ranked=ranked, plot=plot,
                  families=dict(zip(zip(run["label"], run["formulation"]), run["family"])),
                  figure=png.name if png else None,
                  off_axis=figures.off_axis_caption(run, error),
                  include_unsupported=options.include_unsupported,
                  measure=reach.measure_text(error, rows, _components(problem, params)),
                  targets=goals, cost=cost, stored=stored, twin=twin)
    section = problem_section(name, title, label, group,
                              (options.stiffness or {}).get(problem))
    csv, md = out_dir / f"{name}.csv", out_dir / f"{name}.md"
    write_atomically(csv, lambda part: group_table(stored).to_csv(part, index=False))
    write_atomically(md, lambda part: part.write_text(markdown.problem_page(section),
                                                      encoding="utf-8"))
    return section, [p for p in (png, csv, md) if p is not None]


def problem_targets(problem: str, default: tuple) -> tuple:
    """The targets of a problem's table: the precision levels its specification
    declares (``precision_levels``, the IFToMM benchmark's low and high levels of
    A02), loosest first, else ``default``."""
    from integrator_bench.harness.matrix import registry

    cls = registry.problems().get(problem)
    levels = getattr(cls, "precision_levels", None)
    return tuple(sorted(map(float, levels.values()), reverse=True)) if levels else default


def _summary(records, style, out_dir, error, goals, cost=DEFAULT_COST):
    """The summary part and its profiles figures, by ``cost`` and by the other
    cost (``profiles_<other>.png``): ``(part, the figures' paths)``."""
    drawn = {}
    for c in sorted(COSTS, key=lambda c: c != cost):
        data = profile_data(by_cost(records, c), goals, measure=error)
        path = out_dir / (PROFILES_PNG if c == cost else f"profiles_{c}.png")
        drawn[c] = data, figures.profiles_figure(data, style, path, goals, cost=c).name, c
    other = next(v for c, v in drawn.items() if c != cost)
    data, png, _ = drawn[cost]
    plots = interactive.performance_profiles(data, style, goals, cost=cost)
    part = summary_part(data, png, goals, measure=error, plots=plots, cost=cost,
                        other=other, records=records)
    return part, [out_dir / drawn[c][1] for c in drawn]


def _components(problem: str, params: str) -> str:
    """The error components of a problem, ``"x, y"`` (``""`` when it cannot be built)."""
    from integrator_bench.harness.matrix.line import ProblemSpec
    from integrator_bench.harness.ranking.records import params_dict

    try:
        inst = ProblemSpec.of(problem, params_dict(params)).build()
        return ", ".join(inst.error_components or inst.components)
    except Exception:  # a problem no longer registered, or a file gone
        return ""
