"""Integrator settings: declarations, the spec parser and sweeps, the
case identity, the store column, the report's lines, and settings that change
what a method does."""

from __future__ import annotations

import hashlib
import json
import sqlite3
import sys
from pathlib import Path

import numpy as np
import pytest

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.cases import PRESETS, Case, expand, parse_integrator_spec
from integrator_bench.harness.cli import main
from integrator_bench.harness.errors import BadInput
from integrator_bench.harness.ranking.records import clean_records
from integrator_bench.harness.report.style import BUILTIN, styles
from records_frame import family
from integrator_bench.harness.matrix.store import Store, load
from integrator_bench.integrators.settings import SettingError
from integrator_bench.problems.system import convert

WITH_SETTINGS = [n for n, c in registry.integrators().items() if c.settings]
ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("name", WITH_SETTINGS)
def test_defaults_and_bad_values_of_every_declared_setting(name):
    cls = registry.get_integrator(name)
    values = cls().setting_values
    assert values == {s.name: s.default for s in cls.settings}
    for s in cls.settings:
        assert getattr(cls(), s.name) == s.default
        bad = "nope" if s.choices else (s.high + 1 if s.high is not None else -1)
        with pytest.raises(SettingError, match=rf"{s.name}=.*valid settings: .*{s.name}="):
            cls(**{s.name: bad})
    with pytest.raises(SettingError, match=r"has no setting 'bogus'; valid settings"):
        cls(bogus=1)


def test_every_builtin_with_a_seed_control_names_it():
    controls = {s.control for c in registry.integrators().values() for s in c.settings}
    assert {"KMAX", "HMAX", "HINIT", "HMIN", "MAXIT", "PATTERN"} <= controls


def test_sweep_and_defaults_in_the_spec():
    out = parse_integrator_spec("cvode-bdf:max_order=1|2|3|5")
    assert [settings for _, _, settings in out] == [(("max_order", 1),), (("max_order", 2),),
                                                    (("max_order", 3),), ()]
    two = parse_integrator_spec("cvode-bdf:max_order=2,max_step=1e-4")
    assert two[0][2] == (("max_order", 2), ("max_step", 1e-4))
    with pytest.raises(BadInput, match=r"max_order=9 is not int in \[1, 5\]"):
        parse_integrator_spec("cvode-bdf:max_order=9")
    with pytest.raises(BadInput, match="malformed setting"):
        parse_integrator_spec("cvode-bdf:max_order")


def test_default_case_keeps_its_old_id_and_settings_change_it():
    case = Case("two_mass", (("k", 1.0),), "ode", "cvode-bdf", rtol=1e-4)
    old = hashlib.sha256(json.dumps(["two_mass", {"k": 1.0}, "ode", "cvode-bdf", 1e-4, None],
                                    sort_keys=True).encode()).hexdigest()[:16]
    assert case.case_id == old and case.settings_json is None
    variant = Case("two_mass", (("k", 1.0),), "ode", "cvode-bdf", rtol=1e-4,
                   settings=(("max_order", 2),))
    assert variant.case_id != old and variant.line.label == "cvode-bdf (max_order=2)"


def test_presets_full_runs_the_seed_variants_quick_does_not():
    full = {(c.integrator, c.settings) for c in expand(problems=["two_mass:c2=1000"],
                                                       rtols=[1e-3], preset="full")}
    assert {("cvode-bdf", (("max_order", 2),)), ("ida", (("max_order", 2),)),
            ("hht", (("alpha", 0.0),)), ("hht", (("alpha", -1 / 3),))} <= full
    assert ("cvode-bdf", ()) in full and ("hht", ()) in full
    quick = expand(problems=["two_mass:c2=1000"], rtols=[1e-3], preset="quick")
    assert all(c.settings == () for c in quick) and not PRESETS["quick"].variants


