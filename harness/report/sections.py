"""The report's parts: one builder per part, a typed section per problem.

:func:`problem_section` makes a problem's
:class:`~integrator_bench.harness.report.document.ProblemSection` from its
:class:`~integrator_bench.harness.report.document.Group`: its description, its
answer and one :class:`~integrator_bench.harness.report.document.Part` per
builder of :data:`PROBLEM_PARTS`; adding a part to every problem means adding
one builder there, and both renderers
(:mod:`~integrator_bench.harness.report.markdown`,
:mod:`~integrator_bench.harness.report.html`) show it. ``formats`` says where a
part appears (the Markdown files keep the cases table and the list of
failures, the page the failure map and the drift table); ``in_index`` parts
are also gathered into ``index.md`` under one heading, a subsection per
problem. :func:`build_report` adds the parts around the sections: first the
answers (:func:`answers_part`, each section's answer line as a row), then the
summary, status and problems; after them the advice's records, kept apart
(:func:`advice_part`), the appendix drawn above the report (the sources'), scaling and
runs.
"""

from __future__ import annotations

import dataclasses
import json

import pandas as pd

from integrator_bench.harness.matrix.record import STATUSES
from integrator_bench.harness.ranking import reach
from integrator_bench.harness.ranking.records import COUNT_COLUMNS, params_dict, unresponsive
from integrator_bench.harness.report import driving, ranking_text
from integrator_bench.harness.report.comparison import ROWS, compared_integrators, counter_cell
from integrator_bench.harness.report.document import (
    Answer, Block, Cell, Group, Part, ProblemInfo, ProblemSection, Report, Table)
from integrator_bench.harness.report.names import (
    group_table, params_label, sorted_rows, tol_label, unresponsive_label)
from integrator_bench.harness.report.racing_text import race_block
from integrator_bench.harness.report.scaling import scaling_tables
from integrator_bench.harness.matrix.line import FAMILIES, formulation_facts

MD_FORMATS = {"rtol": "{:g}", "h": "{:g}", "cpu_s": "{:.3g}", "scd": "{:.2f}",
              "mescd": "{:.2f}", "err_max": "{:.2e}", "err_rms": "{:.2e}",
              "drift_pos": "{:.3g}", "drift_vel": "{:.3g}"}
EVENT_HEADER = ("integrator", "formulation", "tolerance", "nevents", "matched", "missed",
                "spurious", "event-time error", "state error after last event")
EVENT_CAPTION = ("Matched against the reference's event sequence by kind and order; "
                 "time error in time units, state error mixed (error components). A run "
                 "with an event missed or spurious reaches no target error.")
#: the reach table's rows shown before the rest is folded (HTML)
REACH_SHOWN = 15


def _run(rows: pd.DataFrame) -> pd.DataFrame:
    return rows[rows["status"] != "unsupported"]


# --- the parts of a problem section ---------------------------------------------------

FIGURE_CAPTION = ("x: {measure}; y: CPU seconds of the solve (the median of the timed "
                  "solves). The grey band is the Pareto front of every point. On the HTML "
                  "page the figure draws every line on one pair of axes: hover a point for its "
                  "line, tolerance, CPU and error; a click on a legend entry hides or shows a "
                  "line, a family's button all of its lines. The static figure (PNG) has a "
                  "panel per family and at most ten lines a panel, each integrator's best "
                  "first, in the order of the target table. Right of the error axis, at their "
                  "CPU where measured (status and message on hover): crosses, cases that did "
                  "not end ok; plus signs, ok cases with an error above 100%; tripods, ok "
                  "cases without a measured error or with an event missed or extra.")


def cost_part(g: Group) -> Part:
    """What the problem's figure and tables rank by (:mod:`~integrator_bench.harness.ranking.cost`),
    and each code's overhead factor on it: the median over its ok cases of
    ``cpu_s / work``."""
    from integrator_bench.harness.ranking.cost import overhead_table
    from integrator_bench.harness.report.ranking_text import cost_text

    stored = g.rows if g.stored is None else g.stored
    table = overhead_table(stored)
    rows = [[r.label, f"{r.overhead:.3g}", str(int(r.cases))] for r in table.itertuples()]
    blocks = [Block(tables=[Table(["integrator", "overhead (CPU / work)", "ok cases"], rows,
                                  (1, 2))])] if rows else []
    return Part("cost", f"Cost: ranked by {g.cost}",
                caption=cost_text(stored, g.cost) + " The overhead factor of a code is the "
                "median over its ok cases of cpu_s / work: how many times its method's work the "
                "code took here (1: every cycle in the model and the linear algebra).",
                blocks=blocks, empty="No overhead: no ok case with a measured work.")


