"""FMI 3.0 array variables: the project's ``state_space`` FMU (problems/fmu_sources,
built here with the system's C compiler), a linear system x' = A x + B u,
y = C x + D u whose arrays the structural parameters m, n, r size, run as fmpy
runs it and checked against its exact solution by the matrix exponential."""

import json
import os
import re
import subprocess
import sys

import numpy as np
import pytest
from scipy.linalg import expm

from integrator_bench.harness.measure import references
from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.cases import Case
from integrator_bench.harness.matrix.record import CaseStatus
from integrator_bench.harness.run.execution import execute
from integrator_bench.problems.base import ProblemError
from integrator_bench.problems.fmu import FmuProblem, element_names
from integrator_bench.problems.system import Unsupported, convert

fmpy = pytest.importorskip("fmpy")

IBENCH = [sys.executable, "-m", "integrator_bench.harness.cli"]
#: the default system scored on its states and its output
SCORE = "x[1]+x[2]+y[1]"
#: a reconfigured system: three states (the third decays on its own from 2), two
#: outputs (the second 3 x[3] + u)
THREE = {"n": 3, "r": 2, "A[3][3]": -1.0, "C[2][3]": 3.0, "D[2][1]": 1.0, "start.x[3]": 2.0}


@pytest.fixture(scope="module")
def state_space(tmp_path_factory):
    from integrator_bench.problems import fmu_build
    try:
        return str(fmu_build.build_fmu("state_space", tmp_path_factory.mktemp("ss"),
                                       fmi_version="3.0"))
    except RuntimeError as exc:
        pytest.skip(str(exc))


@pytest.fixture(scope="module")
def refs(state_space, tmp_path_factory):
    """The reference of the default system scored on ``SCORE``, computed here."""
    directory = tmp_path_factory.mktemp("ss_refs")
    references.load(FmuProblem(path=state_space, score=SCORE), directory)
    return directory


def _matrices(problem):
    """A, B, C, D, u and x0 of ``problem``'s parameters, as the FMU reads them."""
    p, n, m, r = problem.params, *(int(problem.params[k]) for k in "nmr")

    def matrix(name, rows, cols):
        return np.array([[p[f"{name}[{i + 1}][{j + 1}]"] for j in range(cols)]
                         for i in range(rows)])
    u = np.array([p[f"u[{j + 1}]"] for j in range(m)])
    return (matrix("A", n, n), matrix("B", n, m), matrix("C", r, n), matrix("D", r, m), u,
            problem.initial_state()[:n])


def _exact(problem, t):
    """The states and every output at times ``t``: x(t) = expm(M t) (x0, 1) with
    M = [[A, B u], [0, 0]] (the constant input as a state of its own)."""
    A, B, C, D, u, x0 = _matrices(problem)
    n = A.shape[0]
    M = np.zeros((n + 1, n + 1))
    M[:n, :n], M[:n, n] = A, B @ u
    X = np.array([(expm(M * tk) @ np.append(x0, 1.0))[:n] for tk in t])
    return X, X @ C.T + D @ u


def _error(Y, exact):
    return float(np.max(np.abs(Y - exact) / (1.0 + np.abs(exact))))


def test_arrays_are_read_as_their_elements(state_space):
    from fmpy.validation import validate_fmu

    assert validate_fmu(state_space) == []
    problem = FmuProblem(path=state_space)
    assert problem.components == ("x[1]", "x[2]")
    assert [p.name for p in problem.parameters] == [
        "m", "n", "r", "A[1][1]", "A[1][2]", "A[2][1]", "A[2][2]", "B[1][1]", "B[2][1]",
        "C[1][1]", "C[1][2]", "D[1][1]", "u[1]"]
    assert problem.params["A[2][1]"] == -4.0 and problem.params["n"] == 2.0
    assert problem.other_options() == ("start.x[1]", "start.x[2]")
    assert set(problem.fmu.outputs) == {"y[1]"}
    assert element_names("A", (2, 3))[3] == "A[2][1]"     # row-major, as FMI serializes
    three = FmuProblem(path=state_space, **THREE)
    assert three.components == ("x[1]", "x[2]", "x[3]")
    assert "A[3][3]" in three.params and set(three.fmu.outputs) == {"y[1]", "y[2]"}
    # the elements a larger size adds are the FMU's own (0), read after reconfiguring
    assert three.params["A[1][3]"] == 0.0 and three.params["A[2][1]"] == -4.0
    np.testing.assert_array_equal(three.initial_state(), [1.0, 0.0, 2.0])
    # the Jacobian by directional derivatives with array seeds is A
    system = three.formulate()
    np.testing.assert_array_equal(system.jac(0.0, system.y0), _matrices(three)[0])


