"""The report's interactive figures: plotly specifications of the work-precision
diagrams and the performance profiles, drawn offline in ``index.html``.

The PNG figures (:mod:`~integrator_bench.harness.report.figures`) draw at most
ten lines a panel; these draw every line a problem has, on one pair of log
axes, so that a page stays readable with thirty lines: hovering a point names
its line, its tolerance (rtol, or h for a fixed step), its CPU and its error;
a click on a legend entry hides or shows one line, the buttons above the plot
a whole family (:data:`~integrator_bench.harness.matrix.line.FAMILIES`); the
legend sits right of the plot, outside it. The specifications are plain dicts
(plotly.js's ``data`` and ``layout``, JSON), built here from the same records,
ranking and style as the PNG figures; :mod:`~integrator_bench.harness.report.html`
writes them into the page, and :func:`write_library` puts plotly.js (from the
``plotly`` package, MIT licence) beside it, so the page needs no network.
"""

from __future__ import annotations

import html
from pathlib import Path

import numpy as np
import pandas as pd

from integrator_bench.harness.matrix.line import FAMILIES
from integrator_bench.harness.paths import write_atomically
from integrator_bench.harness.ranking import reach
from integrator_bench.harness.report.figures import (OFF_AXIS, error_label, off_axis,
                                                     off_axis_label)
from integrator_bench.harness.report.names import line_label
from integrator_bench.harness.report.ranking_text import AXIS, WORD
from integrator_bench.harness.report.style import FAILED_COLOR

#: plotly.js, written beside ``index.html`` by :func:`write_library`
LIBRARY = "plotly.min.js"
#: matplotlib markers of :mod:`~integrator_bench.harness.report.style` -> plotly symbols
SYMBOLS = {"o": "circle", "s": "square", "^": "triangle-up", "v": "triangle-down",
           "D": "diamond", "P": "cross", "*": "star", "<": "triangle-left",
           ">": "triangle-right", "X": "x", "h": "hexagon", "p": "pentagon",
           "d": "diamond-tall"}
#: the PNG figures' markers of the cases off the error axis -> plotly symbols
OFF_SYMBOLS = {"x": "x-thin-open", "+": "cross-thin-open", "1": "y-down-open",
               "3": "y-right-open"}
#: line dash per formulation, as the PNG figures' :data:`~figures.DASHES`
DASHES = {"ode": "solid", "i3": "solid", "i2": "dash", "i1": "dot", "ggl": "dashdot",
          "baumgarte": "dash", "projection": "dot", "partitioning": "dashdot"}
FONT = {"family": "system-ui, sans-serif", "size": 12}


def text(value) -> str:
    """``value`` as plotly label text: plotly reads a few HTML tags in labels, so
    a name's ``<`` ``>`` ``&`` are written as entities (a plugin may be named anything)."""
    return html.escape(str(value), quote=False)


def _legend(title: str) -> dict:
    return {"x": 1.02, "xanchor": "left", "y": 1.0, "yanchor": "top",
            "groupclick": "toggleitem", "title": {"text": text(title)},
            "font": {"size": 11}, "tracegroupgap": 12}