def figure_part(g: Group) -> Part:
    block = Block(figure=g.figure, alt="work-precision",
                  text=[g.off_axis] if g.off_axis else [],
                  plots=[g.plot] if g.plot else []) if g.figure else None
    return Part("figure", "Work-precision", caption=FIGURE_CAPTION.format(measure=g.measure),
                blocks=[block] if block else [], empty="No figure: no case ran.")


def _case_cell(value, col: str):
    if pd.isna(value):
        return None
    if col in COUNT_COLUMNS:
        return str(int(value))
    if col in MD_FORMATS:
        return MD_FORMATS[col].format(value)
    return str(value)


def cases_part(g: Group) -> Part:
    table = group_table(g.rows)
    shown = table if g.include_unsupported else table[table["status"] != "unsupported"]
    cols = list(shown.columns)
    right = [c for c in cols if pd.api.types.is_numeric_dtype(table[c])]
    rows = [[_case_cell(v, c) for v, c in zip(row, cols)]
            for row in shown.itertuples(index=False)]
    text = ([f"{len(table) - len(shown)} unsupported cases left out (see the CSV)."]
            if len(shown) < len(table) else [])
    return Part("cases", "Cases", blocks=[Block(tables=[Table(cols, rows, tuple(right))],
                                                text=text)], formats=("md",))


def targets_part(g: Group) -> Part:
    names = dict(FAMILIES)
    header, body = ranking_text.markdown_rows(g.ranked, g.targets)
    rows = [cells + [names.get(g.families.get((r.label, r.formulation)), "")]
            for cells, r in zip(body, g.ranked.itertuples(index=False))]
    tight = f"how_{reach.tag(g.targets[-1])}"
    first = bool(len(g.ranked)) and g.ranked[tight].iloc[0] in ("interpolated", "at a point")
    table = Table(header + ["family"], rows, tuple(header[2:]), fold=REACH_SHOWN,
                  first_bold=first)
    return Part("targets", "CPU to reach a target error", caption=ranking_text.caption(g.measure),
                blocks=[Block(tables=[table])] if rows else [],
                empty="No line ran.", in_index=True)


def _status_class(statuses: list[str]) -> str:
    run = [s for s in statuses if s != "unsupported"]
    if not run:
        return "uns"
    ok = sum(s == "ok" for s in run)
    return "ok" if ok == len(run) else ("bad" if ok == 0 else "mixed")


def failure_map_part(g: Group) -> Part:
    rows = g.rows[["label", "formulation", "rtol", "h", "status", "reason", "message"]]
    forms = list(dict.fromkeys(rows["formulation"]))
    cells_of: dict = {}
    for c in rows.itertuples(index=False):
        cells_of.setdefault((c.label, c.formulation), []).append(c)
    body = []
    for label in sorted(set(rows["label"])):
        cells = [label]
        for form in forms:
            cases = cells_of.get((label, form), [])
            if not cases:
                cells.append("")
                continue
            tips = []
            for c in cases:
                why = str(c.message).splitlines()[0][:160] if pd.notna(c.message) else ""
                reason = f" [{c.reason}]" if pd.notna(c.reason) and c.reason else ""
                tips.append(f"{tol_label(c.rtol, c.h)}: {c.status}{reason}"
                            f"{' — ' + why if why else ''}")
            statuses = [c.status for c in cases]
            css = _status_class(statuses)
            n_run = len([s for s in statuses if s != "unsupported"])
            text = "unsupported" if css == "uns" else f"{statuses.count('ok')}/{n_run} ok"
            cells.append(Cell(text, title="\n".join(tips), css=css))
        body.append(cells)
    note = ("Cell: ok cases out of those run over the tolerances; hover for each case's "
            "status, reason and message.")
    return Part("failures", "Failure map", defines=("status",),
                blocks=[Block(text=[note], tables=[Table(["integrator"] + forms, body)])],
                formats=("html",))


