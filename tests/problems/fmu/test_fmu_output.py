"""An FMU's own output: its log lines (through the importer's logger callback) go to
standard error, and a ``--json`` command's standard output carries JSON alone,
whatever the FMU prints, in the calling process (the problem's set-up, its
reference) as in the workers (tests/fmu_chatty)."""

import json

import pytest

from integrator_bench.harness.cli import main

LOGGED = "[WARNING] chatty: a warning at the start time"
PRINTED = "chatty: printed to standard output at the start time"


@pytest.fixture(autouse=True)
def _fresh(tmp_path, monkeypatch):
    """References computed under ``tmp_path``, and each FMU set up afresh in this
    process (so that it talks here, whatever an earlier test did)."""
    from integrator_bench.harness.measure import references
    from integrator_bench.problems.fmu import problem as fmu_problem_module

    monkeypatch.setattr(references, "REFERENCE_DIR", tmp_path / "reference")
    monkeypatch.setattr(fmu_problem_module, "_SET_UP", set())


def _json_lines(out: str) -> list:
    lines = out.splitlines()
    assert lines, "nothing on standard output"
    return [json.loads(line) for line in lines]   # each line JSON, or this raises


@pytest.mark.parametrize("version", ["2.0", "3.0"])
def test_run_json_is_json_only_and_the_fmu_talks_on_stderr(chatty_fmus, version, tmp_path,
                                                           capfd):
    status = main(["run", "--json", "-p", f"fmu:path={chatty_fmus[version]}",
                   "-i", "scipy-RK45", "-i", "fmpy-cvode", "--rtol", "1e-3",
                   "--store", str(tmp_path / "s.sqlite")])
    out, err = capfd.readouterr()
    records = _json_lines(out)
    assert status == 0 and {r["integrator"] for r in records} == {"scipy-RK45", "fmpy-cvode"}
    assert all(r["status"] == "ok" for r in records), records
    assert LOGGED in err and PRINTED in err     # the parent's set-up of the FMU talked


def test_advise_json_is_one_json_object(chatty_fmus, tmp_path, capfd):
    main(["advise", "--json", "-p", f"fmu:path={chatty_fmus['2.0']}", "--target", "1e-3",
          "-i", "scipy-RK45", "--perturbed", "0", "--budget", "60s",
          "--store", str(tmp_path / "s.sqlite"), "--out", str(tmp_path / "advice")])
    out, err = capfd.readouterr()
    (answer,) = _json_lines(out)
    assert answer["lines"] and LOGGED in err and PRINTED in err
    from integrator_bench.harness.matrix.store import load_runs    # the report keeps them apart
    assert set(load_runs(tmp_path / "s.sqlite")["purpose"]) == {"advise"}


def test_log_lines_go_to_stderr_without_json_too(chatty_fmus, tmp_path, capfd):
    from integrator_bench.problems.fmu import FmuProblem

    problem = FmuProblem(path=str(chatty_fmus["2.0"]))
    problem.formulate("ode").fun(0.0, problem.initial_state())
    out, err = capfd.readouterr()
    assert LOGGED in err and LOGGED not in out