@pytest.mark.parametrize("spec,expected", [
    ({"n": 7}, "parameter n=7 is outside its range [1, 6]"),
    ({"n": 2.5}, "structural parameter n=2.5 is not an integer"),
    ({"A[3][3]": 1.0}, "parameter 'A[3][3]' is no element of A (A[1][1] .. A[2][2] at m=1, "
                       "n=2, r=1); the structural parameters size the arrays"),
    ({"Z[1]": 1.0}, "unknown parameter 'Z[1]' for problem fmu; valid: m, n, r, A[1][1]"),
    ({"start.x[3]": 1.0}, "'start.x[3]' sets no state start"),
])
def test_bad_structural_and_element_values_are_refused(state_space, spec, expected):
    with pytest.raises(ProblemError, match=re.escape(expected)):
        FmuProblem(path=state_space, **spec)


def test_reference_agrees_with_the_exact_solution_and_with_fmpy(state_space, refs):
    """The harness's reference and fmpy's own simulation of the same FMU against
    the matrix exponential and each other: the reference to 1e-12 (3e-14
    measured), fmpy's CVode at rtol 1e-10 to 1e-7 (9e-9 measured), so the two
    agree to 1e-7 at fmpy's output times."""
    problem = FmuProblem(path=state_space, score=SCORE)
    ref = references.load(problem, refs, compute_missing=False)
    X, Y = _exact(problem, ref.t)
    assert _error(ref.Y, np.column_stack([X, Y])) < 1e-12
    result = fmpy.simulate_fmu(state_space, fmi_type="ModelExchange", output=["x", "y"],
                               relative_tolerance=1e-10, output_interval=0.1)
    fmpy_rows = np.column_stack([result["x"], result["y"]])    # x is fmpy's (n, 2) field
    assert _error(fmpy_rows, np.column_stack(_exact(problem, result["time"]))) < 1e-7
    common = np.isin(ref.t, result["time"])
    assert common.sum() >= 100
    at = np.searchsorted(result["time"], ref.t[common])
    assert _error(fmpy_rows[at], ref.Y[common]) < 1e-7


@pytest.mark.parametrize("integrator", ["scipy-DOP853", "cvode-bdf", "fmpy-cvode"])
def test_integrators_run_the_arrays(state_space, refs, integrator):
    """Through the harness (reference, run, error), the error close to the one
    measured against the exact solution."""
    problem = FmuProblem(path=state_space, score=SCORE)
    record = execute(Case(problem.name, tuple(sorted(problem.params.items())), "ode",
                          integrator, rtol=1e-6), reference_dir=refs)
    assert record["status"] == CaseStatus.OK, record["message"]
    icls = registry.get_integrator(integrator)
    system = convert(problem.formulate(), icls)
    sol = icls().solve(system, rtol=1e-6, atol=system.atol(1e-6))
    Y = system.output(sol.t, sol.y)        # states and the scored output
    error = _error(Y, np.column_stack(_exact(problem, sol.t)))
    assert 1e-10 < error < 1e-3
    # the harness's error (against its reference) is the one against the exact solution
    assert record["err_max"] == pytest.approx(error, rel=0.01)


def test_reconfigured_arrays_run_and_fmpy_says_why_not(state_space, tmp_path):
    problem = FmuProblem(path=state_space, score="x[3]+y[2]", **THREE)
    icls = registry.get_integrator("scipy-DOP853")
    system = convert(problem.formulate(), icls)
    sol = icls().solve(system, rtol=1e-10, atol=system.atol(1e-10))
    X, Y = _exact(problem, sol.t)
    assert _error(system.output(sol.t, sol.y), np.column_stack([X, Y[:, 1:]])) < 1e-8
    with pytest.raises(Unsupported, match="fmpy sizes an FMU's arrays by its structural "
                                          "parameters' start values, and this problem "
                                          "changes n=3, r=2"):
        convert(problem.formulate(), registry.get_integrator("fmpy-cvode"))


def _ibench(*args, tmp_path):
    env = {**os.environ, "IBENCH_DATA_DIR": str(tmp_path / "data"),
           "IBENCH_REFERENCE_DIR": str(tmp_path / "data" / "reference")}
    return subprocess.run([*IBENCH, *args], capture_output=True, text=True, timeout=600,
                          env=env, cwd=tmp_path)


def test_run_and_advise_from_the_command_line(state_space, tmp_path):
    spec = f"fmu:path={state_space},n=3,A[3][3]=-1,start.x[3]=2"
    run = _ibench("run", "--json", "-p", spec, "-i", "scipy-RK45", "-i", "fmpy-cvode",
                  "--rtol", "1e-4", tmp_path=tmp_path)
    assert run.returncode == 0, run.stderr
    records = {r["integrator"]: r for r in map(json.loads, run.stdout.splitlines())}
    assert records["scipy-RK45"]["status"] == CaseStatus.OK
    assert records["fmpy-cvode"]["status"] == CaseStatus.UNSUPPORTED
    advice = _ibench("advise", "--json", "-p", f"fmu:path={state_space}", "--target", "1e-4",
                     "-i", "scipy-RK45", "-i", "cvode-bdf", "--perturbed", "0",
                     "--out", str(tmp_path / "advice"), tmp_path=tmp_path)
    assert advice.returncode == 0, advice.stderr
    answer = json.loads(advice.stdout)
    assert answer["status"] == "answer" and answer["winner"]["run"]["error"] <= 1e-4