DRIVING_TEXT = (
    "Each driven record against its undriven twin's ({twin}: the same model, start and "
    "span with the drive stopped), both ok, the same integrator, formulation and rtol or "
    "step; per formulation, the median of the ratios driven / twin with their range over "
    "integrators and tolerances (steps and f-evals over adaptive pairs only). Digits lost: "
    "the twin's mescd less the driven one's. The twin is the same compiled model (its "
    "driving terms evaluated as zeros), so CPU per f-eval measures the work per "
    "evaluation the driven motion brings (Newton iterations, Jacobians, projections), "
    "not the arithmetic of g_t and g_tt; and the twin moves otherwise, so these are the "
    "driven problem against the mechanism at rest, not one trajectory twice.")


def driving_block(g: Group) -> Block | None:
    """What the driving costs each formulation (:mod:`~integrator_bench.harness.report.driving`):
    a table and its findings, when the group has an undriven twin in the records
    (``g.twin``); a line saying no pair ran when none did; None without a twin."""
    if g.twin is None:
        return None
    stored = g.rows if g.stored is None else g.stored
    twin = driving.changed(stored["params"].iloc[0], g.twin["params"].iloc[0])
    summary = driving.by_formulation(driving.pairs(stored, g.twin))
    text = [DRIVING_TEXT.format(twin=twin)]
    if summary.empty:
        return Block(title="What the driving costs", text=text + [
            "No pair: no case ended ok on both the driven set and its twin."])
    return Block(title="What the driving costs", text=text + driving.findings(summary),
                 tables=[Table(list(driving.HEADER), driving.table_rows(summary),
                               tuple(driving.HEADER[1:]))])


def comparison_part(g: Group) -> Part:
    drive = driving_block(g)
    blocks = [drive] if drive else []
    for label, tab in compared_integrators(g.rows):
        header = [""] + [f"{f} rtol {t}" for f, t in tab.columns]
        body = [[row] + [counter_cell(v, key) for v in values]
                for (key, _), (row, values) in zip(ROWS, tab.iterrows())]
        blocks.append(Block(title=label, tables=[Table(header, body)], folded=True))
    return Part("comparison", "Formulations compared",
                caption="Rows: counters; columns: formulation and rtol"
                        + ("; first, what the driving costs each formulation." if drive
                           else "."),
                defines=("counters", "drift", "mescd"), blocks=blocks,
                empty="No integrator ran two formulations of this problem.")


def drift_part(g: Group) -> Part:
    rows = g.rows
    ok = rows.loc[(rows["status"] == "ok") & rows["rtol"].notna() & rows["drift_pos"].notna(),
                  ["formulation", "rtol", "label", "drift_pos"]]
    tols = sorted(ok["rtol"].unique(), reverse=True)
    body = []
    for form, sub in ok.groupby("formulation", sort=False):
        cells = [form]
        for tol in tols:
            at = sub[sub["rtol"] == tol]
            tip = "\n".join(f"{r.label}: {r.drift_pos:.1e}" for r in at.itertuples())
            cells.append(Cell(f"{at['drift_pos'].median():.1e}", title=tip) if len(at) else "")
        body.append(cells)
    table = Table(["formulation"] + [f"rtol {t:g}" for t in tols], body)
    note = ("Median drift_pos over the integrators that ran the formulation at that rtol "
            "(hover: each integrator).")
    return Part("drift", "Drift against tolerance", defines=("drift",),
                blocks=[Block(text=[note], tables=[table])] if body else [],
                empty="No drift measured (no constraints, or no ok adaptive runs).",
                formats=("html",))


def events_part(g: Group) -> Part:
    """One line per record with event measures (``events_by_kind`` set: an ok run of
    a problem with events): events located, missed, spurious, the largest
    event-time error and the mixed state error after the last matched event."""
    shown = sorted_rows(g.rows[g.rows["events_by_kind"].notna()])
    body = []
    for row in shown.itertuples(index=False):
        body.append((row.label, row.formulation, tol_label(row.rtol, row.h),
                     *(None if pd.isna(v) else str(int(v))
                       for v in (row.nevents, row.events_matched, row.events_missed,
                                 row.events_spurious)),
                     *(None if pd.isna(v) else f"{v:.2e}"
                       for v in (row.event_time_err, row.event_state_err))))
    table = Table(list(EVENT_HEADER), body, EVENT_HEADER[3:])
    return Part("events", "Events", caption=EVENT_CAPTION,
                blocks=[Block(tables=[table])] if body else [], in_index=True)


