"""Report: work-precision figures, tables and an index from result records.

:func:`write_report` takes the DataFrame of records (one row per case, the
fields of :mod:`integrator_bench.harness.record`) and writes, per problem and parameter set, a
work-precision figure (PNG) and a table (CSV and Markdown), plus an
``index.md`` that links them and counts the statuses.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402

from integrator_bench.harness import html_report, reach, tables  # noqa: E402
from integrator_bench.harness.comparison import comparison_markdown  # noqa: E402
from integrator_bench.harness.record import FIELDS, KEY_FIELDS, STATUSES  # noqa: E402
from integrator_bench.harness.wp_figure import with_family, work_precision_figure  # noqa: E402

TABLE_COLUMNS = ["integrator", "formulation", "rtol", "h", "status", "nsteps",
                 "nreject", "nfev", "njev", "nlu", "nniter", "nnfail", "cpu_s",
                 "scd", "mescd", "drift_pos", "drift_vel"]
COUNT_COLUMNS = ["nfev", "njev", "nlu", "nsteps", "nreject", "nniter", "nnfail",
                 "nevents"]
FLOAT_COLUMNS = ["rtol", "atol", "h", "scd", "mescd", "err_max", "err_vel",
                 "err_lambda", "drift_pos", "drift_vel", "cpu_s", "wall_s"]
TEXT_DEFAULTS = {"problem": "unknown", "params": "{}", "formulation": "",
                 "integrator": "", "status": "unknown"}
NULL_MD = tables.NULL
MD_FORMATS = {"rtol": "{:g}", "h": "{:g}", "cpu_s": "{:.3g}", "scd": "{:.2f}",
              "mescd": "{:.2f}", "drift_pos": "{:.3g}", "drift_vel": "{:.3g}"}


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


def _group_files(rows, title, name, out_dir, include_unsupported) -> tuple[list[Path], dict]:
    """Write one group's figure, CSV and Markdown; return the paths and its page entry."""
    written = []
    fig = work_precision_figure(rows, title)
    png = None
    if fig is not None:
        png = out_dir / f"{name}.png"
        fig.savefig(png, dpi=100)
        plt.close(fig)
        written.append(png)
    table = group_table(rows)
    csv = out_dir / f"{name}.csv"
    table.to_csv(csv, index=False)
    md = out_dir / f"{name}.md"
    shown = table if include_unsupported else table[table["status"] != "unsupported"]
    text = f"# {title}\n\n" + (f"![work-precision]({png.name})\n\n" if png else "")
    text += markdown_table(shown.reset_index(drop=True))
    if not include_unsupported and len(shown) < len(table):
        text += f"\n{len(table) - len(shown)} unsupported cases left out (see the CSV).\n"
    text += comparison_markdown(rows)
    messages = _messages(rows if include_unsupported else rows[rows["status"] != "unsupported"])
    if messages:
        text += "\n## Not ok\n\n" + "\n".join(messages) + "\n"
    md.write_text(text, encoding="utf-8")
    fam = with_family(rows[rows["status"] != "unsupported"])
    families = dict(zip(zip(fam["integrator"], fam["formulation"]), fam["family"]))
    entry = {"anchor": name, "slug": name, "title": title, "problem": rows["problem"].iloc[0],
             "rows": rows, "figure": png.name if png else None, "families": families,
             "ranked": reach.reach_table(rows)}
    return written + [csv, md], entry


def write_report(df: pd.DataFrame, out_dir: Path, runs: pd.DataFrame | None = None,
                 include_unsupported: bool = False,
                 stiffness: dict[str, str] | None = None) -> list[Path]:
    """Write figures, tables, ``index.md`` and ``index.html`` for a DataFrame of records.

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
        becomes a "Runs" section of ``index.md`` and ``index.html``.
    include_unsupported : bool
        Keep ``unsupported`` cases in the Markdown tables (the CSV always has them).
    stiffness : dict, optional
        Problem name -> text of its stiffness figures, shown on the page when given.

    Returns
    -------
    list of pathlib.Path
        Per group (problem and params, sorted) its ``<slug>.png`` (absent when
        every case is unsupported), ``<slug>.csv`` and ``<slug>.md``, then
        ``index.md`` and ``index.html``. An empty DataFrame gives the two indexes.
    """
    from integrator_bench.harness.provenance import runs_markdown

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    index, page = out_dir / "index.md", out_dir / "index.html"
    runs_lines = runs_markdown(runs) if runs is not None else []
    if len(df) == 0:
        index.write_text("# Integrator benchmark report\n\nNo records.\n", encoding="utf-8")
        page.write_text(html_report.page([], [], 0, runs_lines), encoding="utf-8")
        return [index, page]

    records = clean_records(df)
    written, used, entries, groups_html = [], set(), [], []
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
        files, group = _group_files(rows, title, name, out_dir, include_unsupported)
        group["stiffness"] = (stiffness or {}).get(problem)
        written += files
        groups_html.append(group)
        n_ok = int((rows["status"] == "ok").sum())
        figure = f"[png]({name}.png)" if group["figure"] else ""
        entries.append((problem, label, len(rows), n_ok, figure,
                        f"[csv]({name}.csv)", f"[md]({name}.md)"))

    counts = records["status"].value_counts()
    statuses = list(STATUSES) + sorted(set(counts.index) - set(STATUSES))
    status_counts = [(s, int(counts.get(s, 0))) for s in statuses]
    dropped = len(df) - len(records)
    lines = ["# Integrator benchmark report", "",
             f"{len(records)} records ({dropped} superseded repeats dropped).", "",
             "## Status", ""]
    lines += tables.markdown_lines(("status", "count"), status_counts, ["count"])
    lines += ["", "## Problems", ""]
    lines += tables.markdown_lines(
        ("problem", "parameters", "cases", "ok", "figure", "CSV", "Markdown"), entries,
        ["cases", "ok"])
    if runs is not None:
        lines += [""] + runs_lines
    index.write_text("\n".join(lines) + "\n", encoding="utf-8")
    page.write_text(html_report.page(groups_html, status_counts, len(records), runs_lines),
                    encoding="utf-8")
    return written + [index, page]
