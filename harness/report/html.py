"""The report's ``index.html``: one offline page with its figures beside it.

Renders the parts (:mod:`integrator_bench.harness.report.document`) whose
``formats`` include ``"html"``. Nothing from the network: inline CSS, hover
text in ``title`` attributes, the interactive figures
(:mod:`~integrator_bench.harness.report.interactive`) drawn by plotly.js from
``plotly.min.js`` beside the page, each with its PNG folded under it (linked
by a relative path). A part defines the metrics it shows
(:data:`DEFINITIONS`, in place of its caption).
"""

from __future__ import annotations

import hashlib
import html
import json

import numpy as np
import pandas as pd

from integrator_bench.harness.report import interactive
from integrator_bench.harness.report.document import (
    Block, Cell, Part, ProblemSection, Report, Table)

CSS = """body{font:15px/1.45 system-ui,sans-serif;margin:0 auto;max-width:1320px;padding:0 18px;
color:#222}h1{margin-top:18px}h2{border-bottom:2px solid #ddd;margin-top:40px}
table{border-collapse:collapse;margin:8px 0;font-size:13px;display:block;overflow-x:auto;max-width:100%}td,th{border:1px solid #ccc;
padding:2px 7px;text-align:right}th{background:#f3f3f3}td.l,th.l{text-align:left}
img{max-width:100%;border:1px solid #eee}.def{background:#f7f7fb;border-left:4px solid #99c;
padding:6px 12px;font-size:13px}.ok{background:#b7e1b0}.mixed{background:#f6d58e}
.bad{background:#ec9a94}.uns{background:#eee;color:#999}.best{font-weight:bold}
nav a{margin-right:12px}details{margin:6px 0}summary{cursor:pointer}
.answer{background:#eef6ee;border-left:4px solid #6a6;padding:6px 12px}
.plot{width:100%;min-height:420px}.families button{margin:2px 6px 2px 0;cursor:pointer}
.families button.off{opacity:.45;text-decoration:line-through}"""
#: the page's one function of its own: a family's button hides or shows its lines
FAMILY_SCRIPT = """function ibenchFamily(id,family,button){var gd=document.getElementById(id);
var idx=[];gd.data.forEach(function(t,i){if(t.meta&&t.meta.family===family)idx.push(i);});
if(!idx.length)return;var hide=gd.data[idx[0]].visible!=='legendonly';
Plotly.restyle(gd,{visible:hide?'legendonly':true},idx);button.classList.toggle('off',hide);}"""
DEFINITIONS = {
    "mescd": "<b>mescd</b> (IVP Test Set): −log10 of the largest mixed error |e| / (atol/rtol "
             "+ |ref|) of the error components (positions for mechanical systems) at the final "
             "time, atol/rtol the problem's absolute scale of the component (its floor); "
             "10<sup>−mescd</sup> is the final-time error (ibench report --error final).",
    "drift": "<b>drift</b>: largest norm over the run of the position constraint residual "
             "|g(q)| (drift_pos) and of the velocity constraint residual |G(q) v| "
             "(drift_vel); g(q, t) and G v + g_t for constraints that depend on time.",
    "counters": "Counters (Sudarsan and Keerthi 1998): <b>NF</b> right-hand side or residual "
                "evaluations (finite-difference calls included), <b>NS</b> accepted steps, "
                "<b>NJ</b> Jacobian evaluations, <b>NLU</b> LU factorizations, <b>NI</b> "
                "Newton iterations, Newton failures, <b>CPU</b> seconds of the solve; "
                "– : the integrator cannot report it.",
    "status": "Status: <b>ok</b>; <b>untimed</b> ok, but a timed solve ended otherwise than "
              "the counted one (no CPU to rank by); <b>failed</b> the integrator gave up (reason diverged, "
              "step-size underflow, …); <b>timeout</b>; <b>crashed</b> the worker died; "
              "<b>error</b> an exception; <b>unsupported</b> the integrator takes no form "
              "of that formulation; <b>skipped</b> not run: a looser tolerance (larger step) "
              "of its line timed out, a smaller step diverged, or the stiffness analysis "
              "rules it out (its message names the case that decided; ibench run --no-skip "
              "runs it); <b>dominated</b> cut by the race: stopped at tau times the least "
              "CPU a line of its problem needed to reach the race target, or not run after "
              "a looser case of its line was (never an answer, beyond tau in the profiles; "
              "ibench run --exhaustive runs it).",
}