def not_ok_part(g: Group) -> Part:
    rows = g.rows if g.include_unsupported else _run(g.rows)
    items = []
    for row in sorted_rows(rows[rows["status"] != "ok"]).itertuples(index=False):
        lines = str(row.message).strip().splitlines() if pd.notna(row.message) else []
        why = f" — {lines[0][:200]}" if lines else ""
        items.append(f"{row.label} ({row.formulation}), {tol_label(row.rtol, row.h)}: "
                     f"{row.status}{why}")
    return Part("not_ok", "Not ok", blocks=[Block(items=items)] if items else [],
                formats=("md",))


def unresponsive_part(g: Group) -> Part:
    """The lines that do not respond to ``rtol``
    (:func:`~integrator_bench.harness.ranking.records.unresponsive`): their figures are
    the same at every tolerance."""
    items = [unresponsive_label(line) for line in unresponsive(g.rows)]
    return Part("unresponsive", "Does not respond to rtol",
                caption="Lines whose ok records at different tolerances are identical in "
                        "every count and error: the integrator ignores its tolerance.",
                blocks=[Block(items=items)] if items else [])


#: the parts of every problem section, in order: add a part here
PROBLEM_PARTS = (cost_part, figure_part, cases_part, targets_part, failure_map_part, comparison_part,
                 drift_part, events_part, unresponsive_part, not_ok_part)


# --- a problem's description and answer -----------------------------------------------

def problem_info(problem: str, params: str, stiffness: str | None = None) -> ProblemInfo:
    """Description, source, dimension, time span and formulations (kind and index) of
    the problem built with the parameters that ran (``params``, a record's JSON)."""
    from integrator_bench.harness.matrix import builds, registry
    from integrator_bench.harness.matrix.stand_in import system_of

    try:
        cls = registry.get_problem_class(problem)
    except registry.UnknownName:
        return ProblemInfo(error="problem no longer registered: no description")
    info = ProblemInfo(description=str(cls.description), source=str(cls.source),
                       stiffness=stiffness or "")
    try:
        inst = builds.build(cls, params_dict(params))   # a plugin's tried in a process first
        t0, t1 = inst.t_span
        info.time_span = f"[{t0:g}, {t1:g}]"
        info.dimension = str(inst.dimension)
        for f in cls.formulations:
            kind, index = formulation_facts(problem, f)     # formulated once per process
            if kind is None:                                # a problem without defaults
                system = system_of(inst, f)
                kind, index = system.kind, getattr(system, "index", None)
            index = f", index {index}" if kind == "dae" else ""
            info.formulations.append(f"{f} ({kind}{index})")
    except Exception as exc:  # the page still shows what it can
        info.error = f"could not build the problem: {exc}"
    return info


def answer(ranked: pd.DataFrame, measure: str = "error",
           target: float = reach.DEFAULT_TARGET, cost: str = "cpu") -> Answer:
    """The answer line: :func:`reach.cheapest` of the target table at ``target``,
    the table's tightest (the run's summary names the same line), ``measure`` its
    words, with its margin over the runner-up; ``cost`` what it ranks by."""
    got = Answer(target, measure=measure, cost=cost)
    top = reach.cheapest(ranked, target)
    if top is not None:
        got.label, got.formulation, got.cpu_s = top["label"], top["formulation"], top["cpu_s"]
        got.verdict, got.how = top["verdict"], top["how"]
        got.lines, got.why, got.same = reach.answer_parts(top)
        second = top["runner_up"]
        got.short = second["margin"].short() if second and second["margin"] else got.why
        got.at = reach.tol_cell(top["tol"], top["mode"])
    return got


