"""Perturbed initial states: an FMU whose only inputs are its states' start values
(``start.NAME`` options) is checked by ``ibench advise`` on perturbed start sets.

The FMU is a Van der Pol oscillator without parameters, built here from C sources
(``tests/fmu_vanderpol``): x(0) = 2, v(0) = 0, both ``initial="exact"``."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from integrator_bench.harness.advise import certificate
from integrator_bench.harness.matrix import registry
from integrator_bench.problems.base import ProblemError
from integrator_bench.problems.fmu import FmuProblem
from integrator_bench.problems.system import convert

HERE = Path(__file__).resolve().parents[2]
IBENCH = [sys.executable, "-m", "integrator_bench.harness.cli"]


@pytest.fixture(scope="module")
def vanderpol(tmp_path_factory):
    pytest.importorskip("fmpy")
    from integrator_bench.problems import fmu_build
    try:
        return fmu_build.build_fmu("vanderpol", tmp_path_factory.mktemp("fmu"),
                                   source_dir=HERE / "fmu_vanderpol")
    except RuntimeError as exc:
        pytest.skip(str(exc))


def _env(tmp_path):
    return {**os.environ, "IBENCH_DATA_DIR": str(tmp_path / "data"),
            "IBENCH_REFERENCE_DIR": str(tmp_path / "data" / "reference")}


def _first_output(problem, integrator, rtol=1e-6):
    icls = registry.get_integrator(integrator)
    system = convert(problem.formulate(), icls)
    sol = icls().solve(system, rtol=rtol, atol=system.atol(rtol))
    assert sol.success
    return np.asarray(sol.t)[0], np.asarray(sol.y)[0]


@pytest.mark.parametrize("integrator", ["scipy-RK45", "fmpy-cvode"])
def test_a_start_option_starts_the_run_where_asked(vanderpol, integrator):
    """Through the harness's own stepping of the FMU and through fmpy's simulation
    (which sets the start values itself), the first output is the given start."""
    default = FmuProblem(path=str(vanderpol))
    assert default.parameters == ()
    assert [s.name for s in default.settable_starts()] == ["start.x", "start.v"]
    np.testing.assert_array_equal(default.initial_state(), [2.0, 0.0])
    moved = FmuProblem(path=str(vanderpol), **{"start.x": "1.5", "start.v": "0.25"})
    assert moved.params["start.x"] == 1.5 and "start.x=1.5" in moved.label()
    assert moved.key_params() != default.key_params()    # its own reference
    t0, y0 = _first_output(moved, integrator)
    assert t0 == moved.t_span[0]
    np.testing.assert_allclose(y0, [1.5, 0.25], rtol=0, atol=1e-12)
    assert not np.allclose(_first_output(default, integrator)[1], y0)


def test_fmi3_state_starts_are_options_too(built_fmus3):
    problem = FmuProblem(path=str(built_fmus3["two_mass"]), **{"start.x2": 1.02})
    np.testing.assert_array_equal(problem.initial_state(), [1.0, 1.02, 0.0, 0.0])


@pytest.mark.parametrize("command, option, expected", [
    ("run", "start.y=1", "'start.y' sets no state start of FMU"),
    ("advise", "start.y=1", "'start.y' sets no state start of FMU"),
    ("run", "start.x=abc", "start.x='abc' is not a number"),
    ("run", "mu=2", "unknown parameter 'mu' for problem fmu; valid: start.x, start.v"),
])
def test_a_bad_start_option_is_one_line_exit_2_naming_the_valid_ones(vanderpol, tmp_path,
                                                                     command, option, expected):
    more = ["--target", "1e-4", "--out", str(tmp_path / "page")] if command == "advise" else []
    r = subprocess.run([*IBENCH, command, "-p", f"fmu:path={vanderpol},{option}", "-i",
                        "cvode-bdf", "--store", str(tmp_path / "s.sqlite"), *more],
                       capture_output=True, text=True, env=_env(tmp_path), cwd=tmp_path)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and expected in lines[0], r.stderr
    assert "start.x, start.v" in lines[0] or "not a number" in lines[0]
    assert not (tmp_path / "s.sqlite").exists() and not (tmp_path / "data").exists()
    assert not (tmp_path / "page").exists()


def test_a_calculated_state_start_is_not_an_option(built_fmus):
    """The bouncing ball's states are initial="calculated": the FMU computes them."""
    with pytest.raises(ProblemError, match='initial="calculated".*valid: none'):
        FmuProblem(path=str(built_fmus["bouncing_ball"]), **{"start.y": 2.0})


