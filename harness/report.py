"""Report: work-precision figures, tables and an index from result records.

:func:`write_report` takes the DataFrame of records (one row per case, the
fields of :mod:`integrator_bench.harness.record`) and writes, per problem and parameter set, a
work-precision figure (PNG) and a table (CSV and Markdown), plus an
``index.md`` that links them and counts the statuses. Each problem gets the
"CPU to reach a target error" table (:mod:`integrator_bench.harness.targets`);
when scaling measurements (``<data dir>/scaling/*.json``, written by
``benchmarks/chain_scaling.py``) exist, a "Scaling" section shows them as a
log-log figure with the fitted slopes. A problem whose records carry event
measures (state events, issue 14) gets an "Events" table in its Markdown and
in ``index.md`` (:func:`events_markdown`).
"""

from __future__ import annotations

import hashlib
import json
import re
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import pandas as pd  # noqa: E402

from integrator_bench.harness import html_report, tables, targets  # noqa: E402
from integrator_bench.harness.comparison import comparison_markdown  # noqa: E402
from integrator_bench.harness.record import FIELDS, KEY_FIELDS, STATUSES  # noqa: E402
from integrator_bench.harness.wp_figure import with_family, work_precision_figure  # noqa: E402

TABLE_COLUMNS = ["integrator", "formulation", "rtol", "h", "status", "nsteps",
                 "nreject", "nfev", "njev", "nlu", "nniter", "nnfail", "cpu_s",
                 "scd", "mescd", "drift_pos", "drift_vel"]
COUNT_COLUMNS = ["nfev", "njev", "nlu", "nsteps", "nreject", "nniter", "nnfail",
                 "nevents", "events_missed", "events_spurious"]
FLOAT_COLUMNS = ["rtol", "atol", "h", "scd", "mescd", "err_max", "err_vel",
                 "err_lambda", "drift_pos", "drift_vel", "cpu_s", "wall_s",
                 "event_time_err", "event_state_err"]
EVENT_HEADER = ("integrator", "formulation", "tolerance", "nevents", "missed", "spurious",
                "event-time error", "state error after last event")
TEXT_DEFAULTS = {"problem": "unknown", "params": "{}", "formulation": "",
                 "integrator": "", "status": "unknown"}
