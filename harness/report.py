"""Report: work-precision figures, tables and an index from result records.

:func:`write_report` takes the DataFrame of records (one row per case, the
fields of :mod:`integrator_bench.harness.record`) and writes, per problem and parameter set, a
work-precision figure (PNG) and a table (CSV and Markdown), plus an
``index.md`` that links them and counts the statuses.
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402

from integrator_bench.harness import tables  # noqa: E402
from integrator_bench.harness.comparison import comparison_markdown  # noqa: E402
from integrator_bench.harness.record import FIELDS, KEY_FIELDS, STATUSES  # noqa: E402

TABLE_COLUMNS = ["integrator", "formulation", "rtol", "h", "status", "nsteps",
                 "nreject", "nfev", "njev", "nlu", "nniter", "nnfail", "cpu_s",
                 "scd", "mescd", "drift_pos", "drift_vel"]
COUNT_COLUMNS = ["nfev", "njev", "nlu", "nsteps", "nreject", "nniter", "nnfail",
                 "nevents"]
FLOAT_COLUMNS = ["rtol", "atol", "h", "scd", "mescd", "err_max", "err_vel",
                 "err_lambda", "drift_pos", "drift_vel", "cpu_s", "wall_s"]
TEXT_DEFAULTS = {"problem": "unknown", "params": "{}", "formulation": "",
                 "integrator": "", "status": "unknown"}
FAILED_LABEL = "failed / timeout / crashed / error"
NULL_MD = tables.NULL
MD_FORMATS = {"rtol": "{:g}", "h": "{:g}", "cpu_s": "{:.3g}", "scd": "{:.2f}",
              "mescd": "{:.2f}", "drift_pos": "{:.3g}", "drift_vel": "{:.3g}"}
# Red is kept for failures; 9 colours and 8 markers give 72 distinct styles.
COLORS = [c for i, c in enumerate(plt.get_cmap("tab10").colors) if i != 3]
MARKERS = "os^vDP*<"


def clean_records(df: pd.DataFrame) -> pd.DataFrame:
    """Normalise the column types and keep the newest record of each case.

    Parameters
    ----------
    df : pandas.DataFrame
        Result records; missing columns of ``FIELDS`` are added as null.

    Returns
    -------
    pandas.DataFrame
        One row per case key (``KEY_FIELDS``), the one with the latest
        ``created``; counts as nullable ``Int64``, measurements as float.
    """
    df = df.copy()
    for col in FIELDS:
        if col not in df.columns:
            df[col] = None
    for col, default in TEXT_DEFAULTS.items():
        df[col] = [default if pd.isna(v) else str(v) for v in df[col]]
    for col in FLOAT_COLUMNS:
        df[col] = pd.to_numeric(df[col], errors="coerce").astype(float)
    for col in COUNT_COLUMNS:
        df[col] = pd.to_numeric(df[col], errors="coerce").round().astype("Int64")
    created = pd.to_datetime(df["created"], utc=True, errors="coerce",
                             format="ISO8601")
    df = (df.assign(_created=created)
            .sort_values("_created", kind="stable", na_position="first")
            .drop_duplicates(subset=list(KEY_FIELDS), keep="last"))
    return df.drop(columns="_created").reset_index(drop=True)


def _params_dict(params: str) -> dict:
    try:
        value = json.loads(params)
    except (TypeError, ValueError):
        return {"params": params}
    return value if isinstance(value, dict) else {"params": value}


def _fmt_value(value) -> str:
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return f"{value:g}"
    return str(value)


def params_label(params: str, sep: str = ", ") -> str:
    """Return ``k=100, m=1`` for the params JSON ``{"k": 100.0, "m": 1}``."""
    items = sorted(_params_dict(params).items())
    return sep.join(f"{k}={_fmt_value(v)}" for k, v in items)


def slug(problem: str, params: str) -> str:
    """Return a filesystem-safe name such as ``spring_pendulum_k=100``.

    Parameters
    ----------
    problem : str
        Problem name.
    params : str
        JSON object of the parameter values; keys are sorted, numbers
        formatted with ``:g``.

    Returns
    -------
    str
        Letters, digits and ``._=+-``; every other run of characters is ``_``.
    """
    text = "_".join(filter(None, [problem, params_label(params, sep="_")]))
    return re.sub(r"[^A-Za-z0-9._=+-]+", "_", text).strip("._") or "group"


def _group_order(key: tuple[str, str]):
    problem, params = key
    items = [(k, 0, float(v), "") if isinstance(v, (int, float))
             and not isinstance(v, bool) else (k, 1, 0.0, str(v))
             for k, v in sorted(_params_dict(params).items())]
    return problem, items, params


def _failed_mask(rows: pd.DataFrame) -> pd.Series:
    ok = rows["status"] == "ok"
    return (~ok & (rows["status"] != "unsupported")) | (ok & ~np.isfinite(rows["mescd"]))


# a finite but absurd error (a fixed-step run that all but blew up: 1e235) is drawn
# at 1e50, so the axis arithmetic stays finite
MAX_PLOTTED_DIGITS_LOST = 50.0


def work_precision_figure(rows: pd.DataFrame, title: str):
    """Draw error vs CPU seconds (left) and error vs nfev (right).

    Parameters
    ----------
    rows : pandas.DataFrame
        Cleaned records of one problem and parameter set.
    title : str
        Figure title.

    Returns
    -------
    matplotlib.figure.Figure
        One line per (integrator, formulation), sorted by tolerance (rtol, or
        h for fixed step). Failed rows are red crosses right of the largest
        plotted error, at their measured cost or else at the panel's top.
        Unsupported rows are left out. The caller closes the figure.
    """
    ok = rows[(rows["status"] == "ok") & np.isfinite(rows["mescd"])]
    ok = ok.assign(_err=10.0 ** -np.maximum(ok["mescd"], -MAX_PLOTTED_DIGITS_LOST))
    failed = rows[_failed_mask(rows)]
    err = ok["_err"]
    lo, hi = (err.min(), err.max()) if len(ok) else (1.0, 1.0)
    fail_x = hi * 10.0
    pairs = sorted(set(zip(ok["integrator"], ok["formulation"])))

    legend_rows = math.ceil((len(pairs) + bool(len(failed))) / 3)
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.6 + 0.25 * legend_rows),
                             layout="constrained")
    panels = [(axes[0], "cpu_s", "CPU time [s]", "error vs CPU time"),
              (axes[1], "nfev", "function evaluations (nfev)",
               "error vs function evaluations")]
    handles = []
    for ax, col, ylabel, panel_title in panels:
        known = []
        for i, (integrator, formulation) in enumerate(pairs):
            sel = ok[(ok["integrator"] == integrator) & (ok["formulation"] == formulation)]
            sel = sel.assign(_tol=sel["rtol"].fillna(sel["h"])).sort_values("_tol")
            x = sel["_err"].to_numpy()
            y = sel[col].astype(float).to_numpy()
            good = np.isfinite(y) & (y > 0)
            known.extend(y[good])
            label = f"{integrator} ({formulation})" if formulation else integrator
            line, = ax.plot(x[good], y[good], marker=MARKERS[i % len(MARKERS)],
                            color=COLORS[i % len(COLORS)], label=label)
            if ax is axes[0]:
                handles.append(line)
        fy = failed[col].astype(float).to_numpy()
        known.extend(fy[np.isfinite(fy) & (fy > 0)])
        top = max(known) * 3.0 if known else 1.0
        bottom = min(known) / 3.0 if known else 0.1
        if len(failed):
            fy = np.where(np.isfinite(fy) & (fy > 0), fy, top)
            ax.plot(np.full(len(fy), fail_x), fy, linestyle="none", marker="x",
                    color="red", markersize=9, markeredgewidth=2)
            ax.axvspan(math.sqrt(hi * fail_x), fail_x * 3.0, color="red", alpha=0.06)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlim(lo / 3.0, fail_x * 3.0 if len(failed) else hi * 3.0)
        ax.set_ylim(bottom, top * 2.0)
        ax.set_xlabel(r"error $10^{-\mathrm{mescd}}$")
        ax.set_ylabel(ylabel)
        ax.set_title(panel_title)
        ax.grid(True, which="major", alpha=0.3)
        if not len(ok):
            counts = rows["status"].value_counts().sort_index()
            note = "no successful runs\n" + ", ".join(f"{n} {s}" for s, n in counts.items())
            ax.text(0.5, 0.5, note, transform=ax.transAxes, ha="center", va="center")
            ax.tick_params(axis="x", which="both", labelbottom=False)
    if len(failed):
        handles.append(Line2D([], [], linestyle="none", marker="x", color="red",
                              markersize=9, markeredgewidth=2, label=FAILED_LABEL))
    if handles:
        fig.legend(handles=handles, loc="outside lower center",
                   ncol=min(3, len(handles)), fontsize="small")
    fig.suptitle(title)
    return fig


def _sorted(rows: pd.DataFrame) -> pd.DataFrame:
    return rows.sort_values(["integrator", "formulation", "rtol", "h"],
                            ascending=[True, True, False, False],
                            na_position="last", kind="stable")


def group_table(rows: pd.DataFrame) -> pd.DataFrame:
    """Return ``TABLE_COLUMNS`` sorted by integrator, formulation, rtol and h.

    Tolerances and step sizes sort descending, nulls last.
    """
    return _sorted(rows)[TABLE_COLUMNS].reset_index(drop=True)


def _compact(table: pd.DataFrame) -> pd.DataFrame:
    """Round cpu_s and drifts to 3 significant digits, scd and mescd to 2 decimals."""
    def sig3(s):
        return s.map(lambda v: float(f"{v:.3g}") if pd.notna(v) else v)
    return table.assign(cpu_s=sig3(table["cpu_s"]), scd=table["scd"].round(2),
                        mescd=table["mescd"].round(2), drift_pos=sig3(table["drift_pos"]),
                        drift_vel=sig3(table["drift_vel"]))


def _md_cell(value, col: str) -> str:
    if pd.isna(value):
        return NULL_MD
    if col in COUNT_COLUMNS:
        return str(int(value))
    if col in MD_FORMATS:
        return MD_FORMATS[col].format(value)
    return str(value)


def markdown_table(table: pd.DataFrame) -> str:
    """Format a table as GitHub Markdown (:func:`integrator_bench.harness.tables.markdown_table`);
    numeric columns right-aligned, nulls ``–``."""
    cols = list(table.columns)
    right = [c for c in cols if pd.api.types.is_numeric_dtype(table[c])]
    rows = ([_md_cell(v, c) for v, c in zip(row, cols)] for row in table.itertuples(index=False))
    return tables.markdown_table(cols, rows, right)


def _messages(rows: pd.DataFrame) -> list[str]:
    out = []
    for row in _sorted(rows[rows["status"] != "ok"]).itertuples(index=False):
        tol = f"rtol={row.rtol:g}" if pd.notna(row.rtol) else f"h={row.h:g}"
        lines = str(row.message).strip().splitlines() if pd.notna(row.message) else []
        why = f" — {lines[0][:200]}" if lines else ""
        out.append(f"- {row.integrator} ({row.formulation}), {tol}: **{row.status}**{why}")
    return out


def write_report(df: pd.DataFrame, out_dir: Path, runs: pd.DataFrame | None = None) -> list[Path]:
    """Write figures, tables and ``index.md`` for a DataFrame of records.

    Parameters
    ----------
    df : pandas.DataFrame
        Result records, one row per case, with the columns of
        ``integrator_bench.harness.record.FIELDS``. Of repeated cases (same ``KEY_FIELDS``)
        only the newest by ``created`` is kept.
    out_dir : pathlib.Path
        Output directory, created if needed.
    runs : pandas.DataFrame, optional
        The store's runs (``integrator_bench.harness.store.load_runs``): their provenance
        becomes a "Runs" section of ``index.md``.

    Returns
    -------
    list of pathlib.Path
        Per group (problem and params, sorted) its ``<slug>.png``,
        ``<slug>.csv`` and ``<slug>.md``, then ``index.md``. An empty
        DataFrame gives ``index.md`` alone.
    """
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    index = out_dir / "index.md"
    if len(df) == 0:
        index.write_text("# Integrator benchmark report\n\nNo records.\n", encoding="utf-8")
        return [index]

    records = clean_records(df)
    written, used, entries = [], set(), []
    groups = records.groupby(["problem", "params"], sort=False)
    for key in sorted(groups.groups, key=_group_order):
        problem, params = key
        rows = groups.get_group(key)
        name = base = slug(problem, params)
        n = 1
        while name in used:
            n += 1
            name = f"{base}_{n}"
        used.add(name)
        label = params_label(params)
        title = f"{problem} ({label})" if label else problem

        fig = work_precision_figure(rows, title)
        png = out_dir / f"{name}.png"
        fig.savefig(png, dpi=110)
        plt.close(fig)

        table = group_table(rows)
        csv = out_dir / f"{name}.csv"
        table.to_csv(csv, index=False)
        md = out_dir / f"{name}.md"
        text = f"# {title}\n\n![work-precision]({png.name})\n\n" + markdown_table(table)
        text += comparison_markdown(rows)
        messages = _messages(rows)
        if messages:
            text += "\n## Not ok\n\n" + "\n".join(messages) + "\n"
        md.write_text(text, encoding="utf-8")
        written += [png, csv, md]
        n_ok = int((rows["status"] == "ok").sum())
        entries.append((problem, label, len(rows), n_ok, f"[png]({png.name})",
                        f"[csv]({csv.name})", f"[md]({md.name})"))

    counts = records["status"].value_counts()
    statuses = list(STATUSES) + sorted(set(counts.index) - set(STATUSES))
    dropped = len(df) - len(records)
    lines = ["# Integrator benchmark report", "",
             f"{len(records)} records ({dropped} superseded repeats dropped).", "",
             "## Status", ""]
    lines += tables.markdown_lines(("status", "count"),
                                   [(s, int(counts.get(s, 0))) for s in statuses], ["count"])
    lines += ["", "## Problems", ""]
    lines += tables.markdown_lines(
        ("problem", "parameters", "cases", "ok", "figure", "CSV", "Markdown"), entries,
        ["cases", "ok"])
    if runs is not None:
        from integrator_bench.harness.provenance import runs_markdown
        lines += [""] + runs_markdown(runs)
    index.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return written + [index]
