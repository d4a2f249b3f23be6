"""The report's ``index.html``: one static, offline page with its figures beside it.

No script and nothing from the network: inline CSS, PNG figures linked by
relative paths, hover messages in ``title`` attributes. Each section defines
the metrics it shows.
"""

from __future__ import annotations

import html
import re

import numpy as np
import pandas as pd

from integrator_bench.harness import targets
from integrator_bench.harness.comparison import ROWS, compared_integrators, counter_cell
from integrator_bench.harness.wp_style import FAMILIES

CSS = """body{font:15px/1.45 system-ui,sans-serif;margin:0 auto;max-width:1320px;padding:0 18px;
color:#222}h1{margin-top:18px}h2{border-bottom:2px solid #ddd;margin-top:40px}
table{border-collapse:collapse;margin:8px 0;font-size:13px;display:block;overflow-x:auto;max-width:100%}td,th{border:1px solid #ccc;
padding:2px 7px;text-align:right}th{background:#f3f3f3}td.l,th.l{text-align:left}
img{max-width:100%;border:1px solid #eee}.def{background:#f7f7fb;border-left:4px solid #99c;
padding:6px 12px;font-size:13px}.ok{background:#b7e1b0}.mixed{background:#f6d58e}
.bad{background:#ec9a94}.uns{background:#eee;color:#999}.best{font-weight:bold}
nav a{margin-right:12px}details{margin:6px 0}summary{cursor:pointer}"""
DEFINITIONS = {
    "scd": "<b>scd</b> (significant correct digits, IVP Test Set): −log10 of the largest "
           "relative error at the final time over the problem's error components (positions "
           "for mechanical systems); the work-precision figure's x axis, the pure "
           "<b>relative position error</b>, is 10<sup>−scd</sup>. It blows up where a "
           "reference position is near zero; the panel's lines are chosen, and the target "
           "table below ranked, by the mixed error 10<sup>−mescd</sup> instead.",
    "mescd": "<b>mescd</b>: the same with the mixed error |e| / (atol/rtol + |ref|), atol/rtol "
             "the problem's absolute scale of the component (for positions: its position "
             "scale), which does not blow up where a reference component is near zero; "
             "10<sup>−mescd</sup>, the relative position error with the position scale as "
             "floor, is the error of the target table and of the answer above.",
    "reach": "<b>CPU to reach</b> a target error: CPU seconds of the solve at which a line "
             "reaches a relative position error with the problem's position scale as floor "
             "(10<sup>−mescd</sup>, at the final time), "
             "interpolated (log CPU against log error) between the two consecutive "
             "tolerances whose errors bracket the target, at the first crossing in order of "
             "increasing work; NS, NF, NJ, NLU interpolated with the same weight. "
             "<b>≤</b>: the loosest tolerance is already below the target (its CPU, an upper "
             "bound); never extrapolated (“not reached”). Least error: the line's least "
             "10<sup>−mescd</sup>. A <b>line</b> is one integrator "
             "and formulation over its tolerances (rtol) or step sizes (h). Sorted by CPU to "
             f"reach {targets.TARGETS[-1]:.0e}, then {targets.TARGETS[0]:.0e}.",
    "front": "<b>Pareto front</b>: the points (any line of the panel) that no other point "
             "beats in both error (10<sup>−scd</sup>, the axis) and CPU. At most ten lines a "
             "panel, each integrator's best first, in the order of the target table "
             "(10<sup>−mescd</sup>). Grey crosses in the shaded strip right of the "
             "error axis are cases that did not end ok (failed, diverged, timeout, crashed, "
             "error, or ok with an error above 100%), at their CPU where measured.",
    "drift": "<b>drift</b>: largest norm over the run of the position constraint residual "
             "|g(q)| (drift_pos) and of the velocity constraint residual |G(q) v| "
             "(drift_vel).",
    "counters": "Counters (Sudarsan and Keerthi 1998): <b>NF</b> right-hand side or residual "
                "evaluations (finite-difference calls included), <b>NS</b> accepted steps, "
                "<b>NJ</b> Jacobian evaluations, <b>NLU</b> LU factorizations, <b>NI</b> "
                "Newton iterations, Newton failures, <b>CPU</b> seconds of the solve; "
                "– : the integrator cannot report it.",
    "status": "Status: <b>ok</b>; <b>failed</b> the integrator gave up (reason diverged, "
              "step-size underflow, …); <b>timeout</b>; <b>crashed</b> the worker died; "
              "<b>error</b> an exception; <b>unsupported</b> the integrator takes no form "
              "of that formulation.",
}


