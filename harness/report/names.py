"""How the report names and orders its groups and lines, and a group's table.

A *group* is one problem and parameter set, named on disk by :func:`slug` and on
the page by :func:`params_label`, ordered by :func:`group_order`; a line is named
in figures by :func:`line_label`. :func:`group_table` is a group's records as the
page's table of them.
"""

from __future__ import annotations

import hashlib
import re

import pandas as pd

from integrator_bench.harness.ranking.records import params_dict

TABLE_COLUMNS = ["integrator", "formulation", "rtol", "h", "status", "nsteps",
                 "nreject", "nfev", "njev", "nlu", "nniter", "nnfail", "cpu_s",
                 "scd", "mescd", "err_max", "err_rms", "drift_pos", "drift_vel"]
#: the record field a column of :data:`TABLE_COLUMNS` shows, where it is not its name:
#: the ``integrator`` column names the line, the integrator with its settings
TABLE_FIELDS = {"integrator": "label"}
MAX_SLUG = 120


def unresponsive_label(line: dict) -> str:
    """``"heun (ode): does not respond to rtol (identical counts and errors at rtol
    0.001, 1e-06)"``."""
    return (f"{line['label']} ({line['formulation']}): does not respond to rtol "
            f"(identical counts and errors at rtol {', '.join(f'{r:g}' for r in line['rtols'])})")


def fmt_value(value) -> str:
    """A number with ``:g``, anything else with ``str``."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return f"{value:g}"
    return str(value)


def params_label(params: str, sep: str = ", ") -> str:
    """Return ``k=100, m=1`` for the params JSON ``{"k": 100.0, "m": 1}``."""
    items = sorted(params_dict(params).items())
    return sep.join(f"{k}={fmt_value(v)}" for k, v in items)


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


def group_order(key: tuple[str, str]):
    """Sort key of a group ``(problem, params)``: by problem, then parameter values
    (numbers numerically)."""
    problem, params = key
    items = [(k, 0, float(v), "") if isinstance(v, (int, float))
             and not isinstance(v, bool) else (k, 1, 0.0, str(v))
             for k, v in sorted(params_dict(params).items())]
    return problem, items, params


def sorted_rows(rows: pd.DataFrame) -> pd.DataFrame:
    """``rows`` by label (the integrator with its settings), formulation, then rtol
    and h descending, nulls last."""
    return rows.sort_values(["label", "formulation", "rtol", "h"],
                            ascending=[True, True, False, False],
                            na_position="last", kind="stable")


def group_table(rows: pd.DataFrame) -> pd.DataFrame:
    """Return ``TABLE_COLUMNS`` sorted by label, formulation, rtol and h; the
    ``integrator`` column shows the label (:data:`TABLE_FIELDS`).

    Tolerances and step sizes sort descending, nulls last.
    """
    table = sorted_rows(rows)[[TABLE_FIELDS.get(c, c) for c in TABLE_COLUMNS]]
    return table.set_axis(TABLE_COLUMNS, axis=1).reset_index(drop=True)


def tol_label(rtol, h) -> str:
    """``rtol=1e-06`` for an adaptive case, ``h=0.01`` for a fixed step, else ``""``."""
    if pd.notna(rtol):
        return f"rtol={rtol:g}"
    return f"h={h:g}" if pd.notna(h) else ""


def line_label(integrator: str, formulation: str, line_mode: str = "rtol") -> str:
    """How a line is named in figures: ``rk4 (ode)``, ``hht (i3, fixed h)``."""
    fixed = ", fixed h" if line_mode == "h" else ""
    return f"{integrator} ({formulation}{fixed})"
