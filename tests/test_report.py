"""Tests of harness.report on small synthetic record tables."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from integrator_bench.harness.record import FIELDS, empty_record
from integrator_bench.harness.report import (FAILED_LABEL, TABLE_COLUMNS, slug, work_precision_figure,
                            write_report)

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
SPRING = "spring_pendulum_k=100"
PENDULUM = "pendulum_L=1_g=9.81"
TWO_MASS = "two_mass_c=0.5"
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
    return pd.DataFrame(rows, columns=list(FIELDS))


@pytest.fixture
def report(tmp_path):
    paths = write_report(make_records(), tmp_path)
    return tmp_path, paths


def test_slug():
    assert slug("spring_pendulum", '{"k": 100.0}') == "spring_pendulum_k=100"
    assert slug("pendulum", '{"g": 9.81, "L": 1.0}') == PENDULUM
    assert slug("p", '{"a": 1e-05, "name": "x/y z"}') == "p_a=1e-05_name=x_y_z"
    assert slug("p", "{}") == "p"


def test_files_exist_and_pngs_are_valid(report):
    out, paths = report
    expected = [out / f"{name}.{ext}" for name in (PENDULUM, SPRING, TWO_MASS)
                for ext in ("png", "csv", "md")] + [out / "index.md"]
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
    rows = [line for line in lines[header + 2:] if line.startswith("|")]
    assert len(rows) == 9
    cells = [c.strip() for c in rows[3].strip("|").split("|")]   # RK45 at rtol 1e-3
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
    write_report(records, tmp_path)
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
    paths = write_report(pd.DataFrame(columns=list(FIELDS)), tmp_path / "out")
    assert paths == [tmp_path / "out" / "index.md"]
    assert list((tmp_path / "out").iterdir()) == paths
    assert "no records" in paths[0].read_text(encoding="utf-8").lower()


def _failed_line(ax):
    lines = [line for line in ax.get_lines()
             if line.get_marker() == "x" and line.get_color() == "red"]
    assert len(lines) == 1
    return lines[0]


def test_figure_marks_failures_and_skips_unsupported():
    import matplotlib.pyplot as plt
    from integrator_bench.harness.report import clean_records

    records = clean_records(make_records())
    rows = records[records["problem"] == "spring_pendulum"]
    fig = work_precision_figure(rows, "spring_pendulum (k=100)")
    try:
        cpu_ax, nfev_ax = fig.axes
        assert cpu_ax.get_xscale() == cpu_ax.get_yscale() == "log"
        labelled = {line.get_label(): line for line in cpu_ax.get_lines()
                    if not line.get_label().startswith("_")}
        assert set(labelled) == {"scipy-RK45 (ode)", "scipy-Radau (ode)"}
        rk45 = labelled["scipy-RK45 (ode)"]
        assert np.allclose(rk45.get_xdata(), [1e-3, 1e-6, 1e-9][::-1])  # sorted by rtol
        biggest = max(line.get_xdata().max() for line in labelled.values())
        for ax, known in [(cpu_ax, 0.5), (nfev_ax, 4000)]:
            failed = _failed_line(ax)
            x, y = failed.get_xdata(), failed.get_ydata()
            assert len(x) == 2                 # failed + timeout, not unsupported
            assert (x > biggest).all() and x.max() < ax.get_xlim()[1]
            assert known in y                  # measured cost where known
            assert max(y) < ax.get_ylim()[1] and max(y) > known  # else near the top
        legend = [t.get_text() for t in fig.legends[0].get_texts()]
        assert FAILED_LABEL in legend
    finally:
        plt.close(fig)


def test_figure_without_ok_rows_has_note():
    import matplotlib.pyplot as plt
    from integrator_bench.harness.report import clean_records

    records = clean_records(make_records())
    fig = work_precision_figure(records[records["problem"] == "two_mass"], "two_mass")
    try:
        texts = [t.get_text() for ax in fig.axes for t in ax.texts]
        assert any("no successful runs" in t for t in texts)
        assert len(_failed_line(fig.axes[0]).get_xdata()) == 1
    finally:
        plt.close(fig)


def test_ok_without_mescd_counts_as_failed():
    import matplotlib.pyplot as plt
    from integrator_bench.harness.report import clean_records

    rows = clean_records(pd.DataFrame([ok_row("a", 1e-3, 3.0),
                                       ok_row("a", 1e-6, 0, mescd=math.nan, cpu_s=0.2)]))
    fig = work_precision_figure(rows, "t")
    try:
        assert list(_failed_line(fig.axes[0]).get_ydata()) == [0.2]
    finally:
        plt.close(fig)
