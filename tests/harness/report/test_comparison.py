"""Formulation comparison tables of the report, from real store records."""

import pandas as pd

from integrator_bench.harness.matrix.cases import expand
from integrator_bench.harness.report import markdown, write_report
from integrator_bench.harness.report.comparison import comparison_table
from integrator_bench.harness.report.document import Group
from integrator_bench.harness.report.sections import comparison_part
from integrator_bench.harness.matrix.store import Store, load
from integrator_bench.harness.run.context import RunContext
from records_frame import records_frame


def comparison_markdown(rows):
    """The "Formulations compared" part of ``rows``, in Markdown."""
    group = Group(rows=rows, ranked=pd.DataFrame(), families={}, figure=None)
    return "\n".join(markdown.part(comparison_part(group)))


def test_comparison_from_a_stored_run_with_null_counts(tmp_path, monkeypatch, run_cases):
    """IDA on three formulations beside HHT; a count a code cannot know is null (here
    IDA's linear-solver setups, made unknown), shares
    a column with HHT's known ones, comes back from the store as pandas NA, and
    prints as a dash."""
    from integrator_bench.integrators import sundials_stats
    read = sundials_stats.read      # nlu left unknown; the workers, forked, inherit it
    monkeypatch.setattr(sundials_stats, "read",
                        lambda *args: {k: v for k, v in read(*args).items() if k != "nlu"})
    cases = expand(problems=["pendulum"], formulations=["i3", "i2", "ggl"],
                   integrators=["ida", "hht"], rtols=[1e-2, 1e-4])
    with Store(tmp_path / "s.sqlite") as store:
        run_cases(cases, RunContext(store=store, jobs=2, progress=False))
    df = load(tmp_path / "s.sqlite")
    assert df[df.integrator == "ida"].nlu.isna().all()
    assert df[(df.integrator == "hht") & (df.status == "ok")].nlu.notna().all()
    df = df[df.status != "unsupported"]
    table = comparison_table(df[df.integrator == "ida"])
    assert list(table.columns) == [(f, t) for f in ("ggl", "i2", "i3") for t in ("0.01", "0.0001")]
    assert table.loc["NS (steps)"].notna().all()
    text = comparison_markdown(df)
    assert "## Formulations compared" in text
    assert "### ida" in text and "| NLU (LU factorizations) | – |" in text
    assert text.count("\n| ") >= 10
    # through the report, which turns counts into nullable integers (pandas NA)
    files = write_report(load(tmp_path / "s.sqlite"), tmp_path / "report")
    md = next(f for f in files if f.suffix == ".md" and f.name.startswith("pendulum"))
    assert "| NLU (LU factorizations) | – |" in md.read_text()


def test_no_table_for_a_single_formulation():
    df = records_frame({"integrator": ["x", "x"], "formulation": ["ode", "ode"],
                        "rtol": [1e-2, 1e-4], "status": ["ok", "ok"],
                        **{k: [1, 2] for k in ("nfev", "nsteps", "njev", "nlu", "nniter",
                                               "nnfail", "cpu_s", "drift_pos", "drift_vel",
                                               "mescd")}})
    assert "No integrator ran two formulations of this problem." in comparison_markdown(df)
    assert "###" not in comparison_markdown(df)
