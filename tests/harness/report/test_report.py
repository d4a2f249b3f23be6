"""Tests of the report package (harness/report/) on small synthetic record tables."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from integrator_bench.harness.matrix import registry

from integrator_bench.harness.matrix.record import FIELDS, empty_record
from integrator_bench.harness.ranking.reach import (
    cpu_to_reach, pareto_front, reach_line, target_table)
from integrator_bench.harness.ranking.records import clean_records
from integrator_bench.harness.report import write_report
from integrator_bench.harness.report.figures import FAILED_LABEL, work_precision_figure
from integrator_bench.harness.report.names import TABLE_COLUMNS, slug
from integrator_bench.harness.report.style import BUILTIN, style
from records_frame import family, records_frame

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
SPRING = "spring_pendulum_k=100"
PENDULUM = "pendulum_L=1_g=9.81"
TWO_MASS = "two_mass_c=0.5"
NO_SCALING = Path("/nonexistent/scaling")   # keeps a real <data dir>/scaling out of the tests
OLD, NEW = "2024-01-01T00:00:00+00:00", "2024-06-01T12:00:00+00:00"


def ok_row(integrator, rtol, digits, **extra):
    """An ok record of spring_pendulum with plausible counts."""
    fields = dict(problem="spring_pendulum", params='{"k": 100.0}', formulation="ode",
                  integrator=integrator, rtol=rtol, atol=None if rtol is None else rtol * 1e-3,
                  status="ok",
                  scd=digits + 0.3, mescd=digits, err_max=10.0 ** -digits,
                  cpu_s=1e-3 * 10 ** (digits / 3), wall_s=2e-3 * 10 ** (digits / 3),
                  nfev=int(50 * 10 ** (digits / 4)), nsteps=int(10 * 10 ** (digits / 4)),
                  nreject=2, njev=None, nlu=None, nniter=None, nnfail=None,
                  drift_pos=1e-9, drift_vel=1e-8, code_version="abc", created=OLD)
    fields.update(extra)
    return empty_record(**fields)


def make_records() -> pd.DataFrame:
    rows = []
    for i, rtol in enumerate([1e-3, 1e-6, 1e-9]):
        rows.append(ok_row("scipy-RK45", rtol, 3.0 + 3 * i))
        rows.append(ok_row("scipy-Radau", rtol, 3.5 + 3 * i, njev=5 + i, nlu=20 + i,
                           nniter=40 + i, nnfail=i))
    rows.append(ok_row("scipy-BDF", 1e-12, 0, status="failed", mescd=None, scd=None,
                       err_max=None, cpu_s=0.5, nfev=4000,
                       message="Required step size is less than spacing between numbers."))
    rows.append(ok_row("scipy-LSODA", 1e-12, 0, status="timeout", mescd=None, scd=None,
                       cpu_s=None, nfev=None, nsteps=None, nreject=None,
                       message="timed out after 10 s"))
    rows.append(ok_row("ida", 1e-6, 0, status="unsupported", mescd=None, scd=None,
                       cpu_s=None, nfev=None, nsteps=None, nreject=None,
                       message="ida needs the dae formulation"))
    # A fixed-step group: rtol null, h set.
    for i, h in enumerate([0.1, 0.01]):
        rows.append(ok_row("rk4", None, 2.0 + 4 * i, problem="pendulum",
                           params='{"g": 9.81, "L": 1.0}', h=h))
    # A group where nothing succeeded.
    rows.append(ok_row("scipy-RK45", 1e-6, 0, problem="two_mass", params='{"c": 0.5}',
                       status="crashed", mescd=None, scd=None, message="segfault"))
    return records_frame(rows)


@pytest.fixture
def report(tmp_path):
    paths = write_report(make_records(), tmp_path, scaling_dir=NO_SCALING)
    return tmp_path, paths


def test_slug_of_many_parameters_stays_short_and_distinct():
    params = {f"parameter_{i}": i * 1.5 for i in range(25)}
    a = slug("chain_drive", json.dumps(params))
    b = slug("chain_drive", json.dumps({**params, "parameter_24": 0.5}))
    assert len(a) <= 120 and a.startswith("chain_drive_parameter_0=0_") and a != b


def test_slug():
    assert slug("spring_pendulum", '{"k": 100.0}') == "spring_pendulum_k=100"
    assert slug("pendulum", '{"g": 9.81, "L": 1.0}') == PENDULUM
    assert slug("p", '{"a": 1e-05, "name": "x/y z"}') == "p_a=1e-05_name=x_y_z"
    assert slug("p", "{}") == "p"


def test_files_exist_and_pngs_are_valid(report):
    out, paths = report
    expected = [out / f"{name}.{ext}" for name in (PENDULUM, SPRING, TWO_MASS)
                for ext in ("png", "csv", "md")] + [out / "profiles.png",
                                                    out / "profiles_work.png",
                                                    out / "plotly.min.js",
                                                    out / "index.md", out / "index.html"]
    assert paths == expected
    assert sorted(out.iterdir()) == sorted(expected)
    for png in out.glob("*.png"):
        data = png.read_bytes()
        assert data.startswith(PNG_MAGIC)
        assert len(data) > 5000


def test_csv_round_trips(report):
    out, _ = report
    table = pd.read_csv(out / f"{SPRING}.csv")
    assert list(table.columns) == TABLE_COLUMNS
    assert len(table) == 9
    assert list(table["integrator"]) == (["ida"] + ["scipy-BDF"] + ["scipy-LSODA"]
                                         + ["scipy-RK45"] * 3 + ["scipy-Radau"] * 3)
    rk45 = table[table["integrator"] == "scipy-RK45"]
    assert list(rk45["rtol"]) == [1e-3, 1e-6, 1e-9]
    assert rk45["njev"].isna().all()          # null counts are empty cells
    assert rk45["nfev"].notna().all()
    radau = table[table["integrator"] == "scipy-Radau"]
    assert list(radau["nlu"]) == [20, 21, 22]
    assert radau["cpu_s"].tolist() == pytest.approx([0.0147, 0.147, 1.47], rel=1e-2)
    assert radau["scd"].tolist() == pytest.approx([3.8, 6.8, 9.8], abs=0.01)
    assert table.loc[table["integrator"] == "scipy-LSODA", "status"].item() == "timeout"
    text = (out / f"{SPRING}.csv").read_text()
    assert "nan" not in text.lower() and "<NA>" not in text
    assert ",20," in text                      # counts written as integers, not 20.0

    fixed = pd.read_csv(out / f"{PENDULUM}.csv")
    assert fixed["rtol"].isna().all()
    assert list(fixed["h"]) == [0.1, 0.01]


def test_markdown_table(report):
    out, _ = report
    text = (out / f"{SPRING}.md").read_text(encoding="utf-8")
    lines = text.splitlines()
    header = next(i for i, line in enumerate(lines) if line.startswith("| integrator"))
    assert lines[header] == "| " + " | ".join(TABLE_COLUMNS) + " |"
    assert set(lines[header + 1].replace("|", "").replace("-", "").replace(":", "")) == set()
    end = next(i for i in range(header, len(lines)) if not lines[i].startswith("|"))
    rows = lines[header + 2:end]
    assert len(rows) == 8                     # the unsupported case is left out
    assert "ida" not in text and "1 unsupported cases left out" in text
    cells = [c.strip() for c in rows[2].strip("|").split("|")]   # RK45 at rtol 1e-3
    row = dict(zip(TABLE_COLUMNS, cells))
    assert row["integrator"] == "scipy-RK45"
    assert row["rtol"] == "0.001"
    assert row["h"] == row["njev"] == row["nlu"] == "–"
    assert row["mescd"] == "3.00" and row["scd"] == "3.30"
    assert row["cpu_s"] == "0.01"
    assert "nan" not in text.lower() and "<NA>" not in text and "None" not in text
    assert "timed out after 10 s" in text     # why a case is not ok


def test_duplicates_keep_newest(tmp_path):
    records = make_records()
    newer = ok_row("scipy-RK45", 1e-6, 6.0, cpu_s=123.0, created=NEW, code_version="def")
    older = ok_row("scipy-RK45", 1e-6, 6.0, cpu_s=456.0, created="2023-01-01T00:00:00Z")
    fixed_new = ok_row("rk4", None, 2.0, problem="pendulum",
                       params='{"g": 9.81, "L": 1.0}', h=0.1, nfev=777,
                       created=NEW)
    # The newest is not last in the frame: order alone must not decide.
    records = pd.concat([pd.DataFrame([fixed_new, newer]), records,
                         pd.DataFrame([older])], ignore_index=True)
    write_report(records, tmp_path, scaling_dir=NO_SCALING)
    table = pd.read_csv(tmp_path / f"{SPRING}.csv")
    assert len(table) == 9
    assert table.loc[(table["integrator"] == "scipy-RK45") & (table["rtol"] == 1e-6),
                     "cpu_s"].tolist() == [123.0]
    fixed = pd.read_csv(tmp_path / f"{PENDULUM}.csv")
    assert len(fixed) == 2
    assert fixed.loc[fixed["h"] == 0.1, "nfev"].tolist() == [777]
    index = (tmp_path / "index.md").read_text(encoding="utf-8")
    assert "3 superseded repeats dropped" in index


def test_index(report):
    out, _ = report
    index = (out / "index.md").read_text(encoding="utf-8")
    for name in (SPRING, PENDULUM, TWO_MASS):
        for ext in ("png", "csv", "md"):
            assert f"]({name}.{ext})" in index
    for status, count in [("ok", 8), ("failed", 1), ("timeout", 1), ("crashed", 1),
                          ("error", 0), ("unsupported", 1)]:
        assert f"| {status} | {count} |" in index


def test_empty_dataframe(tmp_path):
    paths = write_report(pd.DataFrame(columns=list(FIELDS)), tmp_path / "out",
                         scaling_dir=NO_SCALING)
    assert paths == [tmp_path / "out" / "index.md", tmp_path / "out" / "index.html"]
    assert sorted((tmp_path / "out").iterdir()) == sorted(paths)
    assert "no records" in paths[0].read_text(encoding="utf-8").lower()


def test_markdown_keeps_unsupported_when_asked(tmp_path):
    write_report(make_records(), tmp_path, include_unsupported=True, scaling_dir=NO_SCALING)
    text = (tmp_path / f"{SPRING}.md").read_text(encoding="utf-8")
    assert "| ida | ode |" in text and "ida needs the dae formulation" in text


def _failed_line(ax):
    lines = [line for line in ax.get_lines() if line.get_marker() == "x"]
    assert len(lines) == 1
    return lines[0]


def test_figure_marks_failures_apart_and_skips_unsupported():
    import matplotlib.pyplot as plt

    records = clean_records(make_records())
    rows = records[records["problem"] == "spring_pendulum"]
    fig = work_precision_figure(rows, "spring_pendulum (k=100)")
    try:
        titles = [ax.get_title() for ax in fig.axes if ax.get_visible()]
        assert titles == ["Explicit", "Implicit and stiff"]     # from `implicit`, not names
        explicit, implicit = [ax for ax in fig.axes if ax.get_visible()]
        labelled = {line.get_label(): line for line in explicit.get_lines()
                    if not line.get_label().startswith("_")}
        rk45 = labelled["scipy-RK45 (ode)"]
        assert rk45.get_color() == style("scipy-RK45")[0]
        assert rk45.get_marker() == style("scipy-RK45")[1]
        # the table's error (the largest over the output times, err_max), not 10^-scd
        assert np.allclose(rk45.get_xdata(), [1e-3, 1e-6, 1e-9])
        # BDF failed, LSODA timed out: crosses right of every error, in their panels
        crosses = {ax.get_title(): _failed_line(ax) for ax in (explicit, implicit)
                   if [line for line in ax.get_lines() if line.get_marker() == "x"]}
        assert sum(len(c.get_xdata()) for c in crosses.values()) == 2
        bdf = crosses["Implicit and stiff"]
        assert 0.5 in bdf.get_ydata()             # at its measured CPU
        for ax in (explicit, implicit):
            if ax.get_title() in crosses:
                x, y = crosses[ax.get_title()].get_xdata(), crosses[ax.get_title()].get_ydata()
                assert (x > 1e-3).all() and x.max() < ax.get_xlim()[1]
                assert max(y) < ax.get_ylim()[1]
        legend = [t.get_text() for t in implicit.get_legend().get_texts()]
        assert any(t.startswith("2 not ok (1 failed, 1 timeout)") and t.endswith(", at its CPU")
                   for t in legend) and "Pareto front" in legend, legend
        assert FAILED_LABEL == "not ok, at its CPU"
        assert "ida" not in " ".join(legend)     # unsupported left out
    finally:
        plt.close(fig)


def test_figure_limits_lines_per_panel():
    import matplotlib.pyplot as plt

    rows = [ok_row(f"plugin-{k}", rtol, 3.0 + 3 * i, cpu_s=(k + 1) * 10.0 ** (i - 3))
            for k in range(14) for i, rtol in enumerate([1e-3, 1e-6])]
    fig = work_precision_figure(clean_records(pd.DataFrame(rows)), "t")
    try:
        (ax,) = [ax for ax in fig.axes if ax.get_visible()]
        assert ax.get_title() == "Integrators no longer registered"
        drawn = [line.get_label() for line in ax.get_lines()
                 if not line.get_label().startswith("_")]
        assert drawn == [f"plugin-{k} (ode)" for k in range(10)]   # the 10 cheapest
        legend = [t.get_text() for t in ax.get_legend().get_texts()]
        assert "+4 more lines: see the table" in legend
    finally:
        plt.close(fig)


def test_figure_chooses_lines_by_the_tables_mixed_error_and_draws_it():
    import matplotlib.pyplot as plt

    # plugin-0..9 never reach 1e-5; plugin-10, the dearest at every point, reaches it in
    # the mixed error (mescd 6) while its relative error (scd 2) stays poor
    rows = [ok_row(f"plugin-{k}", rtol, 3.0 + i, cpu_s=(k + 1) * 10.0 ** (i - 3))
            for k in range(10) for i, rtol in enumerate([1e-3, 1e-6])]
    rows += [ok_row("plugin-10", rtol, 3.0 + 3 * i, scd=1.0 + i, cpu_s=20 * 10.0 ** (i - 3))
             for i, rtol in enumerate([1e-3, 1e-6])]
    rows = [dict(r, err_max=10.0 ** -r["mescd"]) for r in rows]
    fig = work_precision_figure(clean_records(pd.DataFrame(rows)), "t")
    try:
        (ax,) = [ax for ax in fig.axes if ax.get_visible()]
        drawn = {line.get_label(): line for line in ax.get_lines()
                 if not line.get_label().startswith("_")}
        assert list(drawn) == ["plugin-10 (ode)"] + [f"plugin-{k} (ode)" for k in range(9)]
        # the same error as the table's, not the relative 10^-scd
        assert np.allclose(drawn["plugin-10 (ode)"].get_xdata(), [1e-3, 1e-6])
    finally:
        plt.close(fig)


def test_style_is_fixed_by_name():
    pairs = {style(name) for name in BUILTIN}
    assert len(pairs) == len(BUILTIN)            # every built-in distinct
    assert style("my-plugin") == style("my-plugin")
    assert style("scipy-RK45") == ("#1f77b4", "o")
    assert style("another-plugin") != style("my-plugin")


def test_family_from_declared_attributes():
    assert family("scipy-RK45", "ode", "squeezer") == "explicit"
    assert family("scipy-Radau", "baumgarte", "squeezer") == "implicit"
    assert family("scipy-Radau", "i3", "squeezer") == "dae"      # a DAE form
    assert family("ida", "ode", "two_mass") == "dae"             # accepts no ODE
    assert family("gone-integrator", "ode", "two_mass") == "unknown"
    # LSODA switches to BDF as LSODAR does: both implicit; fmpy's solvers by their method
    assert family("scipy-LSODA", "ode", "two_mass") == "implicit"
    if "assimulo-lsodar" in registry.integrators():
        assert family("assimulo-lsodar", "ode", "two_mass") == "implicit"
    assert family("fmpy-cvode", "ode", "fmu") == "implicit"
    assert family("fmpy-euler", "ode", "fmu") == "explicit"
    assert family("gone-integrator", "i2", "squeezer") == "dae"


def test_pareto_front():
    idx = pareto_front([1e-2, 1e-4, 1e-3, 1e-6], [1.0, 2.0, 3.0, 10.0])
    assert list(idx) == [3, 1, 0]


# --- CPU to reach a target error (harness.ranking.reach) -----------------------------------

def line_rows(errs, cpus, integrator="hht", formulation="i3", counts=None, **extra):
    """A synthetic work-precision line: one ok record per (error, CPU), rtol 1e-1, 1e-2, ...;
    the error is both the mixed (mescd) and the relative (scd) one."""
    rows = []
    for i, (e, c) in enumerate(zip(errs, cpus)):
        fields = dict(problem="chain_drive", params='{"n_links": 30}', formulation=formulation,
                      integrator=integrator, rtol=10.0 ** -(i + 1), status="ok",
                      scd=-math.log10(e), mescd=-math.log10(e), err_max=e, cpu_s=c,
                      nsteps=None,
                      nfev=None, njev=None, nlu=None, created=OLD)
        for name, values in (counts or {}).items():
            fields[name] = values[i]
        fields.update(extra)
        rows.append(empty_record(**fields))
    return records_frame(rows)


def test_reach_line_interpolates_in_log_log_and_never_extrapolates():
    err, cpu = [1e-2, 1e-4, 1e-8], [1.0, 10.0, 100.0]
    assert reach_line(err, cpu, 1e-3)["cpu_s"] == pytest.approx(10 ** 0.5)
    assert reach_line(err, cpu, 1e-6)["cpu_s"] == pytest.approx(10 ** 1.5)
    assert reach_line(err, cpu, 1e-6)["w"] == pytest.approx(0.5)
    exact = reach_line(err, cpu, 1e-4)
    assert exact["cpu_s"] == 10.0 and exact["how"] == "at a point"
    never = reach_line(err, cpu, 1e-9)                          # beyond the tightest point
    assert np.isnan(never["cpu_s"]) and never["how"] == "not reached"
    bound = reach_line([1e-7, 1e-9], [2.0, 5.0], 1e-6)          # starts below the target
    assert bound["cpu_s"] == 2.0 and bound["how"] == "at most"
    assert reach_line([], [], 1e-3)["how"] == "not reached"


def test_target_table_uses_mescd_and_ignores_failures():
    records = clean_records(make_records())
    table = target_table(records[records["problem"] == "spring_pendulum"])
    assert set(table["label"][:2]) == {"scipy-RK45", "scipy-Radau"}   # the ok lines
    rk45 = table[table["label"] == "scipy-RK45"].iloc[0]
    # mescd 3, 6 (scd 3.3, 6.3): 1e-5 is 5 mixed digits, not 5 relative ones (4.7 mixed)
    assert rk45["cpu_1e-05"] == pytest.approx(1e-3 * 10 ** (5 / 3))
    assert rk45["how_1e-03"] == "at most" and rk45["cpu_1e-03"] == pytest.approx(1e-2)
    assert rk45["best_err"] == pytest.approx(1e-9)               # 10^-mescd, not 10^-9.3
    failed = table[table["label"].isin(["scipy-BDF", "scipy-LSODA"])]
    assert set(table["label"][2:]) == {"scipy-BDF", "scipy-LSODA"}   # unreached last
    assert (failed["how_1e-03"] == "not reached").all() and (failed["n_failed"] == 1).all()
    assert failed["best_err"].isna().all()
    assert "ida" not in set(table["label"])                  # unsupported is no line


def test_target_ignores_scd_of_a_near_zero_component():
    # a run whose relative error (scd) is 1e-2 but whose mixed error (mescd) is 1e-6:
    # the table follows mescd
    rows = line_rows([1e-2, 1e-6], [1.0, 10.0])
    rows["scd"] = [2.0, 2.0]
    got = cpu_to_reach(rows, 1e-4, "final").iloc[0]
    assert got["how"] == "interpolated" and got["cpu_s"] == pytest.approx(10 ** 0.5)
    no_mescd = rows.assign(mescd=None)                            # no mixed error: no point
    assert cpu_to_reach(no_mescd, 1e-1, "final").iloc[0]["how"] == "not reached"
    # another measure in digits (Orlov's pin-force error E as -log10 E): the same line
    # reaches E = 1e-3 where its E crosses it, whatever mescd says
    orlov = rows.assign(e_digits=[1.0, 5.0])
    got = cpu_to_reach(orlov, 1e-3, measure="e_digits").iloc[0]
    assert got["how"] == "interpolated" and got["cpu_s"] == pytest.approx(10 ** 0.5)
    assert target_table(orlov, (1e-2,), measure="e_digits").iloc[0]["cpu_1e-02"] == \
        pytest.approx(10 ** 0.25)


def test_target_exact_at_known_points_and_log_log_between():
    from integrator_bench.harness.ranking.reach import cpu_to_reach as reach_rows

    rows = line_rows([1e-2, 1e-4, 1e-6], [1.0, 10.0, 100.0],
                     counts={"nsteps": [10, 40, 160], "nfev": [100, 1000, 10000],
                             "njev": [0, 4, 8], "nlu": [None, 5, 6]})
    at = reach_rows(rows, 1e-4).iloc[0]
    assert at["cpu_s"] == pytest.approx(10.0) and at["how"] == "at a point"
    assert (at["nsteps"], at["nfev"], at["njev"]) == (40, 1000, 4)
    mid = reach_rows(rows, 1e-3).iloc[0]                      # halfway in log error
    assert mid["how"] == "interpolated"
    assert mid["cpu_s"] == pytest.approx(10 ** 0.5)
    assert mid["nsteps"] == 20 and mid["nfev"] == 316         # geometric means
    assert mid["njev"] == 2                                   # a zero end: linear
    assert pd.isna(mid["nlu"])                                # an end cannot report it
    quarter = reach_rows(rows, 10 ** -4.5).iloc[0]
    assert quarter["cpu_s"] == pytest.approx(10 ** 1.25)


def test_target_is_never_extrapolated():
    from integrator_bench.harness.ranking.reach import cpu_to_reach as reach_rows

    rows = line_rows([1e-2, 1e-4], [1.0, 10.0], counts={"nsteps": [7, 9]})
    below = reach_rows(rows, 1e-6).iloc[0]
    assert below["how"] == "not reached" and np.isnan(below["cpu_s"])
    assert pd.isna(below["nsteps"])
    above = reach_rows(rows, 1e-1).iloc[0]                    # the line starts below it
    assert above["how"] == "at most" and above["cpu_s"] == 1.0 and above["nsteps"] == 7


def test_target_walks_the_lines_own_pareto_front():
    from integrator_bench.harness.ranking.reach import cpu_to_reach as reach_rows

    # error falls below 1e-3 between rtol 1e-1 and 1e-2, rises again, falls again: the
    # point that rose is beaten by the one before it and left out
    rows = line_rows([1e-2, 1e-4, 1e-2, 1e-6], [1.0, 10.0, 20.0, 40.0])
    assert reach_rows(rows, 1e-3).iloc[0]["cpu_s"] == pytest.approx(10 ** 0.5)
    # a looser tolerance that cost more than a tighter one is beaten by it: the tighter
    # run reached 1e-4 for 1 s, so 1e-3 costs at most that, never the 2.2 s between
    # the loose point and it, which was more than 1e-5 then cost
    shuffled = line_rows([1e-2, 1e-4, 1e-6], [5.0, 1.0, 50.0])
    loose, tight = (reach_rows(shuffled, t).iloc[0] for t in (1e-3, 1e-5))
    assert loose["how"] == "at most" and loose["cpu_s"] == 1.0
    assert tight["cpu_s"] == pytest.approx(50 ** 0.5) and tight["cpu_s"] >= loose["cpu_s"]


def test_target_lines_ignore_failures_and_sort_by_tight_target():
    from integrator_bench.harness.ranking.reach import target_table

    fast = line_rows([1e-2, 1e-6], [1.0, 2.0], integrator="hht")
    slow = line_rows([1e-2, 1e-6], [3.0, 30.0], integrator="ida", formulation="ggl")
    loose = line_rows([1e-2, 1e-4], [0.1, 0.2], integrator="newmark")
    broken = line_rows([1e-2, 1e-2], [0.5, 0.5], integrator="newmark",
                       status="failed", message="Newton failure")
    table = target_table(pd.concat([slow, loose, fast, broken], ignore_index=True))
    assert list(table["label"]) == ["hht", "ida", "newmark"]
    newmark = table.iloc[2]
    assert newmark["how_1e-05"] == "not reached" and newmark["n_failed"] == 2
    assert newmark["cpu_1e-03"] == pytest.approx(0.1 * 2 ** 0.5)   # only ok points count
    assert table.iloc[0]["cpu_1e-05"] == pytest.approx(2 ** 0.75)


def test_report_contains_the_target_table(tmp_path):
    records = pd.concat([line_rows([1e-2, 1e-6], [1.0, 2.0], integrator="hht"),
                         line_rows([1e-2, 1e-6], [3.0, 30.0], integrator="ida",
                                   formulation="ggl")], ignore_index=True)
    write_report(records, tmp_path, scaling_dir=NO_SCALING)
    group = (tmp_path / "chain_drive_n_links=30.md").read_text(encoding="utf-8")
    index = (tmp_path / "index.md").read_text(encoding="utf-8")
    page = (tmp_path / "index.html").read_text(encoding="utf-8")
    for text in (group, index):
        assert "CPU to reach a target error" in text and "largest mixed error over the " \
            "output times" in text
        head = next(line for line in text.splitlines() if "CPU [s] to 1e-05" in line)
        assert head.split("|")[1:-1][:3] == [" integrator ", " formulation ", " CPU [s] to 1e-03 "]
        rows = [line.split("|")[3:11] for line in text.splitlines()
                if line.startswith("| hht | i3 |")]
        assert [c.strip() for c in rows[-1]] == [f"{2 ** 0.25:.3g}", "rtol 0.056", "–", "–",
                                                 "–", "–", f"{2 ** 0.75:.3g}", "rtol 0.018"]
        lines = text.splitlines()
        assert lines.index(next(x for x in lines if x.startswith("| hht | i3 | 1.19"))) < \
            lines.index(next(x for x in lines if x.startswith("| ida | ggl | 5.33")))
    assert "CPU [s] to 1e-05" in page
    assert "cheapest to reach an error of 1e-05 (the largest mixed error over the " in page
    assert ": <b>hht (i3)</b>, 1.68 s CPU at rtol 0.018" in page


# --- Scaling section -----------------------------------------------------------------

def scaling_json(path: Path) -> None:
    import json

    rows = [{"n_links": n, "n_states": 6 * n + 4, "rhs_s": 1e-6 * n, "jac_s": 2e-6 * n,
             "ggl_res_s": 1.5e-6 * n, "ggl_jac_s": 3e-6 * n, "i3_res_s": 1.2e-6 * n,
             "i3_jac_s": 2.5e-6 * n, "step_ida_s": 1e-5 * n ** 1.2, "step_hht_s": 8e-6 * n ** 1.4,
             "nsteps_ida": 200, "nsteps_hht": 150, "peak_mb": 0.1 * n}
            for n in (10, 30, 100)]
    slopes = {k: 1.0 for k in rows[0] if k.endswith("_s")}
    slopes.update(step_ida_s=1.2, step_hht_s=1.4, peak_mb=1.0)
    path.mkdir(parents=True, exist_ok=True)
    (path / "chain_drive.json").write_text(json.dumps(
        {"problem": "chain_drive", "created": "2025-01-01T00:00:00Z", "machine": "test box",
         "rows": rows, "slopes": slopes,
         "targets": {"rhs_and_jac_slope_max": 1.1, "step_slope_max": 1.3}}))


def test_scaling_section_when_measurements_exist(tmp_path):
    scaling_json(tmp_path / "scaling")
    paths = write_report(make_records(), tmp_path / "out", scaling_dir=tmp_path / "scaling")
    png = tmp_path / "out" / "scaling_chain_drive.png"
    assert png in paths and png.read_bytes()[:8] == PNG_MAGIC
    index = (tmp_path / "out" / "index.md").read_text(encoding="utf-8")
    assert "## Scaling" in index and "](scaling_chain_drive.png)" in index
    assert "| step_hht_s | 1.40 | 1.3 | no |" in index       # over its bound
    assert "| step_ida_s | 1.20 | 1.3 | yes |" in index
    assert "| rhs_s | 1.00 | 1.1 | yes |" in index
    assert "| peak_mb | 1.00 | – | – |" in index
    page = (tmp_path / "out" / "index.html").read_text(encoding="utf-8")
    assert '<h2 id="scaling">Scaling</h2>' in page and 'src="scaling_chain_drive.png"' in page
    assert "test box" in page


def test_no_scaling_section_without_measurements(tmp_path):
    (tmp_path / "scaling").mkdir()
    write_report(make_records(), tmp_path / "out", scaling_dir=tmp_path / "scaling")
    assert "Scaling" not in (tmp_path / "out" / "index.md").read_text(encoding="utf-8")
    assert "Scaling" not in (tmp_path / "out" / "index.html").read_text(encoding="utf-8")
    assert not list((tmp_path / "out").glob("scaling_*"))


@pytest.mark.parametrize("text", ["{not json", '["a list"]', '{"problem": "x"}'])
def test_a_bad_scaling_file_is_left_out_with_a_warning(tmp_path, text):
    scaling_json(tmp_path / "scaling")
    (tmp_path / "scaling" / "broken.json").write_text(text)
    with pytest.warns(UserWarning, match=r"broken\.json: left out of the report"):
        write_report(make_records(), tmp_path / "out", scaling_dir=tmp_path / "scaling")
    index = (tmp_path / "out" / "index.md").read_text(encoding="utf-8")
    assert "](scaling_chain_drive.png)" in index and "broken" not in index


# --- Events table ----------------------------------------------------------------------

def test_event_table_for_problems_with_events(tmp_path):
    ball = dict(problem="bouncing_ball", params='{"e": 0.8}', formulation="ode",
                status="ok", scd=8.0, mescd=8.0, cpu_s=0.01, created=OLD,
                events_by_kind='{"impact": 8}')
    rows = [empty_record(**ball, integrator="cvode-bdf", rtol=1e-6, nevents=8,
                         events_matched=8, events_missed=0, events_spurious=0, event_time_err=2.01e-5,
                         event_state_err=3.5e-14),
            empty_record(**{**ball, "events_by_kind": '{"impact": 7}'}, integrator="scipy-BDF",
                         rtol=1e-3, nevents=7, events_matched=7, events_missed=1,
                         events_spurious=0,
                         event_time_err=0.31, event_state_err=0.02),
            empty_record(**{**ball, "status": "unsupported", "events_by_kind": None,
                            "scd": None, "mescd": None},
                         integrator="rk4", h=0.034, message="ode: rk4 cannot locate state events"),
            ok_row("scipy-RK45", 1e-6, 6)]                       # a problem without events
    write_report(pd.DataFrame(rows, columns=list(FIELDS)), tmp_path, scaling_dir=NO_SCALING)
    group = (tmp_path / "bouncing_ball_e=0.8.md").read_text(encoding="utf-8")
    index = (tmp_path / "index.md").read_text(encoding="utf-8")
    for text in (group, index):
        assert "## Events" in text
        lines = text.splitlines()
        head = next(x for x in lines if x.startswith("| integrator | formulation | tolerance"))
        assert [c.strip() for c in head.split("|")[1:-1]] == [
            "integrator", "formulation", "tolerance", "nevents", "matched", "missed",
            "spurious", "event-time error", "state error after last event"]
        cvode = next(x for x in lines if x.startswith("| cvode-bdf | ode | rtol=1e-06"))
        assert [c.strip() for c in cvode.split("|")[4:-1]] == ["8", "8", "0", "0", "2.01e-05",
                                                               "3.50e-14"]
        bdf = next(x for x in lines if x.startswith("| scipy-BDF | ode | rtol=0.001"))
        assert [c.strip() for c in bdf.split("|")[4:-1]] == ["7", "7", "1", "0", "3.10e-01",
                                                             "2.00e-02"]
        assert not any(x.startswith("| rk4 | ode | h=") for x in lines)
    # the index lists the ball's events only; the problem without events has no table
    assert index.count("### ") - index.split("## Events")[0].count("### ") == 1
    spring = next(p for p in tmp_path.glob("spring_pendulum*.md")).read_text(encoding="utf-8")
    assert "## Events" not in spring
    page = (tmp_path / "index.html").read_text(encoding="utf-8")
    assert page.count("<h3>Events</h3>") == 1                   # the ball's section only
    ball_section = page.split('<h3>Events</h3>')[1].split("</table>")[0]
    assert "cvode-bdf" in ball_section and "3.10e-01" in ball_section


# --- the scaling schema, the runs part, one place per part ----------------------------

def test_scaling_schema_round_trips_and_bounds_each_figure(tmp_path):
    from integrator_bench.harness.report.scaling import (
        Scaling, load_scaling, read_scaling, slope_bound, write_scaling)

    data = Scaling(problem="chain_drive", created=NEW, machine="box",
                   rows=[{"n_links": 10, "rhs_s": 1e-6, "step_ida_s": None, "peak_mb": 1.0}],
                   slopes={"rhs_s": 1.0}, targets={"rhs_and_jac_slope_max": 1.1,
                                                   "step_slope_max": 1.3})
    path = write_scaling(data, tmp_path / "scaling")
    assert path == tmp_path / "scaling" / "chain_drive.json"
    assert read_scaling(path) == Scaling(**{**data.__dict__, "file": "chain_drive"})
    assert load_scaling(tmp_path / "scaling") == [read_scaling(path)]
    assert [slope_bound(k, data.targets) for k in ("rhs_s", "ggl_jac_s", "step_hht_s",
                                                   "peak_mb")] == [1.1, 1.1, 1.3, None]
    assert slope_bound("rhs_s", {}) is None


def test_runs_part_in_index_and_page(tmp_path):
    runs = pd.DataFrame([{"run_id": "20250101-abc", "started": OLD, "finished": NEW,
                          "status": "finished", "code_version": "abc", "host": "box",
                          "cpu_model": "CPU", "cpu_count": 2, "python": "3.11",
                          "versions": json.dumps({"numpy": "2.4", "plugins": {"p": "1.0"}}),
                          "threads": json.dumps({"env": {}, "blas_threads_per_worker": 1}),
                          "backend": json.dumps({"kind": "local", "jobs": 2}),
                          "loadavg": json.dumps([0.5, 0.4, 0.3]),
                          "command": "ibench run -p a|b", "purpose": "run"}])
    write_report(make_records(), tmp_path, runs=runs, scaling_dir=NO_SCALING)
    index = (tmp_path / "index.md").read_text(encoding="utf-8")
    row = next(x for x in index.splitlines() if x.startswith("| 20250101-abc"))
    assert "| box (load 0.5, 0.4, 0.3) |" in row and "| p 1.0 |" in row
    assert "| local, 2 jobs | `ibench run -p a\\|b` |" in row
    page = (tmp_path / "index.html").read_text(encoding="utf-8")
    assert '<h2 id="provenance">Runs (provenance)</h2>' in page
    assert "<code>ibench run -p a|b</code>" in page
    write_report(make_records(), tmp_path / "old", runs=runs.iloc[:0], scaling_dir=NO_SCALING)
    assert "No run provenance stored" in (tmp_path / "old" / "index.md").read_text()


def test_a_part_added_in_one_place_reaches_both_renderers(tmp_path, monkeypatch):
    from integrator_bench.harness.report import sections
    from integrator_bench.harness.report.document import Block, Part

    def notes_part(g):
        n = int((g.rows["status"] == "ok").sum())
        return Part("notes", "Notes", caption="Added in PROBLEM_PARTS alone.",
                    blocks=[Block(text=[f"{n} ok cases."])], in_index=True)

    monkeypatch.setattr(sections, "PROBLEM_PARTS", sections.PROBLEM_PARTS + (notes_part,))
    write_report(make_records(), tmp_path, scaling_dir=NO_SCALING)
    group = (tmp_path / f"{SPRING}.md").read_text(encoding="utf-8")
    index = (tmp_path / "index.md").read_text(encoding="utf-8")
    page = (tmp_path / "index.html").read_text(encoding="utf-8")
    assert "## Notes\n\nAdded in PROBLEM_PARTS alone.\n\n6 ok cases." in group
    assert "## Notes" in index and f"### {SPRING.replace('_k=100', ' (k=100)')}" in index
    assert "<h3>Notes</h3><p>Added in PROBLEM_PARTS alone.</p><p>6 ok cases.</p>" in page


def test_pages_drawn_in_parallel_are_the_pages_drawn_one_by_one(tmp_path):
    """The problems' pages and the summary drawn by two forked processes give the
    same files, byte for byte, as drawn one after the other in this process."""
    one = write_report(make_records(), tmp_path / "one", scaling_dir=NO_SCALING, jobs=1)
    two = write_report(make_records(), tmp_path / "two", scaling_dir=NO_SCALING, jobs=2)
    assert [p.name for p in one] == [p.name for p in two]
    assert len(one) > 4
    for a, b in zip(one, two):
        assert a.read_bytes() == b.read_bytes(), a.name


def hostile_records() -> pd.DataFrame:
    """The synthetic records with an integrator named ``<script>...`` and a message
    holding HTML (a plugin's)."""
    return pd.concat([make_records(), pd.DataFrame([
        ok_row("<script>alert(1)</script>", 1e-6, 5.0),
        ok_row("scipy-DOP853", 1e-6, 0, status="failed", mescd=None, scd=None,
               message="<img src=x onerror=alert(2)> & more")])], ignore_index=True)


def test_markdown_shows_names_as_text_never_as_html(tmp_path):
    """An integrator named ``<script>...`` and a message holding HTML (a plugin's)
    appear in the Markdown pages as character references."""
    write_report(hostile_records(), tmp_path, scaling_dir=NO_SCALING)
    pages = [p.read_text(encoding="utf-8") for p in tmp_path.glob("*.md")]
    text = "\n".join(pages)
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in text
    assert "<script" not in text.replace("`<script>alert(1)</script>`", "")
    assert "<img" not in text.replace("`<img", "")


def test_html_page_shows_names_as_text_never_as_html(tmp_path):
    """The same names on the HTML page: escaped in its text, and in the interactive
    figures' data no ``<`` at all (JSON's ``\\u003c``), so none can end a script."""
    import re

    write_report(hostile_records(), tmp_path, scaling_dir=NO_SCALING)
    page = (tmp_path / "index.html").read_text(encoding="utf-8")
    assert "alert(1)</script>" not in page and "<img src=x" not in page
    scripts = re.findall(r"<script>(.*?)</script>", page, flags=re.S)
    plots = [s for s in scripts if "Plotly.newPlot" in s]
    assert len(plots) >= 2 and all("<" not in s for s in plots)
    assert any("\\u003cscript\\u003ealert(1)" in s for s in plots)
