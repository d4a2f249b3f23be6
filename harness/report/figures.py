"""The report's figures: work-precision panels per problem, and the scaling figure.

Work-precision figure of one problem: one panel per integrator family. x: the
error the report ranks by (:data:`~integrator_bench.harness.ranking.reach.ERRORS`,
``ibench report --error``: by default the largest mixed error over the output
times; the same as the target table's, per problem as
:func:`~integrator_bench.harness.ranking.reach.effective_error` says); y: CPU
seconds. A panel holds at most ``MAX_LINES`` lines, each integrator's best
first, chosen in the order of the report's target table
(:func:`integrator_bench.harness.ranking.reach.target_table`: least CPU to
reach 1e-5, then 1e-3; the rest are in the tables), the Pareto front of all its
points, and the cases off the error axis in a grey strip right of it, at their
CPU where measured, else at the top (:func:`off_axis`): cases not ok (failed,
untimed, timeout, ...) as crosses, ok cases with an error above 100%, without a
measured error, or with a missed or extra event with markers and legend
entries of their own, never counted as failed. A line is one integrator,
formulation and mode (adaptive over rtol, fixed over h): an integrator run both
ways draws two lines. The figure marks no target crossings: those are the
table's.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402

from integrator_bench.harness.matrix.line import FAMILIES  # noqa: E402
from integrator_bench.harness.paths import write_atomically  # noqa: E402
from integrator_bench.harness.ranking import reach  # noqa: E402
from integrator_bench.harness.report.names import line_label, slug  # noqa: E402
from integrator_bench.harness.report.ranking_text import AXIS, WORD  # noqa: E402
from integrator_bench.harness.report.style import FAILED_COLOR, styles  # noqa: E402

MAX_LINES = 10
#: the work-precision figure's margins in inches: left of a panel (tick labels, y
#: label), right of the last, between two columns, above the first row (titles)
#: and below each row (tick labels, x label, legend)
LEFT_IN, RIGHT_IN, GAP_W_IN, TOP_IN, BELOW_IN = 0.85, 0.2, 0.75, 0.75, 2.5
FAILED_LABEL = "not ok, at its CPU"
FRONT_LABEL = "Pareto front"
#: the cases off the error axis, by kind: legend text and marker (see :func:`off_axis`)
OFF_AXIS = {"not ok": (FAILED_LABEL, "x"),
            "error above 100%": ("ok, error above 100%", "+"),
            "no error": ("ok, no error measured", "1"),
            "events": ("ok, an event missed or extra", "3")}
#: line style per formulation (colour and marker belong to the integrator)
DASHES = {"ode": "-", "i3": "-", "i2": "--", "i1": ":", "ggl": "-.", "baumgarte": "--",
          "projection": ":", "partitioning": "-."}


def shown_lines(ranked: pd.DataFrame, limit: int = MAX_LINES) -> pd.DataFrame:
    """The lines a panel draws: each integrator's (with its settings: each label's)
    best line first, then the next best lines, ``limit`` in all, in the row order
    of ``ranked`` (a :func:`integrator_bench.harness.ranking.reach.target_table`,
    index 0, 1, ...); lines without an ok point are not drawn."""
    run = ranked[ranked["n_ok"] > 0]
    first = run.drop_duplicates("label")
    rest = run.drop(first.index)
    pick = pd.concat([first.head(limit), rest]).head(limit)
    return run.loc[sorted(pick.index)]


def off_axis(rows: pd.DataFrame, measure: str = reach.DEFAULT_ERROR) -> dict[str, pd.DataFrame]:
    """The cases a panel cannot put on its error axis, by kind (keys of :data:`OFF_AXIS`).

    ``not ok``: every status but ok and unsupported (failed, untimed, timeout,
    crashed, error); ``error above 100%``: ok with an error above 1;
    ``no error``: ok without an error (no reference, an older store without
    the measure); ``events``: ok with an event missed or extra. Kinds without a
    case are left out.
    """
    err = reach.error_values(rows, measure)
    ok = rows["status"] == "ok"
    kinds = {"not ok": ~ok & (rows["status"] != "unsupported"),
             "error above 100%": ok & np.isfinite(err) & (err > 1),
             "no error": ok & err.isna(),
             "events": ok & np.isinf(err)}
    return {k: rows[sel] for k, sel in kinds.items() if sel.any()}


def off_axis_label(kind: str, sub: pd.DataFrame) -> str:
    """``N <legend text>`` of one kind of :func:`off_axis`: the cases not ok counted
    by status too (``12 not ok (11 failed, 1 timeout), at its CPU``: a timeout is not
    a failure of the integrator)."""
    text = OFF_AXIS[kind][0]
    if kind == "not ok":
        counts = sorted(sub["status"].astype(str).value_counts().items(),
                        key=lambda item: (-item[1], item[0]))
        text = FAILED_LABEL.replace("not ok", "not ok (" + ", ".join(
            f"{n} {status}" for status, n in counts) + ")", 1)
    return f"{len(sub)} {text}"


def error_label(measure: str, rows: pd.DataFrame | None = None) -> str:
    """The error axis: the measure's words (the one the problem is ranked by)."""
    name = reach.effective_error(rows, measure) if rows is not None else measure
    spec = reach.ERRORS.get(name)
    return spec.words if spec else f"10^-{name}"


