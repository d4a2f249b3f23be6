"""The coverage check over a store: a point on each side of 1e-5 per problem x
formulation family x integrator family, and the run's totals line."""

import pandas as pd
import pytest

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.line import family
from integrator_bench.harness.cli.summary import totals
from integrator_bench.harness.ranking.coverage import (
    FORMULATION_FAMILIES, coverage, formulation_family, gaps, summary_line)
from records_frame import records_frame


def _rec(integrator, formulation, mescd, status="ok", rtol=1e-3, problem="p"):
    return {"problem": problem, "params": "{}", "formulation": formulation,
            "integrator": integrator, "rtol": rtol, "h": None, "status": status,
            "mescd": mescd, "err_max": None if mescd is None else 10.0 ** -mescd,
            "cpu_s": 0.1 if status == "ok" else None}


def test_verdicts_of_each_group():
    df = records_frame([
        _rec("scipy-RK45", "ode", 3), _rec("scipy-RK45", "ode", 6, rtol=1e-6),   # both sides
        _rec("scipy-Radau", "ode", 3),                                              # skipped: gap
        _rec("scipy-Radau", "ode", None, "skipped", 1e-6),
        _rec("scipy-RK45", "projection", 3),                                        # not reached
        _rec("scipy-RK45", "projection", None, "failed", 1e-6),
        _rec("cvode-bdf", "projection", 3), _rec("cvode-bdf", "projection", None, "timeout", 1e-6),
        _rec("ida", "i3", 7), _rec("ida", "i3", None, "unsupported")])             # only below
    table = coverage(df).set_index(["formulation_family", "integrator_family"])
    assert table.loc[("ode", "explicit"), "verdict"] == "both sides"
    assert table.loc[("ode", "implicit"), "verdict"] == "gap"
    assert table.loc[("projection", "explicit"), "verdict"] == "not reached"
    assert table.loc[("dae", "dae"), "verdict"] == "only below"
    assert table.loc[("projection", "implicit"), "verdict"] == "gap"    # cut by a timeout
    assert table.loc[("dae", "dae"), "below"] == 1 and len(table) == 5
    assert list(gaps(df)["formulation_family"]) == ["ode", "projection"]
    line = summary_line(df, width=200)
    assert "1 of 5" in line and "2 gaps: p/ode/implicit, p/projection/implicit" in line
    assert "families" in line and len(summary_line(df)) <= 100


@pytest.mark.parametrize("name", list(registry.integrators()))
def test_every_integrator_has_a_family(name):
    # the integrator's own, whatever the formulation (a DAE form leaves it as it is)
    table = coverage(records_frame([_rec(name, "i3", 6.0),
                                    dict(_rec(name, "ode", 6.0), settings='{"x": 1}')]))
    assert set(table["integrator_family"]) == \
        {family(registry.integrators()[name], None)} <= {"explicit", "implicit", "dae"}


@pytest.mark.parametrize("form", registry.formulations())
def test_every_formulation_has_a_family(form):
    assert formulation_family(form) in FORMULATION_FAMILIES


def test_totals_counts_and_skipped_share():
    df = records_frame([dict(_rec("a", "ode", 3), budget_edge=1),
                        dict(_rec("a", "ode", None, "skipped"), reason="after_timeout"),
                        _rec("a", "ode", None, "timeout"), _rec("a", "ode", None, "unsupported")])
    first, counts, edge = totals(df, wall_s=12.4, cpu_s=20.2)
    assert first == ("wall 12 s; CPU 20 s (solves 0 s); skipped 33 % of 3 runnable "
                     "(1 after_timeout)")
    assert counts == "cases: 1 ok, 1 timeout, 1 unsupported, 1 skipped"
    assert edge.startswith("budget's edge: 1 ok within 10 % of it, 1 timeouts")
    assert len(totals(df.assign(budget_edge=0, status="ok"))) == 2   # nothing at the edge