def work_precision(rows: pd.DataFrame, ranked: pd.DataFrame, style: dict, title: str,
                   measure: str = reach.DEFAULT_ERROR, cost: str = "cpu") -> dict | None:
    """The work-precision specification of one problem and parameter set; its y
    axis the ``cpu_s`` column, the method's work under ``cost`` ``work``
    (:func:`~integrator_bench.harness.ranking.cost.by_cost`).

    Parameters
    ----------
    rows : pandas.DataFrame
        The group's cleaned records, with their ``family``
        (:attr:`~integrator_bench.harness.matrix.line.Line.family`), unsupported
        cases left out.
    ranked : pandas.DataFrame
        The group's target table: its lines are drawn in its order.
    style : dict
        Integrator -> (colour, matplotlib marker), as every figure of the report.
    title : str
        The figure's title.
    measure : str
        The error of the x axis (:data:`~integrator_bench.harness.ranking.reach.ERRORS`).

    Returns
    -------
    dict or None
        ``{"data": [...], "layout": {...}, "families": [(key, name), ...]}``: a
        trace per line with an ok point (``legendgroup`` its family, hover text
        with line, tolerance, CPU and error), the Pareto front of every point,
        and the cases that did not end ok as crosses right of the error axis (at
        their CPU where measured, their status and message on hover), with the
        other cases off that axis (:func:`~integrator_bench.harness.report.figures.off_axis`);
        None when no case ran.
    """
    if not len(rows):
        return None
    pts = reach.line_points(rows, measure)[["label", "formulation", "mode", "tol", "err",
                                            "cpu_s"]]
    pts = pts[pts["err"] <= 1]
    at = pts.groupby(["label", "formulation", "mode"], sort=False).indices  # a line: its rows
    family_of = dict(zip(zip(rows["label"], rows["formulation"]), rows["family"]))
    names = dict(FAMILIES)
    data, present = [], []
    what = WORD[cost]
    if len(pts):
        front = pts.iloc[reach.pareto_front(pts["err"], pts["cpu_s"])]
        data.append({"type": "scatter", "mode": "lines", "name": "Pareto front",
                     "x": _floats(front["err"]), "y": _floats(front["cpu_s"]),
                     "line": {"shape": "hv", "width": 8, "color": "rgba(0,0,0,0.18)"},
                     "hoverinfo": "skip", "legendgroup": "front", "legendrank": 1})
    for rank, line in enumerate(ranked[ranked["n_ok"] > 0].itertuples(index=False)):
        sel = pts.iloc[at.get((line.label, line.formulation, line.mode), [])]
        if not len(sel):
            continue
        color, marker = style.get(line.label, ("#555555", "o"))
        fam = family_of.get((line.label, line.formulation), "unknown")
        if fam not in present:
            present.append(fam)
        label = line_label(line.label, line.formulation, line.mode)
        tol = "h" if line.mode == "h" else "rtol"
        hover = [f"<b>{text(label)}</b><br>{tol} {t:.3g}<br>{what} {c:.3g} s<br>error {e:.3g}"
                 for t, c, e in zip(sel["tol"], sel["cpu_s"], sel["err"])]
        data.append({"type": "scatter", "mode": "lines+markers", "name": text(label),
                     "x": _floats(sel["err"]), "y": _floats(sel["cpu_s"]),
                     "line": {"color": color, "width": 1.6,
                              "dash": DASHES.get(line.formulation, "solid")},
                     "marker": {"color": color, "size": 7,
                                "symbol": SYMBOLS.get(marker, "circle")},
                     "hovertext": hover, "hoverinfo": "text", "legendgroup": fam,
                     "legendgrouptitle": {"text": text(names.get(fam, fam))},
                     "legendrank": 10 + 10 * _order(fam) + rank / 1000,
                     "meta": {"family": fam, "line": label}})
    err = pts["err"] if len(pts) else pd.Series([1e-6, 1.0])
    right = max(float(err.max()) * 3.0, 1e-3)
    top = pd.to_numeric(rows["cpu_s"], errors="coerce")
    top = float(top[top > 0].max()) * 2.0 if (top > 0).any() else 1.0
    for kind, sub in off_axis(rows, measure).items():
        label, marker = OFF_AXIS[kind]
        cpu = pd.to_numeric(sub["cpu_s"], errors="coerce").to_numpy(float)
        cpu = np.where(np.isfinite(cpu) & (cpu > 0), cpu, top)
        tols = pd.to_numeric(sub["rtol"], errors="coerce").fillna(
            pd.to_numeric(sub["h"], errors="coerce"))
        hover = [f"<b>{text(i)} ({text(f)})</b><br>{text(s)} at tolerance {t:.3g}<br>"
                 f"{text(str(m or '')[:160])}"
                 for i, f, s, t, m in zip(sub["label"], sub["formulation"],
                                          sub["status"], tols, sub["message"])]
        data.append({"type": "scatter", "mode": "markers", "name": off_axis_label(kind, sub),
                     "x": [right * 3.0] * len(cpu), "y": _floats(cpu),
                     "marker": {"color": FAILED_COLOR, "symbol": OFF_SYMBOLS[marker],
                                "size": 9, "line": {"width": 2, "color": FAILED_COLOR}},
                     "hovertext": hover, "hoverinfo": "text", "legendgroup": "off axis",
                     "legendrank": 1000})
    if not data:
        return None
    layout = {"title": {"text": text(title)}, "font": FONT, "height": 560,
              "margin": {"l": 70, "r": 20, "t": 50, "b": 55}, "hovermode": "closest",
              "xaxis": {"type": "log", "title": {"text": text(error_label(measure, rows))},
                        "exponentformat": "power"},
              "yaxis": {"type": "log", "title": {"text": AXIS[cost]},
                        "exponentformat": "power"},
              "legend": _legend("click: hide or show a line")}
    return {"data": data, "layout": layout,
            "families": [(k, names.get(k, k)) for k in sorted(present, key=_order)]}


