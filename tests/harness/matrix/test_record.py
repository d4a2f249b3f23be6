"""The typed record: one dataclass, converted at the store's boundary; the case's
identity, line, mode, label, kind and family set once from the Case, stored, and
what the report draws; a store written before these fields still loads."""

from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

import pandas as pd
import pytest

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.cases import Case, expand
from integrator_bench.harness.matrix.line import Line, backfill, family
from integrator_bench.harness.matrix.record import FIELDS, Record, mode_of
from integrator_bench.harness.matrix.store import Store, load
from integrator_bench.harness.ranking.records import clean_records
from integrator_bench.harness.report.write import write_report
from integrator_bench.harness.run.execution import base_record, execute

#: a store written by the code before the typed record (``ibench run`` of two_mass,
#: bouncing_ball and pendulum under scipy-RK45, cvode-bdf:max_order=2, rk4, ida, hht)
OLD_STORE = Path(__file__).parents[2] / "data" / "store_untyped_record.sqlite"
IDENTITY = ("mode", "line", "label", "kind", "family")


def test_fields_come_from_the_dataclass_with_their_sql_types():
    assert list(FIELDS) == [f.name for f in dataclasses.fields(Record)]
    assert FIELDS["nfev"] == "INTEGER" and FIELDS["cpu_s"] == "REAL"
    assert FIELDS["problem"] == "TEXT" and FIELDS["solver_counts"] == "TEXT"
    assert set(IDENTITY) <= set(FIELDS)


def test_a_field_that_does_not_exist_cannot_be_written():
    record = Record(problem="two_mass")
    record["nfev"] = 3
    record.update(nsteps=2)
    assert (record.nfev, record["nsteps"], record.get("problem")) == (3, 2, "two_mass")
    with pytest.raises(KeyError, match="nfevs"):
        record["nfevs"] = 3
    with pytest.raises(KeyError):
        record.update(cpu=1.0)
    assert record.get("nope", "default") == "default" and record.get("h") is None
    assert dict(record) == record.to_dict() and list(record.to_dict()) == list(FIELDS)


def test_mode_is_defined_once():
    assert mode_of(1e-6, None) == "rtol" and mode_of(None, 0.01) == "h"
    assert mode_of(float("nan"), 0.01) == "h"
    assert Case("p", (), "ode", "rk4", h=0.1).mode == "h"
    assert Case("p", (), "ode", "rk4", rtol=1e-3).mode == "rtol"


@pytest.mark.parametrize("name", sorted(registry.integrators()))
def test_the_family_follows_what_each_integrator_declares(name):
    icls = registry.integrators()[name]
    expected = ("dae" if not icls.accepts & {"ode", "fmu"}
                else "implicit" if icls.implicit else "explicit")
    assert family(icls, "ode") == expected
    assert family(icls, "mechanical") == family(icls, "dae") == "dae"
    assert family(None, "ode") == "unknown"


def test_the_expansion_stores_identity_on_every_record():
    cases = expand(problems=["pendulum"], formulations=["ode", "i3"],
                   integrators=["cvode-bdf:max_order=2", "hht"], rtols=[1e-4])
    by = {(c.formulation, c.integrator): c for c in cases}
    assert by[("ode", "cvode-bdf")].kind == "ode" and by[("i3", "hht")].kind == "dae"
    record = base_record(by[("ode", "cvode-bdf")])
    assert record.label == "cvode-bdf (max_order=2)" and record.family == "implicit"
    assert record.mode == "rtol" and json.loads(record.line) == [
        "pendulum", dict(by[("ode", "cvode-bdf")].params), "ode", "cvode-bdf",
        {"max_order": 2}, "rtol"]
    assert base_record(by[("i3", "hht")]).family == "dae"


def test_a_case_built_without_its_kind_gets_it_from_the_system_it_runs():
    case = Case("two_mass", tuple(sorted(registry.get_problem_class("two_mass")().params.items())),
                "ode", "scipy-RK45", rtol=1e-3)
    assert case.kind is None and base_record(case).kind is None
    record = execute(case, repeat=1)
    assert record.status == "ok" and record.kind == "ode" and record.family == "explicit"


def _stored_identity(path) -> list:
    import sqlite3

    db = sqlite3.connect(path)
    try:
        return db.execute(f"SELECT {', '.join(IDENTITY)} FROM records").fetchall()
    finally:
        db.close()