def esc(value) -> str:
    """HTML-escaped text; None and NaN as ``–``."""
    if value is None or (isinstance(value, float) and np.isnan(value)) or value is pd.NA:
        return "–"
    return html.escape(str(value), quote=True)


def definition(*keys: str) -> str:
    """A box defining the metrics ``keys`` of :data:`DEFINITIONS`."""
    return '<div class="def">' + "<br>".join(DEFINITIONS[k] for k in keys) + "</div>"


def cell(value) -> str:
    """A cell's HTML: a :class:`~integrator_bench.harness.report.sections.Cell` with its
    link, code, hover title and status class; anything else escaped."""
    if not isinstance(value, Cell):
        return esc(value) if value != "" else ""
    text = f"<code>{esc(value.text)}</code>" if value.code else esc(value.text)
    if value.href:
        text = f'<a href="{esc(value.href)}">{text}</a>'
    if value.css or value.title:
        text = (f'<span class="{esc(value.css)}" title="{esc(value.title)}" '
                f'style="display:block">{text}</span>')
    return text


def _rows(t: Table, rows, bold_first: bool) -> str:
    out = []
    for n, row in enumerate(rows):
        cls = ' class="best"' if n == 0 and bold_first else ""
        cells = "".join(f"<td>{cell(c)}</td>" if i in t.right or t.header[i] in t.right
                        else f'<td class="l">{cell(c)}</td>' for i, c in enumerate(row))
        out.append(f"<tr{cls}>{cells}</tr>")
    return "".join(out)


def table(t: Table) -> str:
    """An HTML table: the ``right`` columns right-aligned, the others left; beyond
    ``fold`` rows the rest in a closed ``details``."""
    head = "".join(f"<th>{esc(h)}</th>" if i in t.right or h in t.right
                   else f'<th class="l">{esc(h)}</th>' for i, h in enumerate(t.header))
    shown = t.rows if t.fold is None else t.rows[:t.fold]
    out = f"<table><tr>{head}</tr>{_rows(t, shown, t.first_bold)}</table>"
    if len(shown) < len(t.rows):
        rest = t.rows[len(shown):]
        out += (f"<details><summary>{len(rest)} more lines</summary><table><tr>{head}</tr>"
                f"{_rows(t, rest, False)}</table></details>")
    return out


