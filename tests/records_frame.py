"""Record frames for tests that build records by hand.

The ranking, the report and the summary take records with every field of
:data:`~integrator_bench.harness.matrix.record.FIELDS`, as a store gives them and
:func:`~integrator_bench.harness.ranking.records.clean_records` makes them; a test
writes only the fields it is about and completes them here, never in each test.
"""

from __future__ import annotations

import json

import pandas as pd

from integrator_bench.harness.matrix.line import backfill
from integrator_bench.harness.matrix.record import FIELDS
from integrator_bench.harness.ranking.margin import MIN_PAIRED
from integrator_bench.harness.ranking.records import TEXT_DEFAULTS


def exact(cpu: float, n: int = MIN_PAIRED) -> str:
    """A record's ``cpu_samples`` for ``n`` timed solves that all took ``cpu`` seconds:
    a record whose margin over another is known exactly (a test about something
    else than the noise)."""
    return json.dumps([float(cpu)] * n)


def records_frame(rows, **same) -> pd.DataFrame:
    """The records ``rows`` (dicts, or a DataFrame), each with the fields ``same``
    too, as a DataFrame with every field: those not given null (the text fields of
    :data:`~integrator_bench.harness.ranking.records.TEXT_DEFAULTS` their default,
    ``params`` ``{}``), and the line's ``mode``, ``line``, ``label`` and ``family``
    filled from the others (:func:`~integrator_bench.harness.matrix.line.backfill`).
    Nothing else changes: no record is dropped, no type converted."""
    df = pd.DataFrame(rows).assign(**same)
    df = df.assign(**{name: None for name in FIELDS if name not in df.columns})
    df = df.assign(**{name: df[name].astype(object).where(df[name].notna(), default)
                      for name, default in TEXT_DEFAULTS.items()})
    return backfill(df)


def family(integrator: str, formulation: str, problem: str, settings: str | None = None) -> str:
    """The family a stored record of this line without one is read with."""
    row = {"problem": problem, "params": "{}", "formulation": formulation,
           "integrator": integrator, "settings": settings, "rtol": 1e-3, "h": None}
    return backfill(pd.DataFrame([row]))["family"].iloc[0]
