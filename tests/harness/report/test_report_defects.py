"""Defects found in the report by a reader, each with the test that would have caught it."""

from __future__ import annotations

import json

import matplotlib.pyplot as plt
import pandas as pd
import pytest

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.record import FIELDS
from integrator_bench.harness.ranking.reach import target_table
from integrator_bench.harness.ranking.records import clean_records
from integrator_bench.harness.report import write_report
from integrator_bench.harness.report.figures import FAILED_LABEL, OFF_AXIS, work_precision_figure
from integrator_bench.harness.report.sections import problem_info
from integrator_bench.harness.report.style import BUILTIN, PLUGIN_COLORS, styles

from test_report import NO_SCALING, OLD, ok_row
from records_frame import records_frame

PROBLEMS = sorted(registry.problems())
INTEGRATORS = registry.integrators()


def _params(name: str) -> str:
    """The parameters a run of ``name``'s first benchmark set records (all of them)."""
    cls = registry.problems()[name]
    given = cls.benchmark_parameters[0] if cls.benchmark_parameters else {}
    return json.dumps(cls(**given).params, sort_keys=True)


# --- the time span is the one of the parameters that ran ------------------------------

@pytest.mark.parametrize("name", PROBLEMS)
def test_problem_info_gives_the_span_of_the_parameters_that_ran(name):
    params = _params(name)
    t0, t1 = registry.problems()[name](**json.loads(params)).t_span
    info = problem_info(name, params)
    assert info.error == ""
    assert info.time_span == f"[{t0:g}, {t1:g}]"


def test_page_shows_the_span_of_chain_bushing_and_spring_pendulum(tmp_path):
    rows = [ok_row("scipy-Radau", 1e-3, 3.0, problem=name, params=_params(name))
            for name in ("spring_pendulum", "chain_bushing")]
    write_report(pd.DataFrame(rows, columns=list(FIELDS)), tmp_path, scaling_dir=NO_SCALING)
    page = (tmp_path / "index.html").read_text(encoding="utf-8")
    assert "property object" not in page
    spans = [x.split("<br>")[0].split(";")[0] for x in page.split("<b>time span:</b> ")[1:]]
    assert spans == ["[0, 0.1]", "[0, 10]"]         # chain_bushing (n_links=30), then spring
    md = next(tmp_path.glob("chain_bushing*.md")).read_text(encoding="utf-8")
    assert "time span: [0, 0.1]" in md


# --- ok runs with a negative scd are not "failed" -------------------------------------

def _mixed_rows() -> pd.DataFrame:
    rows = [ok_row("scipy-RK45", rtol, d) for rtol, d in ((1e-3, 3.0), (1e-6, 6.0))]
    rows.append(ok_row("scipy-RK45", 1e-1, 0.0, scd=-0.48, mescd=-0.4,    # ok, error > 100%
                       err_max=10 ** 0.4))
    rows.append(ok_row("scipy-RK45", 1e-12, 0.0, status="failed", scd=None, mescd=None,
                       message="step-size underflow"))
    return records_frame(rows)


def one_panel(records: pd.DataFrame):
    """The legend texts and the lines ``(label, marker, linestyle, points)`` of the one
    panel of ``records``' figure."""
    fig = work_precision_figure(clean_records(records), "t")
    try:
        (ax,) = [ax for ax in fig.axes if ax.get_visible()]
        return ([t.get_text() for t in ax.get_legend().get_texts()],
                [(x.get_label(), x.get_marker(), x.get_linestyle(), len(x.get_xdata()))
                 for x in ax.get_lines()])
    finally:
        plt.close(fig)


def test_figure_legend_counts_ok_runs_off_the_axis_apart_from_failures():
    legend, lines = one_panel(_mixed_rows())
    assert "1 not ok (1 failed), at its CPU" in legend and FAILED_LABEL == "not ok, at its CPU"
    assert f"1 {OFF_AXIS['error above 100%'][0]}" in legend
    assert {m: n for _, m, style, n in lines if style == "None"} == {"x": 1, "+": 1}


def test_markdown_counts_ok_runs_off_the_axis_apart_from_failures(tmp_path):
    write_report(_mixed_rows(), tmp_path, scaling_dir=NO_SCALING)
    md = next(tmp_path.glob("spring_pendulum*.md")).read_text(encoding="utf-8")
    assert ("Right of the error axis: 1 not ok (1 failed), at its CPU; "
            f"1 {OFF_AXIS['error above 100%'][0]}.") in md