def answers_part(sections: list[ProblemSection]) -> Part:
    """The report's first part: per problem and parameter set its answer line as a
    row (the cheapest line, its CPU, the tolerance at the crossing, its margin over
    the runner-up), the answers of the sections below."""
    rows = []
    for s in sections:
        a = s.answer
        reached = a.cpu_s is not None
        rows.append([s.problem, s.label or None,
                     a.lines if reached else "not reached",
                     f"{'≤ ' if a.how == 'at most' else ''}{a.cpu_s:.3g}" if reached else None,
                     a.at if reached else None, a.margin() or None])
    target = reach.tag(sections[0].answer.target) if sections else ""
    header = ["problem", "parameters", f"cheapest to {target}", "CPU [s]", "at", "margin"]
    return Part("answers", f"Answers: the cheapest line to an error of {target}",
                caption="Per problem and parameter set, the first row of its table of CPU to "
                        "reach the target (its section below, where the error is named): "
                        "CPU in seconds (≤: an upper bound), the tolerance at the crossing, "
                        "and the margin, the runner-up's CPU over the answer's, with its 95 % "
                        "interval from the paired timed solves (a tie when it reaches 1: "
                        "the noise cannot tell them apart; runner-up Nx: beyond 2x, out of "
                        "contention). "
                        "ibench report --target E answers at E.",
                blocks=[Block(tables=[Table(header, rows, ("CPU [s]", "margin"))])]
                if rows else [], empty="No problem ran.")


def advice_part(records: pd.DataFrame) -> Part | None:
    """The records ``ibench advise`` stored (its searches and the robustness check's
    perturbed parameter sets), shown as the advice's: per problem and parameter set
    how many, apart from the problems' own; None when there are none."""
    if not len(records):
        return None
    rows = []
    for (problem, params), sub in records.groupby(["problem", "params"], sort=True):
        rows.append([problem, params_label(params) or None, str(len(sub)),
                     str(int((sub["status"] == "ok").sum())),
                     str(sub["run_id"].nunique()) if "run_id" in sub else None])
    header = ["problem", "parameters", "records", "ok", "advice runs"]
    return Part("advice", "Advice records (kept apart)",
                caption="Records stored by ibench advise: its searches and the perturbed "
                        "parameter sets of its robustness check. They are the advice's "
                        "evidence (its own page, advice/index.html beside the store, shows "
                        "them) and count in no section, answer, table or profile of this "
                        "report, so that each answer rests on the problem's own runs, as "
                        "ibench run's summary does.",
                blocks=[Block(tables=[Table(header, rows, ("records", "ok", "advice runs"))])])


# --- the parts before and after the sections ---------------------------------------------