def off_axis_caption(rows: pd.DataFrame, measure: str = reach.DEFAULT_ERROR) -> str:
    """One sentence counting the cases of :func:`off_axis` by kind, with the figure's
    legend text; empty when every case is on the axis."""
    kinds = off_axis(rows, measure)
    if not kinds:
        return ""
    return ("Right of the error axis: "
            + "; ".join(off_axis_label(k, sub) for k, sub in kinds.items()) + ".")


def _panel(ax, rows: pd.DataFrame, ranked: pd.DataFrame, xlim, ylim, style,
           measure: str) -> list:
    pts = reach.line_points(rows, measure)[["label", "formulation", "mode", "err", "cpu_s"]]
    pts = pts[pts["err"] <= 1]      # above 100% or an event wrong: off the axis, not a point
    at = pts.groupby(["label", "formulation", "mode"], sort=False).indices  # a line: its rows
    shown = shown_lines(ranked)
    handles = []
    if len(pts):
        front = pts.iloc[reach.pareto_front(pts["err"], pts["cpu_s"])]
        ax.step(front["err"], front["cpu_s"], where="post", color="black", alpha=0.25,
                linewidth=6, solid_capstyle="round", zorder=1)
        handles.append(Line2D([], [], color="black", alpha=0.25, linewidth=6,
                              label=FRONT_LABEL))
    for line in shown.itertuples(index=False):
        sel = pts.iloc[at.get((line.label, line.formulation, line.mode), [])]
        color, marker = style[line.label]
        handle, = ax.plot(sel["err"], sel["cpu_s"], color=color, marker=marker,
                          linestyle=DASHES.get(line.formulation, "-"),
                          markersize=6, linewidth=1.4, zorder=3,
                          label=line_label(line.label, line.formulation, line.mode))
        handles.append(handle)
    kinds = off_axis(rows, measure)
    if kinds:
        ax.axvspan(xlim[1] * 1.5, xlim[1] * 6.0, color=FAILED_COLOR, alpha=0.12, zorder=0)
    for kind, sub in kinds.items():
        label, marker = OFF_AXIS[kind]
        cpu = sub["cpu_s"].to_numpy(float)
        cpu = np.where(np.isfinite(cpu) & (cpu > 0), cpu, ylim[1] / 1.5)
        ax.plot(np.full(len(cpu), xlim[1] * 3.0), np.clip(cpu, ylim[0], ylim[1]),
                linestyle="none", marker=marker, color=FAILED_COLOR, markersize=8,
                markeredgewidth=2, zorder=2)
        handles.append(Line2D([], [], linestyle="none", marker=marker, color=FAILED_COLOR,
                              markersize=8, markeredgewidth=2, label=off_axis_label(kind, sub)))
    more = int((ranked["n_ok"] > 0).sum()) - len(shown)
    if more > 0:
        handles.append(Line2D([], [], linestyle="none",
                              label=f"+{more} more lines: see the table"))
    if not len(pts):
        ax.text(0.5, 0.5, "no successful runs", transform=ax.transAxes, ha="center")
    return handles