def esc(value) -> str:
    """HTML-escaped text; None and NaN as ``–``."""
    if value is None or (isinstance(value, float) and np.isnan(value)) or value is pd.NA:
        return "–"
    return html.escape(str(value), quote=True)


def definition(*keys: str) -> str:
    """A box defining the metrics ``keys`` of :data:`DEFINITIONS`."""
    return '<div class="def">' + "<br>".join(DEFINITIONS[k] for k in keys) + "</div>"


def table(header, rows, left=1, row_class=None) -> str:
    """An HTML table; the first ``left`` columns left-aligned; cells are HTML already."""
    head = "".join(f'<th class="l">{h}</th>' if i < left else f"<th>{h}</th>"
                   for i, h in enumerate(header))
    body = []
    for n, row in enumerate(rows):
        cls = f' class="{row_class[n]}"' if row_class and row_class[n] else ""
        cells = "".join(f'<td class="l">{c}</td>' if i < left else f"<td>{c}</td>"
                        for i, c in enumerate(row))
        body.append(f"<tr{cls}>{cells}</tr>")
    return f"<table><tr>{head}</tr>{''.join(body)}</table>"


def reach_section(table_: pd.DataFrame, families: dict, top: int = 15) -> str:
    """The CPU-to-reach-a-target-error table
    (:func:`integrator_bench.harness.targets.target_table`): the first ``top``
    lines, the rest folded; the first row bold when it reaches the tightest target."""
    names = dict(FAMILIES)
    header, body = targets.markdown_rows(table_)
    header = header[:2] + ["family"] + header[2:]
    rows = [[esc(c) for c in cells[:2]]
            + [esc(names.get(families.get((cells[0], cells[1])), ""))]
            + [esc(c) for c in cells[2:]] for cells in body]
    tight = f"how_{targets.TARGETS[-1]:.0e}"
    first = len(table_) and table_[tight].iloc[0] in ("interpolated", "at a point")
    classes = ["best" if i == 0 and first else "" for i in range(len(rows))]
    out = table(header, rows[:top], left=3, row_class=classes[:top])
    if len(rows) > top:
        out += (f"<details><summary>{len(rows) - top} more lines</summary>"
                + table(header, rows[top:], left=3) + "</details>")
    return out


def scaling_section(items: list[tuple[dict, str]]) -> str:
    """The "Scaling" section: per measurement file its log-log figure, the fitted
    slopes against their bounds and the measurements; empty without files."""
    from integrator_bench.harness.report import scaling_tables

    if not items:
        return ""
    parts = ['<h2 id="scaling">Scaling</h2>',
             "<p>CPU seconds per right-hand side, residual, Jacobian and step against the "
             "number of links; slopes fitted on log-log axes (1: linear growth).</p>"]
    for data, png in items:
        head, slopes, cols, body = scaling_tables(data)
        name = data.get("problem", data["file"])
        parts += [f"<h3>{esc(name)}</h3>",
                  f"<p>Created {esc(data.get('created'))} on {esc(data.get('machine'))}.</p>",
                  f'<p><img src="{esc(png)}" alt="scaling of {esc(name)}"></p>',
                  table(head, [[esc(c) for c in r] for r in slopes]),
                  table([esc(c) for c in cols], [[esc(c) for c in r] for r in body])]
    return "".join(parts)


def _status_class(statuses: list[str]) -> str:
    run = [s for s in statuses if s != "unsupported"]
    if not run:
        return "uns"
    ok = sum(s == "ok" for s in run)
    return "ok" if ok == len(run) else ("bad" if ok == 0 else "mixed")