def test_the_count_of_cases_not_ok_separates_timeouts_from_failures():
    """A problem page said "12 failed" where one of the twelve was a timeout."""
    from integrator_bench.harness.report.figures import off_axis_caption
    rows = _mixed_rows()
    more = rows.iloc[[-1, -1, -1]].copy()
    more["status"] = ["failed", "timeout", "crashed"]
    caption = off_axis_caption(pd.concat([rows, more], ignore_index=True))
    assert caption.startswith("Right of the error axis: 4 not ok (2 failed, 1 crashed, "
                              "1 timeout), at its CPU; "), caption


# --- every integrator its own colour ------------------------------------------------------

PLUGINS = ("ros3p", "heun", "my-plugin", "another-plugin", "rodas", "radau-plugin")


def test_every_registered_and_plugin_integrator_has_its_own_colour():
    got = styles([*INTEGRATORS, *PLUGINS])
    colours = [c for c, _ in got.values()]
    assert len(set(colours)) == len(colours)
    # the clashes: ros3p with sdirk3, heun with scipy-Radau
    assert got["ros3p"][0] != got["sdirk3"][0] and got["heun"][0] != got["scipy-Radau"][0]
    builtin = {c for c, _ in BUILTIN.values()}
    assert len(builtin) == len(BUILTIN) and not builtin & set(PLUGIN_COLORS)
    assert all(got[p][0] in PLUGIN_COLORS for p in PLUGINS)


@pytest.mark.parametrize("name", sorted(n for n, c in INTEGRATORS.items()
                                        if c.origin == "built-in"))
def test_a_built_in_keeps_its_fixed_style(name):
    assert name in BUILTIN, f"{name}: append a colour to BUILTIN"
    assert styles([name, *PLUGINS])[name] == BUILTIN[name]


def test_plugin_colours_are_stable_across_runs():
    a = styles(["heun", "ros3p", *INTEGRATORS])
    b = styles(list(reversed([*INTEGRATORS, "ros3p", "heun"])))
    assert a == b                                   # the order of a run does not matter
    assert styles(["heun"])["heun"] == styles(["heun", "scipy-RK45"])["heun"]


def test_more_plugins_than_colours_still_get_a_style():
    names = [f"plugin-{k}" for k in range(len(PLUGIN_COLORS) + 3)]
    got = styles(names)
    assert len({c for c, _ in got.values()}) == len(PLUGIN_COLORS)


# --- a line per (integrator, formulation, mode) --------------------------------------------

def _both_ways() -> pd.DataFrame:
    rows = [ok_row("bdf2", rtol, d, problem="two_mass", params='{"c2": 0.1}')
            for rtol, d in ((1e-3, 3.0), (1e-6, 6.0))]
    rows += [ok_row("bdf2", None, d, problem="two_mass", params='{"c2": 0.1}', h=h,
                    cpu_s=c, created=OLD)
             for h, d, c in ((0.1, 2.0, 5e-3), (0.01, 4.0, 5e-2))]
    return records_frame(rows)


def test_adaptive_and_fixed_runs_are_two_lines():
    records = clean_records(_both_ways())
    table = target_table(records)
    assert sorted(zip(table["label"], table["mode"])) == [("bdf2", "h"), ("bdf2", "rtol")]
    _, lines = one_panel(records)
    drawn = {label: n for label, _, _, n in lines if not label.startswith("_")}
    assert drawn == {"bdf2 (ode)": 2, "bdf2 (ode, fixed h)": 2}


def test_markdown_names_the_fixed_step_line(tmp_path):
    write_report(_both_ways(), tmp_path, scaling_dir=NO_SCALING)
    md = next(tmp_path.glob("two_mass*.md")).read_text(encoding="utf-8")
    assert "| bdf2 | ode (fixed h) |" in md and "| bdf2 | ode | " in md


def test_a_store_with_an_infinite_cpu_s_reports_it_as_such(tmp_path):
    """A damaged or edited store's ``cpu_s`` of inf: the report is written (no axis
    limit from it), its table shows inf and the page says the record is not ranked."""
    from test_report import make_records

    df = make_records()
    df.loc[df.index[:2], "cpu_s"] = float("inf")
    write_report(df, tmp_path, jobs=1, scaling_dir=tmp_path / "none")
    page = (tmp_path / "index.md").read_text() + "".join(
        p.read_text() for p in tmp_path.glob("*.md") if p.name != "index.md")
    assert "2 ok records with an infinite cpu_s" in page and "| inf |" in page
