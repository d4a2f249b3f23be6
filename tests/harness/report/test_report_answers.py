"""The report's first screen answers (per problem: the cheapest line, its CPU, the
tolerance at the crossing, its margin, on top of index.md, index.html and each
section, before the figures), ``ibench report --target E`` answers at any positive
target, and the records of an advice are kept apart from the problem's own, so the
report's answer is the run's summary's. Small hand-made records and stores."""

from __future__ import annotations

import math

import pandas as pd
import pytest

from integrator_bench.harness.cli import main
from integrator_bench.harness.cli.summary import summary
from integrator_bench.harness.matrix.record import empty_record
from integrator_bench.harness.ranking.reach import cheapest, target_table
from integrator_bench.harness.ranking.records import clean_records
from integrator_bench.harness.report import write_report
from integrator_bench.harness.run.context import RunContext
from records_frame import exact, records_frame

NO_SCALING = "/nonexistent/scaling"
OWN, ADVICE = "20260101T000000-own", "20260102T000000-adv"


def point(integrator, rtol, err, cpu, params='{"k": 100.0}', run_id=OWN, **extra):
    """An ok record of spring_pendulum whose errors are ``err``."""
    return empty_record(problem="spring_pendulum", params=params, formulation="ode",
                        integrator=integrator, rtol=rtol, status="ok",
                        scd=-math.log10(err), mescd=-math.log10(err), err_max=err,
                        err_rms=err / 2, cpu_s=cpu, cpu_samples=exact(cpu), run_id=run_id,
                        created="2026-01-01T00:00:00+00:00", **extra)


def own_records() -> pd.DataFrame:
    """scipy-Radau crosses 1e-5 at 0.01 s (interpolated), scipy-RK45 at 0.02 s."""
    return records_frame([point("scipy-Radau", 1e-4, 1e-4, 0.001),
                          point("scipy-Radau", 1e-6, 1e-6, 0.1),
                          point("scipy-RK45", 1e-4, 1e-4, 0.002),
                          point("scipy-RK45", 1e-6, 1e-6, 0.2)])


def test_the_first_screen_answers(tmp_path):
    write_report(own_records(), tmp_path, scaling_dir=NO_SCALING)
    index = (tmp_path / "index.md").read_text(encoding="utf-8")
    heads = [line for line in index.splitlines() if line.startswith("## ")]
    assert heads[0] == "## Answers: the cheapest line to an error of 1e-05", heads
    row = next(line for line in index.splitlines() if line.startswith("| spring_pendulum |"))
    assert [c.strip() for c in row.split("|")[1:-1]] == [
        "spring_pendulum", "k=100", "scipy-Radau (ode)", "0.01", "rtol 1e-05", "2x (exact)"]
    page = next(tmp_path.glob("spring_pendulum*.md")).read_text(encoding="utf-8")
    lines = page.splitlines()
    assert lines[2].startswith("Answer: cheapest to reach an error of 1e-05") and \
        "**scipy-Radau (ode)**, 0.01 s CPU at rtol 1e-05, margin 2 over scipy-RK45 " \
        "(ode), exact" in lines[2]
    assert lines.index("## Work-precision") < lines.index("## CPU to reach a target error")
    html = (tmp_path / "index.html").read_text(encoding="utf-8")
    assert html.index('id="answers"') < html.index('id="summary"')
    section = html[html.index("<section"):]
    assert section.index('class="answer"') < section.index("<img")


def test_a_target_of_the_users_choice(tmp_path):
    write_report(own_records(), tmp_path, scaling_dir=NO_SCALING, target=2.5e-4)
    page = next(tmp_path.glob("spring_pendulum*.md")).read_text(encoding="utf-8")
    assert "cheapest to reach an error of 0.00025" in page and "CPU [s] to 0.00025" in page
    assert "CPU [s] to 1e-05" not in page
    index = (tmp_path / "index.md").read_text(encoding="utf-8")
    assert "## Answers: the cheapest line to an error of 0.00025" in index


@pytest.fixture
def store(tmp_path):
    from integrator_bench.harness.matrix.store import Store

    path = tmp_path / "s.sqlite"
    with Store(path) as s:
        for r in own_records().to_dict("records"):
            s.add(r)
    return path


def test_report_target_option(store, tmp_path, capsys):
    assert main(["report", "--store", str(store), "--out", str(tmp_path / "r"),
                 "--target", "1e-6"]) == 0
    page = next((tmp_path / "r").glob("spring_pendulum*.md")).read_text(encoding="utf-8")
    assert "Answer: cheapest to reach an error of 1e-06 (" in page
    assert "**scipy-Radau (ode)**, 0.1 s CPU at rtol 1e-06" in page