def summary_part(data: dict, figure: str | None, targets_=reach.TARGETS,
                 measure: str = reach.DEFAULT_ERROR, plots: list | None = None,
                 cost: str = "cpu", other: tuple | None = None,
                 records: pd.DataFrame | None = None) -> Part:
    """The page's opening: performance and data profiles over every problem, and
    each integrator's share solved within 2x and 10x of the best
    (:mod:`~integrator_bench.harness.report.profiles`); the selection of
    problems and what counts as solved in words."""
    from integrator_bench.harness.report.profiles import FACTORS

    first = data[targets_[0]]
    text = [
        f"Every problem and parameter set the store holds ({first['problems']}) is a "
        f"problem of the profiles; at each target those that no integrator solved ("
        + ", ".join(f"{data[t]['problems'] - data[t]['solved']} at {reach.tag(t)}"
                    for t in targets_)
        + ") are left out, as they have no best.",
        "An integrator (one curve, with its settings) solves a problem when one of its lines, "
        "in any formulation, adaptive or fixed step, reaches the target error ("
        + reach.measure_text(measure) + ", the error of the tables below; a problem whose "
        "final-time error says nothing is ranked over the output times); its cost is the "
        "least CPU over those lines to reach it, "
        "interpolated as in the tables (≤: the loosest point's CPU, an upper bound). Failed, "
        "timed-out, skipped, unsupported and never-reaching runs count as infinity.",
        "Performance profile (Dolan and Moré, Math. Program. 91 (2002) 201-213): the share "
        "of problems on which the integrator's CPU is within tau times the best integrator's, "
        "against log2 tau; at log2 tau = 0, the share on which it is the fastest. Data "
        "profile (Moré and Wild, SIAM J. Optim. 20 (2009) 172-191): the share of problems "
        "solved within alpha (n + 1) right-hand side evaluations (nfev at the crossing, n the "
        "problem's states: one evaluation and a forward-difference Jacobian).",
    ]
    header = ["integrator"]
    for t in targets_:
        header += [f"solved to {reach.tag(t)}"] + [f"within {f:g}x at {reach.tag(t)}"
                                                      for f in FACTORS]
    key = targets_[-1]
    shares = data[key]["shares"]
    order = shares.sort_values([f"within {f:g}x" for f in FACTORS] + ["solved"],
                               ascending=False, kind="stable").index
    rows = []
    for name in order:
        cells = [name]
        for t in targets_:
            row = data[t]["shares"].loc[name]
            cells += [f"{int(row['solved'])} of {data[t]['problems']}"]
            cells += [f"{100 * row[f'within {f:g}x']:.0f} %" for f in FACTORS]
        rows.append(cells)
    table = Table(header, rows, tuple(range(1, len(header))))
    from integrator_bench.harness.report.ranking_text import cost_text

    text = [cost_text(records, cost)] + text
    blocks = [Block(text=text, figure=figure or "",
                    alt="performance and data profiles of every integrator",
                    tables=[table], plots=list(plots or []))]
    if other is not None:   # (data, figure, cost): the profiles by the other cost, folded,
        data_o, figure_o, cost_o = other   # its figure static (an interactive plot in a
        part = summary_part(data_o, figure_o, targets_, measure, None, cost_o,  # closed fold
                            records=records)                # kept the page's hover from working)
        blocks += [dataclasses.replace(b, title=f"The same ranked by {cost_o}", folded=True,
                                       text=b.text[:1]) for b in part.blocks]
    return Part("summary", f"Summary: every integrator across every problem, by {cost}",
                caption=f"Shares of the problems some integrator solved (at "
                        f"{reach.tag(key)}: {data[key]['solved']}); sorted by the share "
                        f"within {FACTORS[0]:g}x of the best at {reach.tag(key)}.",
                blocks=blocks, in_index=False)


def status_part(records: pd.DataFrame, targets=()) -> Part:
    """The count of each status, and what a raced store's race cut
    (:func:`~integrator_bench.harness.report.racing_text.race_block`, warning of a
    target of ``targets`` tighter than the race's)."""
    counts = records["status"].value_counts()
    statuses = list(STATUSES) + sorted(set(counts.index) - set(STATUSES))
    rows = [(s, str(int(counts.get(s, 0)))) for s in statuses]
    raced = race_block(records, targets)
    return Part("status", "Status", defines=("status",),
                blocks=[Block(tables=[Table(["status", "count"], rows, ("count",))])]
                + ([raced] if raced is not None else []))


def problems_part(sections: list[ProblemSection]) -> Part:
    rows = []
    for s in sections:
        n_ok = int((s.rows["status"] == "ok").sum())
        fig = Cell("png", href=f"{s.anchor}.png") if s.figure else None
        rows.append((s.problem, s.label, str(len(s.rows)), str(n_ok), fig,
                     Cell("csv", href=f"{s.anchor}.csv"), Cell("md", href=f"{s.anchor}.md")))
    header = ["problem", "parameters", "cases", "ok", "figure", "CSV", "Markdown"]
    return Part("problems", "Problems", blocks=[Block(tables=[Table(header, rows,
                                                                   ("cases", "ok"))])])


def scaling_part(items: list) -> Part:
    """Per scaling file (:class:`~integrator_bench.harness.report.scaling.Scaling` and
    its figure's file name) its figure, slopes against their bounds and measurements."""
    blocks = []
    for data, png in items:
        head, slopes, cols, body = scaling_tables(data)
        blocks.append(Block(title=data.problem,
                            text=[f"Created {data.created} on {data.machine}."],
                            figure=png, alt="scaling",
                            tables=[Table(list(head), slopes, ("log-log slope", "bound")),
                                    Table(list(cols), body, tuple(cols))]))
    return Part("scaling", "Scaling", blocks=blocks,
                caption="CPU seconds per right-hand side, residual, Jacobian and step "
                        "against the number of links; slopes fitted on log-log axes "
                        "(1: linear growth).")


def _loads(text):
    try:
        return json.loads(text) if isinstance(text, str) else (text or {})
    except ValueError:
        return {}