def failure_map(rows: pd.DataFrame) -> str:
    """Integrator × formulation grid coloured by status; hover lists each case."""
    forms = list(dict.fromkeys(rows["formulation"]))
    out_rows = []
    for integrator, sub in sorted(rows.groupby("integrator"), key=lambda kv: kv[0]):
        cells = [esc(integrator)]
        for form in forms:
            cases = sub[sub["formulation"] == form]
            if not len(cases):
                cells.append("")
                continue
            tips = []
            for c in cases.itertuples(index=False):
                tol = f"rtol={c.rtol:g}" if pd.notna(c.rtol) else (
                    f"h={c.h:g}" if pd.notna(c.h) else "")
                why = str(c.message).splitlines()[0][:160] if pd.notna(c.message) else ""
                reason = f" [{c.reason}]" if pd.notna(c.reason) and c.reason else ""
                tips.append(f"{tol}: {c.status}{reason}{' — ' + why if why else ''}")
            statuses = list(cases["status"])
            cls = _status_class(statuses)
            n_ok = statuses.count("ok")
            n_run = len([s for s in statuses if s != "unsupported"])
            text = "unsupported" if cls == "uns" else f"{n_ok}/{n_run} ok"
            cells.append(f'<span class="{cls}" title="{esc(chr(10).join(tips))}" '
                         f'style="display:block">{text}</span>')
        out_rows.append(cells)
    return table(["integrator"] + [esc(f) for f in forms], out_rows)


def comparison_section(rows: pd.DataFrame) -> str:
    """Sudarsan-Keerthi tables, one per integrator that ran two or more formulations."""
    parts = []
    for integrator, tab in compared_integrators(rows):
        header = [""] + [f"{esc(f)}<br>rtol {t}" for f, t in tab.columns]
        body = [[esc(label)] + [counter_cell(v, key) for v in values]
                for (key, _), (label, values) in zip(ROWS, tab.iterrows())]
        parts.append(f"<details><summary>{esc(integrator)}</summary>"
                     + table(header, body) + "</details>")
    return "".join(parts) or "<p>No integrator ran two formulations of this problem.</p>"


def drift_section(rows: pd.DataFrame) -> str:
    """Median position drift over integrators per formulation and rtol (hover: each)."""
    ok = rows[(rows["status"] == "ok") & rows["rtol"].notna() & rows["drift_pos"].notna()]
    if not len(ok):
        return "<p>No drift measured (no constraints, or no ok adaptive runs).</p>"
    tols = sorted(ok["rtol"].unique(), reverse=True)
    body = []
    for form, sub in ok.groupby("formulation", sort=False):
        cells = [esc(form)]
        for tol in tols:
            at = sub[sub["rtol"] == tol]
            if not len(at):
                cells.append("")
                continue
            tip = "\n".join(f"{r.integrator}: {r.drift_pos:.1e}" for r in at.itertuples())
            cells.append(f'<span title="{esc(tip)}">{at["drift_pos"].median():.1e}</span>')
        body.append(cells)
    return table(["formulation"] + [f"rtol {t:g}" for t in tols], body)


def events_section(lines: list[str]) -> str:
    """The event table of a problem with state events (Markdown lines of
    :func:`integrator_bench.harness.report.events_markdown`), or nothing."""
    if not lines:
        return ""
    return ("<h3>Events</h3><p>Events located, missed and spurious against the "
            "reference's sequence (matched by kind and order), the largest event-time "
            "error and the mixed error of the state after the last matched event.</p>"
            + markdown_to_html(lines))


def markdown_to_html(lines: list[str]) -> str:
    """A Markdown section made of ``##`` titles, text and pipe tables, as HTML."""
    out, rows = [], []
    for line in lines + [""]:
        if line.startswith("|"):
            cells = [c.strip().replace(r"\|", "|") for c in
                     re.split(r"(?<!\\)\|", line.strip()[1:-1])]
            if not all(set(c) <= set("-:") for c in cells):
                rows.append([esc(c.strip("`")) for c in cells])
            continue
        if rows:
            out.append(table(rows[0], rows[1:], left=len(rows[0])))
            rows = []
        if line.startswith("#"):
            out.append(f"<h3>{esc(line.lstrip('# '))}</h3>")
        elif line.strip():
            out.append(f"<p>{esc(line)}</p>")
    return "".join(out)


def problem_info(problem: str, stiffness: str | None = None) -> str:
    """Description, source, dimension, formulations (kind and index) of a registered
    problem, and ``stiffness`` (text, e.g. eigenvalues) when given; a note when
    the problem is no longer registered."""
    from integrator_bench.harness import registry

    cls = registry.problems().get(problem)
    if cls is None:
        return "<p>(problem no longer registered: no description)</p>"
    try:
        inst = cls()
        forms = []
        for f in cls.formulations:
            system = inst.formulate(f)
            index = f", index {system.index}" if system.kind == "dae" else ""
            forms.append(f"{f} ({system.kind}{index})")
        dim = f"{inst.dimension}"
    except Exception as exc:  # the page still shows what it can
        forms, dim = [f"could not build the problem: {exc}"], "–"
    stiff_text = f"<br><b>Stiffness:</b> {esc(stiffness)}" if stiffness else ""
    return (f"<p>{esc(cls.description)}<br><b>Source:</b> {esc(cls.source)}<br>"
            f"<b>Dimension:</b> {esc(dim)}; <b>time span:</b> {esc(cls.t_span)}<br>"
            f"<b>Formulations (system kind, index):</b> {esc(', '.join(forms))}"
            f"{stiff_text}</p>")