@pytest.mark.parametrize("value", ["0", "-1e-3", "inf", "nan", "tiny"])
def test_a_bad_target_is_one_line_exit_2_nothing_written(store, tmp_path, capsys, value):
    before = sorted(tmp_path.rglob("*"))
    with pytest.raises(SystemExit) as stop:
        main(["report", "--store", str(store), "--out", str(tmp_path / "r"),
              "--target", value])
    err = capsys.readouterr().err.strip().splitlines()
    assert stop.value.code == 2 and len(err) == 1 and f"--target {value!r}" in err[0], err
    assert sorted(tmp_path.rglob("*")) == before


def advice_records() -> pd.DataFrame:
    """What an advice stores: a tighter scipy-RK45 run that makes it the cheapest on the
    problem's own parameters, and a perturbed parameter set."""
    return records_frame([point("scipy-RK45", 1e-5, 1e-5, 0.003, run_id=ADVICE),
                          point("scipy-RK45", 1e-5, 1e-5, 0.003, params='{"k": 103.0}',
                                run_id=ADVICE)])


def test_the_advice_records_are_kept_apart(tmp_path):
    """Marked by the run's purpose."""
    own, advice = own_records(), advice_records()
    runs = pd.DataFrame([{"run_id": OWN, "purpose": "run", "command": "ibench run"},
                         {"run_id": ADVICE, "purpose": "advise",
                          "command": "ibench advise -p spring_pendulum:k=100 --target 1e-5"}])
    both = pd.concat([own, advice], ignore_index=True)
    mixed = clean_records(both[both["params"] == own["params"].iloc[0]])
    assert cheapest(target_table(mixed), 1e-5)["label"] == "scipy-RK45"  # counted, it wins
    write_report(both, tmp_path / "apart", runs=runs, scaling_dir=NO_SCALING)
    index = (tmp_path / "apart" / "index.md").read_text(encoding="utf-8")
    answer = next(line for line in index.splitlines() if line.startswith("| spring_pendulum |"))
    assert "| scipy-Radau (ode) |" in answer
    assert "scipy-Radau/ode" in summary(own).splitlines()[1]    # the run's summary agrees
    assert "k=103" not in answer and not list((tmp_path / "apart").glob("*k=103*"))
    assert "4 records (0 superseded repeats dropped); 2 records of ibench advise runs kept " \
        "apart" in index
    part = index[index.index("## Advice records (kept apart)"):]
    assert "| spring_pendulum | k=100 | 1 | 1 | 1 |" in part
    assert "| spring_pendulum | k=103 | 1 | 1 | 1 |" in part


def test_a_store_from_before_purpose_gets_it_from_the_command(tmp_path):
    """A store whose runs lack ``purpose`` gets it when read, from each stored command
    line, split as a shell splits it: ``ibench advise ...`` is an advice."""
    import sqlite3

    from integrator_bench.harness.matrix import provenance
    from integrator_bench.harness.matrix.store import Store, load_runs
    commands = ["ibench run -p pendulum", "ibench advise -p 'spring_pendulum:k=100'",
                "ibench 'unbalanced", "python -m ibench advise"]
    with Store(tmp_path / "s.sqlite") as store:
        for command in commands:
            store.begin_run(provenance.collect(command, purpose="run"))
    with sqlite3.connect(tmp_path / "s.sqlite") as db:
        db.execute("UPDATE runs SET purpose = NULL")
    runs = load_runs(tmp_path / "s.sqlite")
    assert dict(zip(runs["command"], runs["purpose"])) == dict(zip(
        commands, ["run", "advise", "run", "run"]))


def test_a_run_stores_its_purpose(tmp_path, run_cases):
    from integrator_bench.harness.matrix.cases import expand
    from integrator_bench.harness.matrix.store import Store, load_runs

    cases = expand(problems=["two_mass"], integrators=["scipy-RK45"], rtols=[1e-3],
                   formulations=["ode"])
    with Store(tmp_path / "s.sqlite") as store:
        run_cases(cases, RunContext(store=store, jobs=1, progress=False, purpose="advise"))
        run_cases(cases, RunContext(store=store, jobs=1, progress=False))
    assert list(load_runs(tmp_path / "s.sqlite")["purpose"]) == ["advise", "run"]