def test_bad_setting_exits_2_naming_the_range_nothing_written(tmp_path, capsys):
    store = tmp_path / "s.sqlite"
    assert main(["run", "-i", "cvode-bdf:max_order=9", "--store", str(store)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "max_order=9" in err[0] and "[1, 5]" in err[0]
    assert not store.exists()


def test_run_stores_both_lines_and_the_report_names_them(tmp_path):
    store = tmp_path / "s.sqlite"
    args = ["run", "-p", "two_mass:c2=1000", "-i", "cvode-bdf", "-i", "cvode-bdf:max_order=2",
            "--rtol", "1e-4", "--store", str(store), "--jobs", "2"]
    assert main(args) == 0
    df = load(store)
    assert sorted(df["settings"].fillna("")) == ["", '{"max_order": 2}']
    default, two = (df[df["settings"].isna()].iloc[0], df[df["settings"].notna()].iloc[0])
    assert default["nfev"] != two["nfev"]
    assert main(["run", *args[1:], "--resume"]) == 0          # both already stored
    assert len(load(store)) == 2
    out = tmp_path / "report"
    assert main(["report", "--store", str(store), "--out", str(out)]) == 0
    page = (out / "index.md").read_text()
    assert "cvode-bdf (max_order=2)" in page and "| cvode-bdf |" in page


def test_old_store_gains_the_settings_column(tmp_path):
    path = tmp_path / "old.sqlite"
    Store(path).close()
    db = sqlite3.connect(path)
    db.execute("ALTER TABLE records DROP COLUMN settings")
    db.execute("INSERT INTO records (case_id, integrator) VALUES ('x', 'ida')")
    db.commit()
    db.close()
    df = load(path)
    assert "settings" in df.columns and df["settings"].isna().all()


def test_variants_take_the_base_colour_a_marker_of_their_own_and_family():
    names = ["cvode-bdf", "cvode-bdf (max_order=2)", "cvode-bdf (max_order=3)", "ida"]
    s = styles(names, {n: "cvode-bdf" for n in names[1:3]})
    assert s["cvode-bdf"] == BUILTIN["cvode-bdf"]
    markers = {s[n][1] for n in names[:3]}
    assert {s[n][0] for n in names[:3]} == {BUILTIN["cvode-bdf"][0]} and len(markers) == 3
    assert family("cvode-bdf", "ode", "two_mass", '{"max_order": 2}') == \
        family("cvode-bdf", "ode", "two_mass") == "implicit"
    rows = clean_records(__import__("pandas").DataFrame(
        [{"integrator": "ida", "settings": '{"max_order": 2}', "created": "2026-01-01"},
         {"integrator": "ida", "settings": None, "created": "2026-01-01"}]))
    assert sorted(rows["label"]) == ["ida", "ida (max_order=2)"]
    assert list(rows["integrator"]) == ["ida", "ida"]


def test_list_integrators_shows_the_settings(capsys):
    assert main(["list", "integrators", "--json"]) == 0
    items = {d["name"]: d for d in json.loads(capsys.readouterr().out)}
    kmax = next(s for s in items["cvode-bdf"]["settings"] if s["name"] == "max_order")
    assert kmax["control"] == "KMAX" and kmax["default"] == 5 and kmax["valid"] == "int in [1, 5]"
    assert main(["list", "integrators"]) == 0
    assert "jacobian_every" in capsys.readouterr().out


def _stiff():
    problem = registry.get_problem_class("two_mass")(c2=1000)
    return problem.formulate("ode")


@pytest.mark.parametrize("name", ["implicit-euler", "trapezoidal", "sdirk3", "bdf2"])
def test_newton_pattern_and_iteration_limit_change_what_is_done(name):
    cls = registry.get_integrator(name)
    system = convert(_stiff(), cls)
    h = (system.t_end - system.t0) / 200
    runs = {k: cls(**k_values).solve(system, h=h) for k, k_values in
            (("default", {}), ("every1", {"jacobian_every": 1}), ("every3", {"jacobian_every": 3}),
             ("maxit1", {"max_newton": 1}))}
    c = {k: sol.counts for k, sol in runs.items()}
    # PATTERN 1: a Jacobian (and an LU) at every iteration after the first of a solve
    assert c["every1"]["njev"] > c["every3"]["njev"] > c["default"]["njev"]
    assert c["every1"]["njev"] >= c["every1"]["nniter"] - c["every1"]["nsteps"] * 3
    # one iteration allowed: a solve that needs two fails and is retried with a new Jacobian
    assert c["maxit1"]["nnfail"] > c["default"]["nnfail"]
    for sol in runs.values():
        assert sol.success
    assert np.allclose(runs["every1"].y[-1], runs["default"].y[-1], rtol=1e-6, atol=1e-8)


def test_alpha_and_polynomial_settings_reach_the_method():
    pend = registry.get_problem_class("pendulum")()
    hht = registry.get_integrator("hht")
    system = convert(pend.formulate("i3"), hht)
    a = hht().solve(system, h=0.01).y[-1]
    b = hht(alpha=-1 / 3).solve(system, h=0.01).y[-1]
    assert not np.allclose(a, b, rtol=1e-10, atol=0)
    dumka = registry.get_integrator("dumka3")
    two = convert(_stiff(), dumka)
    h = (two.t_end - two.t0) / 400
    with np.errstate(all="ignore"):
        p3, p6 = (dumka(polynomial=k).solve(two, h=h) for k in ("P2", "P5"))
    # h rho is beyond P2's stability interval and within P5's: P2 blows up, P5 does not
    assert p6.success and not p3.success


def test_plugin_declares_its_own_settings():
    sys.path.insert(0, str(ROOT / "examples" / "ibench-heun"))
    try:
        import ibench_heun
    finally:
        sys.path.pop(0)
    cls = registry.register(ibench_heun.Heun, origin="ibench-heun (tests)")
    try:
        out = parse_integrator_spec("heun:c2=0.5|1")
        assert [s for _, _, s in out] == [(("c2", 0.5),), ()]
        with pytest.raises(BadInput, match=r"c2=0 is not float in \(0, 1\]"):
            parse_integrator_spec("heun:c2=0")
        system = _stiff()
        system = convert(registry.get_problem_class("two_mass")().formulate("ode"), cls)
        heun, mid = (cls(c2=c).solve(system, rtol=1e-6, atol=system.atol(1e-6)) for c in (1, 0.5))
        assert heun.success and mid.success
        assert heun.counts != mid.counts or not np.array_equal(heun.y, mid.y)
    finally:
        registry.unregister("heun")


def test_settings_check_quick(tmp_path, run_cases):
    from integrator_bench.harness.run.context import RunContext
    from integrator_bench.harness.run.limits import Limits

    sys.path.insert(0, str(ROOT / "studies"))
    try:
        import settings_check
    finally:
        sys.path.pop(0)
    rows = settings_check.compare(run_cases(
        settings_check.make_cases(settings_check.QUICK_PLAN),
        RunContext(jobs=2, progress=False,
                   limits=Limits(budget_s=settings_check.QUICK_TIMEOUT_S))))
    lines = {r["line"] for r in rows}
    assert lines == {"cvode-bdf", "cvode-bdf (max_order=2)"}
    two = next(r for r in rows if r["line"] == "cvode-bdf (max_order=2)")
    assert two["ratio_1e-03"] is not None


def test_max_order_2_does_a_fraction_of_the_default_work_on_the_bushing_chain():
    """The issue's finding on a shortened chain_bushing (30 links, 10 ms): the
    lightly damped bushing modes lie outside BDF3-5's stability sectors, so CVODE
    at its default maximum order 5 takes several times the steps of order 2 at
    the same tolerance."""
    cls = registry.get_integrator("cvode-bdf")
    system = convert(registry.get_problem_class("chain_bushing")(t_end=0.01).formulate("ode"),
                     cls)
    five, two = (cls(max_order=k).solve(system, rtol=1e-4, atol=system.atol(1e-4))
                 for k in (5, 2))
    assert five.success and two.success
    assert 3 * two.counts["nfev"] < five.counts["nfev"]
    assert 3 * two.counts["nsteps"] < five.counts["nsteps"]


def test_provenance_names_the_integrators_with_their_settings(tmp_path):
    from integrator_bench.harness.matrix.store import load_runs

    store = tmp_path / "p.sqlite"
    assert main(["run", "-p", "two_mass", "-i", "cvode-bdf:max_order=2", "--rtol", "1e-3",
                 "--store", str(store)]) == 0
    options = json.loads(load_runs(store)["options"].iloc[0])
    assert options["integrators"] == ["cvode-bdf (max_order=2)"]