def test_perturbed_starts_follow_the_rule_and_repeat(vanderpol):
    """No parameter: each start times 1 + u 3 %; the zero start plus u 3 % of its
    atol scale (2 here)."""
    problem = FmuProblem(path=str(vanderpol))
    a, b = (certificate.perturbation(problem, 3) for _ in range(2))
    assert a == b and a.what == certificate.STARTS
    assert a.names == ("start.x", "start.v") and len(a.sets) == 3
    p = certificate.PERTURBATION
    for s in a.sets:
        assert s["start.x"] != 2.0 and abs(s["start.x"] / 2.0 - 1) <= p
        assert s["start.v"] != 0.0 and abs(s["start.v"]) <= p * 2.0
    facts = certificate.perturbed_facts(problem, a)
    assert facts.starts == {"start.x": {"start": 2.0, "scale": 2.0},
                               "start.v": {"start": 0.0, "scale": 2.0}}


def test_a_mechanism_without_parameters_is_not_perturbed_in_its_start():
    """The squeezer has no parameter, and its start must stay consistent."""
    squeezer = registry.get_problem_class("squeezer")()
    assert squeezer.parameters == () and squeezer.settable_starts() == ()
    assert certificate.perturbation(squeezer, 2) == certificate.Perturbation(None, (), ())


def test_advise_checks_the_advice_on_perturbed_start_sets(vanderpol, tmp_path):
    """The robustness check of a model without parameters: N start sets, each run
    against its own reference, their errors reported, the advice verified on them."""
    target, n = 1e-5, 3
    cmd = [*IBENCH, "advise", "-p", f"fmu:path={vanderpol}", "--target", str(target),
           "-i", "cvode-adams", "-i", "scipy-DOP853", "--perturbed", str(n),
           "--store", str(tmp_path / "s.sqlite"), "--out", str(tmp_path / "page"), "--jobs", "1"]
    got = subprocess.run([*cmd, "--json"], capture_output=True, text=True, env=_env(tmp_path),
                         timeout=600)
    assert got.returncode == 0, got.stderr
    answer = json.loads(got.stdout)
    rob = answer["robustness"]
    assert rob["why"] is None and rob["perturbed"]["what"] == "initial states"
    assert rob["perturbed"]["names"] == ["start.x", "start.v"]
    assert rob["perturbed"]["relative"] == certificate.PERTURBATION
    assert len(rob["sets"]) == n and all(set(s) == {"start.x", "start.v"} for s in rob["sets"])
    holding = rob["checked"][0]
    errors = [r["error"] for r in holding["runs"]]
    assert len(errors) == n and all(0 < e <= target for e in errors) and holding["holds"]
    assert len(set(errors)) == n       # each set is its own run against its own reference
    assert answer["status"] == "answer" and answer["verified_sets"] == n
    # a reference per start set, beside the model's own
    refs = list((tmp_path / "data" / "reference").rglob("*.npz"))
    assert len(refs) == n + 1
    # the terminal text says what was perturbed, and the answer's line stays
    text = subprocess.run(cmd, capture_output=True, text=True, env=_env(tmp_path),
                          timeout=600).stdout
    assert f"on {n} perturbed start sets: errors" in text
    assert "perturbed initial states" in text and "start.v, start.x" in text
    assert text.strip().splitlines()[-1].endswith(f"verified on {n} perturbed sets")
    assert "perturbed initial states" in (tmp_path / "page" / "index.html").read_text()