NULL_MD = tables.NULL
MAX_SLUG = 120
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
        A name longer than ``MAX_SLUG`` characters (a problem with many
        parameters, e.g. chain_drive's 23) keeps its first 80 and ends with
        ``_`` and 10 hex digits of the SHA-1 of the whole text, so file names
        stay within the file system's limit and distinct.
    """
    text = "_".join(filter(None, [problem, params_label(params, sep="_")]))
    name = re.sub(r"[^A-Za-z0-9._=+-]+", "_", text).strip("._") or "group"
    if len(name) > MAX_SLUG:
        digest = hashlib.sha1(text.encode("utf-8")).hexdigest()[:10]
        name = f"{name[:80].rstrip('._')}_{digest}"
    return name


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


def target_markdown(table: pd.DataFrame, level: str = "##") -> list[str]:
    """The "CPU to reach a target error" section of one problem, as Markdown lines.

    Parameters
    ----------
    table : pandas.DataFrame
        :func:`integrator_bench.harness.targets.target_table` of the problem.
    level : str
        Markdown heading marks of the section title.
    """
    header, body = targets.markdown_rows(table)
    right = header[2:]
    lines = [f"{level} CPU to reach a target error", "", targets.CAPTION, ""]
    if not len(body):
        return lines + ["No line ran."]
    return lines + tables.markdown_lines(header, body, right)


EVENT_CAPTION = ("Matched against the reference's event sequence by kind and order; "
                 "time error in time units, state error mixed (error components).")


def events_markdown(rows: pd.DataFrame, level: str | None = "##") -> list[str]:
    """The "Events" table of one problem's records, as Markdown lines.

    One line per record that has event measures (``events_by_kind`` set: an
    ``ok`` run of a problem with events): integrator, formulation, tolerance
    (``rtol=`` or ``h=``), events located, missed and spurious events, the
    largest event-time error and the mixed state error after the last matched
    event. No lines for a problem without events; with ``level`` None the
    table alone, without heading and caption.
    """
    shown = _sorted(rows[rows["events_by_kind"].notna()])
    if not len(shown):
        return []
    body = []
    for row in shown.itertuples(index=False):
        tol = f"rtol={row.rtol:g}" if pd.notna(row.rtol) else f"h={row.h:g}"
        body.append((row.integrator, row.formulation, tol,
                     *(None if pd.isna(v) else int(v)
                       for v in (row.nevents, row.events_missed, row.events_spurious)),
                     *(None if pd.isna(v) else f"{v:.2e}"
                       for v in (row.event_time_err, row.event_state_err))))
    table = tables.markdown_lines(EVENT_HEADER, body, EVENT_HEADER[3:])
    return table if level is None else [f"{level} Events", "", EVENT_CAPTION, ""] + table


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
    target_rows = targets.target_table(rows)
    text += "\n" + "\n".join(target_markdown(target_rows)) + "\n"
    text += comparison_markdown(rows)
    event_lines = events_markdown(rows)
    if event_lines:
        text += "\n" + "\n".join(event_lines) + "\n"
    messages = _messages(rows if include_unsupported else rows[rows["status"] != "unsupported"])
    if messages:
        text += "\n## Not ok\n\n" + "\n".join(messages) + "\n"
    md.write_text(text, encoding="utf-8")
    fam = with_family(rows[rows["status"] != "unsupported"])
    families = dict(zip(zip(fam["integrator"], fam["formulation"]), fam["family"]))
    entry = {"anchor": name, "slug": name, "title": title, "problem": rows["problem"].iloc[0],
             "rows": rows, "figure": png.name if png else None, "families": families,
             "targets": target_rows, "events": events_markdown(rows, None)}
    return written + [csv, md], entry


SCALING_TARGETS = {"rhs_and_jac_slope_max": "right-hand side, residual and Jacobian",
                   "step_slope_max": "step"}


def load_scaling(scaling_dir: Path | None) -> list[dict]:
    """The scaling measurements ``scaling_dir/*.json``, sorted by file name.

    Parameters
    ----------
    scaling_dir : pathlib.Path or None
        Directory of the JSON files ``benchmarks/chain_scaling.py`` writes
        (``{"problem", "created", "machine", "rows": [{"n_links", ...}],
        "slopes": {...}, "targets": {...}}``); None or a missing directory
        gives none.

    Returns
    -------
    list of dict
        The parsed files, each with ``"file"`` (its stem) added. A file that
        cannot be read or is not a JSON object with ``rows`` is left out with a
        ``UserWarning`` naming it, so that one bad file never costs the report.
    """
    if scaling_dir is None or not Path(scaling_dir).is_dir():
        return []
    out = []
    for path in sorted(Path(scaling_dir).glob("*.json")):
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, ValueError) as exc:
            warnings.warn(f"{path}: left out of the report, not readable as JSON ({exc})",
                          stacklevel=2)
            continue
        if not isinstance(data, dict) or not isinstance(data.get("rows"), list):
            warnings.warn(f"{path}: left out of the report, not a scaling file "
                          "(a JSON object with 'rows')", stacklevel=2)
            continue
        out.append({**data, "file": path.stem})
    return out


def _timing_keys(rows: list[dict]) -> list[str]:
    keys = dict.fromkeys(k for r in rows for k in r if k.endswith("_s"))
    return list(keys)


def slope_target(key: str, limits: dict) -> float | None:
    """The slope bound of a timing ``key``: ``step_*`` keys take ``step_slope_max``,
    the other timings (right-hand side, residual, Jacobian) ``rhs_and_jac_slope_max``."""
    name = "step_slope_max" if key.startswith("step_") else "rhs_and_jac_slope_max"
    value = limits.get(name)
    return None if value is None else float(value)


def scaling_figure(data: dict, out_dir: Path) -> Path:
    """Log-log figure of CPU seconds per evaluation or step against ``n_links``."""
    rows = data["rows"]
    fig, ax = plt.subplots(figsize=(7.5, 5))
    for key in _timing_keys(rows):
        pts = [(r["n_links"], r[key]) for r in rows
               if r.get(key) is not None and r.get("n_links") is not None and r[key] > 0]
        if pts:
            n, t = zip(*sorted(pts))
            slope = data.get("slopes", {}).get(key)
            label = key if slope is None else f"{key} (slope {slope:.2f})"
            ax.loglog(n, t, "o-", label=label)
    ax.set_xlabel("links N")
    ax.set_ylabel("CPU seconds per call or step")
    ax.set_title(f"{data.get('problem', data['file'])}: cost against size")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    png = Path(out_dir) / f"scaling_{slug(str(data['file']), '{}')}.png"
    fig.savefig(png, dpi=100)
    plt.close(fig)
    return png


def scaling_tables(data: dict) -> tuple[tuple, list, tuple, list]:
    """The slopes table (quantity, slope, bound, within) and the measurements table."""
    limits = data.get("targets", {})
    slopes = []
    for key, slope in data.get("slopes", {}).items():
        bound = slope_target(key, limits) if key.endswith("_s") else None
        within = "–" if bound is None or slope is None else ("yes" if slope <= bound else "no")
        slopes.append((key, "–" if slope is None else f"{slope:.2f}",
                       "–" if bound is None else f"{bound:g}", within))
    cols = list(dict.fromkeys(k for r in data["rows"] for k in r))
    body = [[_fmt_value(r.get(c)) if r.get(c) is not None else None for c in cols]
            for r in data["rows"]]
    return ("quantity", "log-log slope", "bound", "within"), slopes, tuple(cols), body


def scaling_markdown(items: list[tuple[dict, str]]) -> list[str]:
    """The "Scaling" section of ``index.md``: per file its figure and tables."""
    if not items:
        return []
    lines = ["", "## Scaling", "",
             "CPU seconds per right-hand side, residual, Jacobian and step against the "
             "number of links; slopes fitted on log-log axes (1: linear growth)."]
    for data, png in items:
        head, slopes, cols, body = scaling_tables(data)
        lines += ["", f"### {data.get('problem', data['file'])}", "",
                  f"Created {data.get('created', '–')} on {data.get('machine', '–')}.", "",
                  f"![scaling]({png})", ""]
        lines += tables.markdown_lines(head, slopes, ["log-log slope", "bound"])
        lines += [""] + tables.markdown_lines(cols, body, cols)
    return lines


def write_report(df: pd.DataFrame, out_dir: Path, runs: pd.DataFrame | None = None,
                 include_unsupported: bool = False,
                 stiffness: dict[str, str] | None = None,
                 scaling_dir: Path | None = None) -> list[Path]:
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
    scaling_dir : pathlib.Path, optional
        Where the scaling measurements are (:func:`load_scaling`); default
        ``<data dir>/scaling`` (:mod:`integrator_bench.harness.paths`). With
        any ``*.json`` there, ``index.md`` and ``index.html`` get a "Scaling"
        section and ``scaling_<name>.png`` is written.

    Returns
    -------
    list of pathlib.Path
        Per group (problem and params, sorted) its ``<slug>.png`` (absent when
        every case is unsupported), ``<slug>.csv`` and ``<slug>.md``, then the
        scaling figures, then ``index.md`` and ``index.html``. An empty
        DataFrame gives the scaling figures and the two indexes.
    """
    from integrator_bench.harness.paths import DATA_DIR
    from integrator_bench.harness.provenance import runs_markdown

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    index, page = out_dir / "index.md", out_dir / "index.html"
    runs_lines = runs_markdown(runs) if runs is not None else []
    scaling = load_scaling(DATA_DIR / "scaling" if scaling_dir is None else scaling_dir)
    scaling_items = [(data, scaling_figure(data, out_dir).name) for data in scaling]
    scaling_files = [out_dir / png for _, png in scaling_items]
    if len(df) == 0:
        text = "# Integrator benchmark report\n\nNo records.\n"
        index.write_text(text + "\n".join(scaling_markdown(scaling_items)), encoding="utf-8")
        page.write_text(html_report.page([], [], 0, runs_lines, scaling_items),
                        encoding="utf-8")
        return scaling_files + [index, page]

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
    lines += ["", "## CPU to reach a target error", "", targets.CAPTION]
    for group in groups_html:
        header, body = targets.markdown_rows(group["targets"])
        lines += ["", f"### {group['title']}", ""]
        lines += tables.markdown_lines(header, body, header[2:]) if body else ["No line ran."]
    event_groups = [(group["title"], events_markdown(group["rows"], None))
                    for group in groups_html]
    if any(table for _, table in event_groups):
        lines += ["", "## Events", "", EVENT_CAPTION]
        for title, table in event_groups:
            if table:
                lines += ["", f"### {title}", ""] + table
    lines += scaling_markdown(scaling_items)
    if runs is not None:
        lines += [""] + runs_lines
    index.write_text("\n".join(lines) + "\n", encoding="utf-8")
    page.write_text(html_report.page(groups_html, status_counts, len(records), runs_lines,
                                     scaling_items), encoding="utf-8")
    return written + scaling_files + [index, page]
