"""The records a ranking reads: cleaned, the advice's kept apart.

:func:`clean_records` normalises a DataFrame of result records (the fields of
:mod:`integrator_bench.harness.matrix.record`), keeps the newest record of each
case and fills the fields of its line a record lacks
(:func:`~integrator_bench.harness.matrix.line.backfill`); the ranking's functions
take records with every field, as it gives them. :func:`split_advice` sets apart
the records an advice stored. A *line* of a problem and parameter set is one
integrator with its settings, formulation and mode (adaptive at its ``rtol`` or
fixed at its ``h``) over its tolerances or step sizes
(:class:`~integrator_bench.harness.matrix.line.Line`); the tables, figures and
answers group and name it by its ``label`` (``cvode-bdf (max_order=2)``), which
keeps an integrator run with settings apart from its defaults, while
``integrator`` holds the registry name. :func:`unresponsive` finds the adaptive
lines that ignore their tolerance.
"""

from __future__ import annotations

import json

import pandas as pd

from integrator_bench.harness.matrix.line import KEY_FIELDS, backfill
from integrator_bench.harness.matrix.provenance import ADVISE
from integrator_bench.harness.matrix.record import FIELDS

COUNT_COLUMNS = ["nfev", "njev", "nlu", "nsteps", "nreject", "nniter", "nnfail",
                 "nevents", "events_matched", "events_missed", "events_spurious"]
FLOAT_COLUMNS = ["rtol", "atol", "h", "scd", "mescd", "err_max", "err_rms", "err_max_rel",
                 "err_rms_rel", "err_floor", "final_degenerate", "err_vel",
                 "err_lambda", "drift_pos", "drift_vel", "cpu_s", "wall_s",
                 "event_time_err", "event_state_err"]
TEXT_DEFAULTS = {"problem": "unknown", "params": "{}", "formulation": "",
                 "integrator": "", "status": "unknown"}
#: the columns a line's records are grouped by: the report's view of
#: :attr:`~integrator_bench.harness.matrix.line.Line.key` (the ``label`` stands for the
#: integrator and its settings)
LINE = ["problem", "params", "label", "formulation", "mode"]


def clean_records(df: pd.DataFrame) -> pd.DataFrame:
    """Normalise the column types, keep the newest record of each case and fill
    its line's fields.

    Parameters
    ----------
    df : pandas.DataFrame
        Result records; missing columns of ``FIELDS`` are added as null.

    Returns
    -------
    pandas.DataFrame
        One row per case key (``KEY_FIELDS``), the one with the latest
        ``created``; counts as nullable ``Int64``, measurements as float; the
        line's ``mode``, ``line``, ``label`` and ``family`` filled where a record
        lacks them (:func:`~integrator_bench.harness.matrix.line.backfill`).
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
    return backfill(df.drop(columns="_created").reset_index(drop=True))


def advice_run_ids(runs: pd.DataFrame | None) -> set:
    """The ids of the runs an advice made: ``purpose`` ``advise`` (a store's runs,
    :meth:`~integrator_bench.harness.matrix.store.Store.runs`, all have one)."""
    if runs is None or not len(runs):
        return set()
    return set(runs.loc[runs["purpose"] == ADVISE, "run_id"])


def split_advice(df: pd.DataFrame, runs: pd.DataFrame | None):
    """``(own, advice)``: the records of ``df`` stored by runs of the matrix, and
    those an advice stored (:func:`advice_run_ids`), which the report keeps apart
    so that a problem's answer rests on its own runs, as ``ibench run``'s summary
    does."""
    ids = advice_run_ids(runs)
    if not ids or "run_id" not in df.columns:
        return df, df.iloc[:0]
    advice = df["run_id"].isin(ids)
    return df[~advice], df[advice]


#: what must be identical across a line's tolerances for :func:`unresponsive`
SAME_COLUMNS = ["nfev", "njev", "nlu", "nsteps", "nreject", "nniter", "nnfail", "scd",
                "mescd", "err_max"]


def unresponsive(rows: pd.DataFrame) -> list[dict]:
    """The adaptive lines of ``rows`` that do not respond to ``rtol``: two or more
    ``ok`` or ``failed`` records at different tolerances, identical in status,
    reason, every count and error (:data:`SAME_COLUMNS`), as an integrator that
    ignores its tolerance gives, and an error (``err_max``) not already below
    the tightest of them (a method exact on the problem, such as RADAU5 on a
    piecewise-quadratic solution, takes the same steps at every tolerance for a
    good reason).
    One dict per line: its :data:`LINE` columns and ``rtols``. ``rows``: records
    with every field (:func:`clean_records`)."""
    if rows.empty:
        return []
    ok = rows.loc[rows["status"].isin(["ok", "failed"])
                  & pd.to_numeric(rows["rtol"], errors="coerce").notna(),
                  LINE + ["rtol", "status", "reason"] + SAME_COLUMNS]
    # the lines alike at two or more tolerances, counted for all of them at once;
    # each of those is then looked at as below
    alike = ok.assign(rtol=pd.to_numeric(ok["rtol"]),
                      **{c: ok[c].astype("float64") for c in SAME_COLUMNS})
    counts = alike.groupby(LINE, sort=True).nunique(dropna=False)
    others = counts.columns.drop("rtol")
    candidates = counts.index[(counts["rtol"] >= 2) & (counts[others] == 1).all(axis=1)]
    lines = ok.groupby(LINE, sort=True)
    found = []
    for key in candidates:
        line = lines.get_group(key)
        rtols = sorted(set(pd.to_numeric(line["rtol"])), reverse=True)
        if len(rtols) < 2:
            continue
        same = line[SAME_COLUMNS].astype("float64")
        outcome = line[["status", "reason"]]
        exact = bool((same["err_max"] <= min(rtols)).all())
        if not exact and all(same[c].nunique(dropna=False) == 1 for c in same) and \
                all(outcome[c].nunique(dropna=False) == 1 for c in outcome):
            found.append(dict(zip(LINE, key), rtols=rtols))
    return found


def params_dict(params: str) -> dict:
    """The parameter values of a record's ``params`` JSON (``{"params": text}``
    when it is not a JSON object)."""
    try:
        value = json.loads(params)
    except (TypeError, ValueError):
        return {"params": params}
    return value if isinstance(value, dict) else {"params": value}