def performance_profiles(data: dict, style: dict, goals=reach.TARGETS,
                         cost: str = "cpu") -> list[dict]:
    """The summary's performance profiles of CPU (of the method's work with
    ``cost`` ``work``), one specification per target
    (:func:`~integrator_bench.harness.report.profiles.performance_profile` of
    :func:`~integrator_bench.harness.report.profiles.profile_data`): a step curve
    per integrator, hover naming it, tau and its share of the problems."""
    from integrator_bench.harness.report import profiles

    what = WORD[cost]
    specs = []
    for t in goals:
        d = data[t]
        r = d["ratios"]
        taus = profiles.tau_grid(r, 200)
        perf = profiles.performance_profile(d["cpu"], taus)
        traces = []
        for name in perf.columns:
            color, marker = style.get(name.split(" ")[0], ("#555555", "o"))
            share = perf[name].to_numpy(float)
            hover = [f"<b>{text(name)}</b><br>within {tau:.3g}x of the best on "
                     f"{100 * s:.0f} % of the problems" for tau, s in zip(taus, share)]
            traces.append({"type": "scatter", "mode": "lines", "name": text(name),
                           "x": _floats(np.log2(taus)), "y": _floats(share),
                           "line": {"shape": "hv", "color": color, "width": 1.6},
                           "hovertext": hover, "hoverinfo": "text"})
        layout = {"title": {"text": f"Performance profile, {what} to {reach.tag(t)} "
                                    f"({len(r)} problems)"},
                  "font": FONT, "height": 520, "hovermode": "closest",
                  "margin": {"l": 70, "r": 20, "t": 50, "b": 55},
                  "xaxis": {"title": {"text": f"log2 tau ({what} within tau times the best)"}},
                  "yaxis": {"title": {"text": "share of problems"}, "range": [-0.02, 1.02]},
                  "legend": _legend("click: hide or show")}
        specs.append({"data": traces, "layout": layout, "families": []})
    return specs


def write_library(out_dir: Path) -> Path:
    """Write plotly.js as ``out_dir/plotly.min.js`` (unless it is there already,
    the same); return its path."""
    from plotly.offline import get_plotlyjs

    path = Path(out_dir) / LIBRARY
    code = get_plotlyjs()
    if not path.is_file() or path.read_text(encoding="utf-8") != code:
        write_atomically(path, lambda part: part.write_text(code, encoding="utf-8"))
    return path


def _order(family: str) -> int:
    keys = list(FAMILIES)
    return keys.index(family) if family in keys else len(keys)


def _floats(values) -> list:
    """Plain floats for JSON to 5 significant digits (a figure's resolution; the
    hover text says the values), None (a gap) where not finite."""
    return [float(f"{v:.5g}") if np.isfinite(v) else None for v in np.asarray(values, float)]