def work_precision_figure(rows: pd.DataFrame, title: str, style: dict | None = None,
                          measure: str = reach.DEFAULT_ERROR, ranked=None,
                          cost: str = "cpu"):
    """Draw one problem's work-precision panels, one per family present; the y
    axis is ``cpu_s``, which holds the work under ``cost`` ``work``
    (:func:`~integrator_bench.harness.ranking.cost.by_cost`).

    Parameters
    ----------
    rows : pandas.DataFrame
        Cleaned records of one problem and parameter set
        (:func:`~integrator_bench.harness.ranking.records.clean_records`).
    title : str
        Figure title.
    style : dict, optional
        Line label -> (colour, marker)
        (:func:`integrator_bench.harness.report.style.styles` of every
        integrator of the report); default: of those in ``rows``.
    measure : str
        The error of the x axis, that of the target table
        (:func:`~integrator_bench.harness.ranking.reach.error_values`).
    ranked : pandas.DataFrame, optional
        The group's target table (computed when not given); each panel draws
        its lines in its order.

    Returns
    -------
    matplotlib.figure.Figure or None
        Panels (in ``FAMILIES`` order, only families with a run case) sharing
        both log axes; None when every case is unsupported. The caller closes it.
    """
    rows = rows[rows["status"] != "unsupported"]
    present = [(key, name) for key, name in FAMILIES.items() if (rows["family"] == key).any()]
    if not present:
        return None
    style = style or styles(rows["label"], dict(zip(rows["label"], rows["integrator"])))
    pts = reach.line_points(rows, measure)
    pts = pts[pts["err"] <= 1]
    if ranked is None:
        ranked = reach.target_table(rows, measure=measure)
    err = pts["err"][np.isfinite(pts["err"])] if len(pts) else pd.Series([], dtype=float)
    err = err if len(err) else pd.Series([1e-6, 1.0])
    cpu = pd.concat([pts["cpu_s"], rows["cpu_s"][rows["cpu_s"] > 0]])
    cpu = cpu[np.isfinite(cpu)]   # a damaged store's inf is no axis limit
    cpu = cpu if len(cpu) else pd.Series([1e-3, 1.0])
    xlim = (err.min() / 3.0, max(err.max() * 3.0, 1e-3))
    ylim = (cpu.min() / 2.0, cpu.max() * 3.0)
    ncols = min(len(present), 2)
    nrows = -(-len(present) // ncols)
    width, height = 6.2 * ncols + 0.4, 6.4 * nrows
    fig, axes = plt.subplots(nrows, ncols, figsize=(width, height), sharex=True, sharey=True,
                             squeeze=False)
    # fixed margins in inches (a layout engine measured every text: most of the drawing
    # time): the title above, the axis label and the legend of up to 16 entries below
    # each panel, the tick labels and the y label left of it
    axes_w = (width - LEFT_IN - RIGHT_IN - (ncols - 1) * GAP_W_IN) / ncols
    axes_h = (height - TOP_IN - nrows * BELOW_IN) / nrows
    fig.subplots_adjust(left=LEFT_IN / width, right=1 - RIGHT_IN / width,
                        top=1 - TOP_IN / height, bottom=BELOW_IN / height,
                        wspace=GAP_W_IN / axes_w, hspace=BELOW_IN / axes_h)
    for ax in axes.flat[len(present):]:
        ax.set_visible(False)
    for ax, (key, name) in zip(axes.flat, present):
        sub = rows[rows["family"] == key]
        lines = {(i, f) for i, f in zip(sub["label"], sub["formulation"])}
        mine = ranked[[(i, f) in lines for i, f in zip(ranked["label"],
                                                       ranked["formulation"])]]
        handles = _panel(ax, sub, mine, xlim, ylim, style, measure)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlim(xlim[0], xlim[1] * 10.0)
        ax.set_ylim(*ylim)
        # y given: the title at 1.0, where matplotlib puts it with the tick labels below
        # the axes, without measuring every shared axis's ticks for it (a third of
        # the drawing time)
        ax.set_title(name, y=1.0)
        ax.set_xlabel(error_label(measure, rows))
        ax.xaxis.set_tick_params(labelbottom=True)
        ax.yaxis.set_tick_params(labelleft=True)
        ax.grid(True, which="major", alpha=0.3)
        ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.13),
                  ncol=2, fontsize="small", frameon=False)
    for row in axes:
        row[0].set_ylabel(AXIS[cost])
    fig.suptitle(title)
    return fig