def problem_section(group: dict) -> str:
    """One problem's section; ``group`` holds ``anchor``, ``title``, ``problem``,
    ``rows`` (its records), ``figure`` (file name or None), ``targets``
    (:func:`integrator_bench.harness.targets.target_table`), ``families`` and
    ``stiffness``."""
    rows, ranked = group["rows"], group["targets"]
    tag = f"{targets.TARGETS[-1]:.0e}"
    reached = ranked[ranked[f"how_{tag}"].isin(["interpolated", "at a point"])] \
        if len(ranked) else ranked
    what = "a relative position error (position scale as floor, 10<sup>−mescd</sup>) of"
    answer = (f"no line reaches {what} {tag} within its measured range" if not len(reached)
              else f"cheapest to reach {what} {tag}: <b>{esc(reached['integrator'].iloc[0])} "
                   f"({esc(reached['formulation'].iloc[0])})</b>, "
                   f"{reached[f'cpu_{tag}'].iloc[0]:.3g} s CPU")
    fig = (f'<p><img src="{esc(group["figure"])}" alt="work-precision diagram of '
           f'{esc(group["title"])}"></p>' if group["figure"] else "<p>No figure: no case ran.</p>")
    return "".join([
        f'<section id="{esc(group["anchor"])}"><h2>{esc(group["title"])}</h2>',
        problem_info(group["problem"], group.get("stiffness")),
        f"<p>Answer: {answer}.</p>",
        "<h3>Work-precision</h3>", fig, definition("scd", "mescd", "front"),
        "<h3>CPU to reach a target error</h3>", definition("reach"),
        reach_section(ranked, group["families"]),
        "<h3>Failure map</h3>", definition("status"),
        "<p>Cell: ok cases out of those run over the tolerances; hover for each case's "
        "status, reason and message.</p>", failure_map(rows),
        "<h3>Formulations compared</h3>", definition("counters", "drift", "mescd"),
        comparison_section(rows),
        "<h3>Drift against tolerance</h3>", definition("drift"),
        "<p>Median drift_pos over the integrators that ran the formulation at that rtol "
        "(hover: each integrator).</p>", drift_section(rows),
        events_section(group.get("events") or []),
        f'<p>Tables: <a href="{esc(group["slug"])}.csv">CSV</a>, '
        f'<a href="{esc(group["slug"])}.md">Markdown</a></p></section>'])


def page(groups: list[dict], status_counts: list[tuple[str, int]], n_records: int,
         runs_lines: list[str], scaling: list[tuple[dict, str]] = ()) -> str:
    """The whole ``index.html``.

    Parameters
    ----------
    groups : list of dict
        One per problem and parameter set, as :func:`problem_section` takes them.
    status_counts : list of (str, int)
        Records per status.
    n_records : int
        Records after dropping superseded repeats.
    runs_lines : list of str
        The Markdown of the runs' provenance
        (:func:`integrator_bench.harness.provenance.runs_markdown`).
    scaling : list of (dict, str)
        Scaling measurements and their figure's file name
        (:func:`scaling_section`); none: no "Scaling" section.
    """
    nav = "".join(f'<a href="#{esc(g["anchor"])}">{esc(g["title"])}</a>' for g in groups)
    nav += '<a href="#scaling">Scaling</a>' if scaling else ""
    summary = table(["status", "records"], [[esc(s), str(n)] for s, n in status_counts])
    return "".join([
        '<!DOCTYPE html><html lang="en"><head><meta charset="utf-8">',
        "<title>Integrator benchmark report</title>", f"<style>{CSS}</style></head><body>",
        "<h1>Integrator benchmark report</h1>", f"<nav>{nav}</nav>",
        f"<p>{n_records} records.</p>", summary, definition("status"),
        *[problem_section(g) for g in groups], scaling_section(list(scaling)),
        '<h2 id="provenance">Provenance</h2>', markdown_to_html(runs_lines),
        "</body></html>\n"])