def test_a_store_written_before_the_typed_record_loads_upgrades_and_reports(tmp_path):
    store_path = tmp_path / "old.sqlite"
    shutil.copy(OLD_STORE, store_path)
    old = load(store_path)
    # read once, the old records' lines are filled in from today's registry, as a
    # new record would have them; the file is not written
    assert len(old) == 50 and old["kind"].isna().all()
    assert old[["mode", "line", "label", "family"]].notna().all().all()
    ok = old[old["status"] == "ok"]
    assert set(ok.loc[ok["integrator"] == "hht", "family"]) == {"dae"}
    assert set(ok.loc[ok["integrator"] == "scipy-RK45", "family"]) == {"explicit"}
    assert set(old["mode"]) == {"rtol", "h"}
    assert "cvode-bdf (max_order=2)" in set(old["label"])
    assert all(json.loads(text) == json.loads(Line.of_record(row).text)
               for text, (_, row) in zip(old["line"], old.iterrows()))
    assert store_path.read_bytes() == OLD_STORE.read_bytes()
    # a new run appends typed records beside the old ones
    case = Case("two_mass", tuple(sorted(registry.get_problem_class("two_mass")().params.items())),
                "ode", "rk4", h=0.01, kind="ode")
    with Store(store_path) as store:
        assert store.add(execute(case, repeat=1))
    both = load(store_path)
    assert len(both) == 51 and both.iloc[-1]["family"] == "explicit"
    filled = ["mode", "line", "label", "family"]
    assert both.iloc[:50][filled].values.tolist() == old[filled].values.tolist()
    assert all(value is None for row in _stored_identity(store_path)[:50] for value in row)


def test_an_old_store_reports_as_the_same_records_with_their_lines_stored(tmp_path):
    """An old store's records are read with the line fields a run writes today
    (Case.identity), and it reports."""
    old = load(OLD_STORE)

    def case(row) -> Case:   # the case a run makes today, its kind from the system it runs
        params = json.loads(row["params"])
        settings = json.loads(row["settings"]) if isinstance(row["settings"], str) else {}
        kind = registry.get_problem_class(row["problem"])(**params) \
            .formulate(row["formulation"]).kind
        return Case(row["problem"], tuple(sorted(params.items())), row["formulation"],
                    row["integrator"], rtol=None if pd.isna(row["rtol"]) else row["rtol"],
                    h=None if pd.isna(row["h"]) else row["h"],
                    settings=tuple(sorted(settings.items())), kind=kind)

    cases = {row["case_id"]: case(row) for _, row in old.iterrows()}
    assert all(c.case_id == cid for cid, c in cases.items())
    written = old.assign(**{name: [cases[c].identity()[name] for c in old["case_id"]]
                            for name in ("mode", "line", "label", "family")})
    filled = ["mode", "label", "family"]
    assert written[filled].values.tolist() == old[filled].values.tolist()
    assert written["line"].map(json.loads).tolist() == old["line"].map(json.loads).tolist()
    write_report(old[old["problem"] == "pendulum"], tmp_path, scaling_dir=tmp_path / "none", jobs=1)
    index = (tmp_path / "index.md").read_text(encoding="utf-8")
    assert "cvode-bdf (max_order=2) | ode" in index and "DAE and mechanical forms" in index


def test_the_report_draws_the_family_and_label_the_record_says():
    rows = pd.DataFrame([{**Record(problem="two_mass", params="{}", formulation="ode",
                                   integrator="scipy-RK45", rtol=1e-3, status="ok",
                                   family="implicit", label="scipy-RK45 (x=1)", mode="rtol",
                                   settings='{"x": 1}').to_dict()}])
    # today's registry says explicit; the record says implicit, and wins
    assert backfill(rows)["family"].tolist() == ["implicit"]
    # the ranking names the line by the record's label; the integrator stays the registry's
    assert clean_records(rows)[["label", "integrator"]].values.tolist() == \
        [["scipy-RK45 (x=1)", "scipy-RK45"]]
    # a record without them (made by hand, not read from a store) gets its line's
    assert backfill(rows.assign(family=None, label=None))[["family", "label"]].values.tolist() \
        == [["explicit", "scipy-RK45 (x=1)"]]
