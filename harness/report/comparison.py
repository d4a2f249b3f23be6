"""Formulation comparison tables, in the shape of the seeds' tables.

Sudarsan and Keerthi (1998), Tables 1-4, set the approaches (projection,
tangent parametrization, stabilized index 2, Baumgarte) side by side at
TOL = 1e-2, 1e-4, 1e-6 with the counters NF, NS, NJ, NI and CPU as rows; the
seed report's Table 5 sets IDA at index 3 against index 2 (steps, f-evals,
Jacobians, Newton failures, time). Here, for one problem and one integrator
that ran several formulations, rows are the counters and drift, columns are
(formulation, tolerance). The report's "Formulations compared" part
(:mod:`integrator_bench.harness.report.sections`) shows one such table per
integrator.
"""

from __future__ import annotations

import pandas as pd

from integrator_bench.harness.tables import NULL

ROWS = (("nfev", "NF (f-evals)"), ("nsteps", "NS (steps)"), ("njev", "NJ (Jacobians)"),
        ("nlu", "NLU (LU factorizations)"), ("nniter", "NI (Newton iterations)"),
        ("nnfail", "Newton failures"), ("cpu_s", "CPU (s)"), ("drift_pos", "drift |g(q, t)|"),
        ("drift_vel", "drift |G v + g_t|"), ("mescd", "mescd (digits)"))
#: the record fields of :data:`ROWS`
KEYS = tuple(key for key, _ in ROWS)


def comparison_table(rows: pd.DataFrame) -> pd.DataFrame:
    """Counters by (formulation, rtol) for one integrator's adaptive runs.

    Parameters
    ----------
    rows : DataFrame
        Records of one problem and parameter set and one integrator.
    """
    ok = rows.loc[(rows.status == "ok") & rows.rtol.notna(), ["formulation", "rtol", *KEYS]]
    ok = ok.sort_values(["formulation", "rtol"], ascending=[True, False])
    table = {(r.formulation, f"{r.rtol:g}"): [getattr(r, key) for key, _ in ROWS]
             for r in ok.itertuples()}
    return pd.DataFrame(table, index=[label for _, label in ROWS])


def counter_cell(value, key: str) -> str:
    """One cell of a comparison table, for the row of :data:`ROWS` named ``key``."""
    if pd.isna(value):  # None, NaN and pandas' NA alike
        return NULL
    if key.startswith("drift"):
        return f"{value:.1e}"
    if key in ("cpu_s", "mescd"):
        return f"{value:.3g}"
    return f"{int(value)}"


def compared_integrators(rows: pd.DataFrame):
    """``(label, comparison_table)`` for each integrator with its settings (its
    ``label``), by name, that ran two or more formulations of the problem (in
    its ok adaptive runs, the table's columns)."""
    ok = rows.loc[(rows.status == "ok") & rows.rtol.notna(),
                  ["label", "status", "formulation", "rtol", *KEYS]]
    forms = ok.groupby("label")["formulation"].nunique()
    compared = ok[ok["label"].isin(forms.index[forms >= 2])]
    for label, sub in sorted(compared.groupby("label"), key=lambda kv: kv[0]):
        yield label, comparison_table(sub)