def scaling_figure(data, out_dir) -> str:
    """Log-log figure of CPU seconds per evaluation or step against ``n_links``.

    Parameters
    ----------
    data : integrator_bench.harness.report.scaling.Scaling
        One measurement file.
    out_dir : pathlib.Path
        Where ``scaling_<file>.png`` is written.

    Returns
    -------
    str
        The name of the file written.
    """
    fig, ax = plt.subplots(figsize=(7.5, 5))
    for key in data.timing_keys():
        pts = [(r["n_links"], r[key]) for r in data.rows
               if r.get(key) is not None and r.get("n_links") is not None and r[key] > 0]
        if pts:
            n, t = zip(*sorted(pts))
            slope = data.slopes.get(key)
            label = key if slope is None else f"{key} (slope {slope:.2f})"
            ax.loglog(n, t, "o-", label=label)
    ax.set_xlabel("links N")
    ax.set_ylabel("CPU seconds per call or step")
    ax.set_title(f"{data.problem}: cost against size")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    name = f"scaling_{slug(data.file, '{}')}.png"
    save(fig, Path(out_dir) / name)
    return name


def save(fig, path: Path) -> Path:
    """Write ``fig`` as PNG (100 dpi) to ``path`` (atomically) and close it."""
    try:
        write_atomically(path, lambda part: fig.savefig(part, dpi=100, format="png"))
    finally:
        plt.close(fig)
    return path


def profiles_figure(data: dict, style: dict, path: Path, targets_=reach.TARGETS,
                    cost: str = "cpu") -> Path:
    """The summary page's figure: per target, the performance profile of CPU
    (``log2 tau``) and the data profile of ``nfev / (n_p + 1)``
    (:mod:`~integrator_bench.harness.report.profiles`), one step curve per
    integrator, in its colour and marker of every other figure; written to ``path``.
    ``cost`` names what the performance profile ranks by (``cpu`` or ``work``,
    :mod:`~integrator_bench.harness.ranking.cost`)."""
    from integrator_bench.harness.report import profiles

    fig, axes = plt.subplots(2, len(targets_), figsize=(6.4 * len(targets_) + 2.6, 9.6),
                             squeeze=False)
    handles = {}
    for j, t in enumerate(targets_):
        d = data[t]
        r = d["ratios"]
        taus = profiles.tau_grid(r, 400)
        perf = profiles.performance_profile(d["cpu"], taus)
        units = d["nfev"].div(data["dimension"] + 1, axis=0)
        u = units.loc[r.index].to_numpy()
        u = u[np.isfinite(u)]
        hi = max(10.0, float(u.max()) * 1.2) if u.size else 10.0
        alphas = np.logspace(0.0, np.log10(hi), 400)
        prof = profiles.data_profile(d["nfev"], data["dimension"], alphas, r.index)
        for s in perf.columns:
            colour, marker = style.get(s.split(" ")[0], ("#555", "o"))
            # the integrator's marker every 50th point tells apart curves of like colour
            marks = dict(color=colour, lw=1.4, marker=marker, markevery=(j * 7 % 50, 50),
                         markersize=5, fillstyle="none")
            (h,) = axes[0, j].step(np.log2(taus), perf[s], where="post", **marks)
            axes[1, j].step(alphas, prof[s], where="post", **marks)
            handles.setdefault(s, h)
        n = len(r)
        name = WORD[cost]
        axes[0, j].set_title(f"performance profile, {name} to {reach.tag(t)} ({n} problems)",
                             y=1.0)      # y given: as above
        axes[0, j].set_xlabel(f"log2 tau ({name} within tau times the best)")
        axes[1, j].set_title(f"data profile, nfev to {reach.tag(t)} ({n} problems)", y=1.0)
        axes[1, j].set_xscale("log")
        axes[1, j].set_xlabel("alpha: nfev / (n + 1), n the problem's states")
        for ax in axes[:, j]:
            ax.set_ylim(-0.02, 1.02)
            ax.set_ylabel("share of problems")
            ax.grid(True, which="both", alpha=0.3)
    fig.legend(list(handles.values()), list(handles), loc="center right", fontsize=8)
    width = 6.4 * len(targets_) + 2.6      # fixed margins: no layout engine (see above)
    fig.subplots_adjust(left=0.7 / width, right=1 - 2.6 / width, bottom=0.07, top=0.96,
                        wspace=0.9 / 6.4 * len(targets_) / 2, hspace=0.3)
    return save(fig, path)