def _backend(backend: dict) -> str | None:
    if backend.get("kind") == "dask":
        workers = backend.get("workers") or []
        hosts = sorted({w.get("host") for w in workers if w.get("host")})
        return (f"dask {backend.get('scheduler')}: {len(workers)} workers, "
                f"{sum(w.get('nthreads') or 0 for w in workers)} threads on {', '.join(hosts)}")
    return f"local, {backend.get('jobs')} jobs" if backend else None


def runs_part(runs: pd.DataFrame | None) -> Part:
    """One row per run of the store's ``runs`` table
    (:data:`integrator_bench.harness.matrix.record.RUN_FIELDS`); none stored: a note."""
    header = ("run", "started", "finished", "status", "code", "host", "CPU", "Python", "numpy",
              "scipy", "scikit-sundae", "fmpy", "plugins", "threads", "backend", "command")
    rows = []
    for row in ([] if runs is None else runs.to_dict("records")):
        v = _loads(row.get("versions"))
        threads = _loads(row.get("threads"))
        env = ", ".join(f"{k}={x}" for k, x in (threads.get("env") or {}).items() if x)
        per_worker = threads.get("blas_threads_per_worker")
        thread_text = "; ".join(filter(None, [env or "no thread variables set",
                                              per_worker and f"{per_worker} BLAS thread per case"]))
        plugins = ", ".join(f"{k} {x}" for k, x in (v.get("plugins") or {}).items()) or "none"
        status = row.get("status")
        if status == "running" and not row.get("finished"):
            status = "running or killed"
        load = _loads(row.get("loadavg"))
        host = f"{row.get('host')} (load {', '.join(map(str, load))})" if load else row.get("host")
        rows.append([row.get("run_id"), row.get("started"), row.get("finished"), status,
                     row.get("code_version"), host,
                     f"{row.get('cpu_model')} ({row.get('cpu_count')} cores)", row.get("python"),
                     v.get("numpy"), v.get("scipy"), v.get("scikit-sundae"), v.get("fmpy"),
                     plugins, thread_text, _backend(_loads(row.get("backend"))),
                     Cell(str(row.get("command")), code=True)])
    return Part("provenance", "Runs (provenance)",
                blocks=[Block(tables=[Table(list(header), rows)])] if rows else [],
                empty="No run provenance stored (a store from before format 2).")


def problem_section(anchor: str, title: str, label: str, group: Group,
                    stiffness: str | None = None) -> ProblemSection:
    """A problem section: :func:`problem_info`, :func:`answer` and :data:`PROBLEM_PARTS`."""
    rows = group.rows
    problem, params = rows["problem"].iloc[0], rows["params"].iloc[0]
    return ProblemSection(anchor=anchor, title=title, problem=problem, label=label, rows=rows,
                          figure=group.figure, info=problem_info(problem, params, stiffness),
                          answer=answer(group.ranked, group.measure, group.targets[-1],
                                        group.cost),
                          parts=[build(group) for build in PROBLEM_PARTS])


def build_report(records: pd.DataFrame, dropped: int, sections: list,
                 runs: pd.DataFrame | None = None, summary: Part | None = None,
                 advice: pd.DataFrame | None = None, made_after=(), targets=()) -> Report:
    """The report around its sections: the answers (:func:`answers_part`), the
    ``summary`` (:func:`summary_part`), status and problems before; the advice's
    records (:func:`advice_part`), the parts the caller made (``made_after``, in
    order: the appendix's part, :attr:`~integrator_bench.harness.report.write.ReportOptions.appendix`,
    and the scaling part, :func:`scaling_part`; None for one it did not make) and the ``runs`` (when
    given) after; ``targets``: the report's, which the status part warns of when
    tighter than a race's."""
    with_runs = runs is not None
    before = [status_part(records, targets), problems_part(sections)] if len(records) else []
    before = ([answers_part(sections)] if sections else []) + \
        ([summary] if summary is not None else []) + before
    after = [p for p in [advice_part(advice if advice is not None else records.iloc[:0])]
             if p is not None]
    after += [p for p in made_after if p is not None]
    after += [runs_part(runs)] if with_runs else []
    return Report(len(records), dropped, sections, before, after,
                  apart=0 if advice is None else len(advice))