def script_json(value) -> str:
    """``value`` as JSON safe inside a ``<script>`` element (``<``, ``>`` and ``&``
    escaped as JSON's ``\\u`` codes, so no text of it can end the element)."""
    return (json.dumps(value, separators=(",", ":"), allow_nan=False)
            .replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026"))


def plot(spec: dict) -> str:
    """An interactive figure: its family buttons (when it has families), its
    ``div`` and the script that draws it; the ``div``'s id is a digest of the
    specification, so the page is the same from run to run."""
    data = {"data": spec["data"], "layout": spec["layout"]}
    code = script_json(data)
    ident = "plot-" + hashlib.sha256(code.encode()).hexdigest()[:12]
    buttons = "".join(
        f'<button type="button" onclick="ibenchFamily(\'{ident}\',\'{esc(key)}\',this)">'
        f"{esc(name)}</button>" for key, name in spec.get("families", []))
    head = (f'<p class="families">Show or hide a family: {buttons}</p>'
            if len(spec.get("families", [])) > 1 else "")
    return (f'{head}<div class="plot" id="{ident}"></div><script>(function(){{var f={code};'
            f'Plotly.newPlot("{ident}",f.data,f.layout,{{displaylogo:false,responsive:true}});'
            "})();</script>")


def has_plots(r: Report) -> bool:
    """Whether the report has an interactive figure (then the page loads plotly.js)."""
    parts = [*r.before, *r.after, *(p for s in r.sections for p in s.parts)]
    return any(b.plots for p in parts if "html" in p.formats for b in p.blocks)


def block(b: Block, level: str = "h3") -> str:
    image = f'<img src="{esc(b.figure)}" alt="{esc(b.alt)}">' if b.figure else ""
    if b.plots:
        parts = [plot(spec) for spec in b.plots]
        if image:
            parts.append(f"<details><summary>Static figure (PNG)</summary><p>{image}</p>"
                         "</details>")
    else:
        parts = [f"<p>{image}</p>" if image else ""]
    parts += [f"<p>{esc(text)}</p>" for text in b.text]
    if b.items:
        parts.append("<ul>" + "".join(f"<li>{esc(i)}</li>" for i in b.items) + "</ul>")
    parts += [table(t) for t in b.tables]
    inner = "".join(parts)
    if b.folded:
        return f"<details><summary>{esc(b.title)}</summary>{inner}</details>"
    return (f"<{level}>{esc(b.title)}</{level}>" if b.title else "") + inner


def part(p: Part, level: str = "h3", anchor: bool = False) -> str:
    if "html" not in p.formats or not p.shown:
        return ""
    sub = f"h{int(level[1]) + 1}"
    ident = f' id="{esc(p.key)}"' if anchor else ""
    about = definition(*p.defines) if p.defines else (f"<p>{esc(p.caption)}</p>"
                                                      if p.caption else "")
    inner = "".join(block(b, sub) for b in p.blocks) or f"<p>{esc(p.empty)}</p>"
    return f"<{level}{ident}>{esc(p.title)}</{level}>{about}{inner}"


def answer_line(a) -> str:
    """The answer line (:func:`~integrator_bench.harness.report.markdown.answer_line`'s
    words) as a paragraph."""
    return (f'<p class="answer">Answer: '
            f'{a.sentence(strong=lambda t: f"<b>{esc(t)}</b>", plain=esc)}.</p>')


def info(s: ProblemSection) -> str:
    i = s.info
    if i.error and not i.description:
        text = f"<p>({esc(i.error)})</p>"
    else:
        stiff = f"<br><b>Stiffness:</b> {esc(i.stiffness)}" if i.stiffness else ""
        forms = ", ".join(i.formulations) or i.error
        text = (f"<p>{esc(i.description)}<br><b>Source:</b> {esc(i.source)}<br>"
                f"<b>Dimension:</b> {esc(i.dimension)}; <b>time span:</b> {esc(i.time_span)}"
                f"<br><b>Formulations (system kind, index):</b> {esc(forms)}{stiff}</p>")
    return text


def problem_section(s: ProblemSection) -> str:
    """One problem's ``section``: the answer on top, description, parts (the figure
    first) and its files' links."""
    return "".join([
        f'<section id="{esc(s.anchor)}"><h2>{esc(s.title)}</h2>', answer_line(s.answer),
        info(s),
        *[part(p) for p in s.parts],
        f'<p>Tables: <a href="{esc(s.anchor)}.csv">CSV</a>, '
        f'<a href="{esc(s.anchor)}.md">Markdown</a></p></section>'])


def page(r: Report) -> str:
    """The whole ``index.html``: navigation, the parts before, the sections, the parts
    after (each with its key as anchor)."""
    after = [p for p in r.after if "html" in p.formats and p.shown]
    nav = "".join(f'<a href="#{esc(s.anchor)}">{esc(s.title)}</a>' for s in r.sections)
    nav += "".join(f'<a href="#{esc(p.key)}">{esc(p.title)}</a>' for p in after)
    scripts = (f'<script src="{interactive.LIBRARY}"></script><script>{FAMILY_SCRIPT}</script>'
               if has_plots(r) else "")
    return "".join([
        '<!DOCTYPE html><html lang="en"><head><meta charset="utf-8">',
        "<title>Integrator benchmark report</title>", f"<style>{CSS}</style>{scripts}</head>"
        "<body>",
        "<h1>Integrator benchmark report</h1>", f"<nav>{nav}</nav>",
        f"<p>{esc(r.count_text())}</p>",
        *[part(p, "h2", anchor=True) for p in r.before],
        *[problem_section(s) for s in r.sections],
        *[part(p, "h2", anchor=True) for p in after],
        "</body></html>\n"])
