"""The advice's reproduction recipe (``certificate.reproduction``, from each
integrator's ``library_call``) followed to the letter with the plain library, one
code of each library, on the problem's own right-hand side: the error the harness
recorded for the same case, to a tight relative tolerance.

The cases are cheap: the two-mass oscillator over its 10 s at rtol 1e-5, one
solve each, against its committed (exact) reference."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from integrator_bench.harness.advise import certificate, page
from integrator_bench.harness.advise.candidates import Candidate
from integrator_bench.harness.measure import references
from integrator_bench.harness.measure.metrics import mixed_max
from integrator_bench.harness.matrix import registry
from integrator_bench.harness.paths import REFERENCE_DIR
from integrator_bench.harness.run.execution import execute
from integrator_bench.integrators import library_call

PROBLEM, RTOL = "two_mass", 1e-5


def _case(integrator, **settings):
    """``(system, record, recipe)``: the harness's record of the case, the recipe of
    the same line at the same rtol, and the problem's own system (its ``fun`` and
    ``jac``, not the harness's counted copy)."""
    problem = registry.get_problem_class(PROBLEM)()
    line = Candidate("ode", integrator, tuple(sorted(settings.items())))
    record = execute(line.case(problem, RTOL), reference_dir=REFERENCE_DIR, repeat=1)
    assert record["status"] == "ok", record["message"]
    recipe = certificate.reproduction(problem, line, RTOL)
    system = problem.formulate(recipe.formulation)
    call = recipe.library_call
    assert call is not None and call["function"] == "system.fun"
    # tolerances per state, the output times: as the recipe states them
    np.testing.assert_array_equal(call["options"]["atol"], RTOL * np.array(recipe.atol_scale))
    assert call["options"]["rtol"] == RTOL == recipe.rtol
    assert recipe.output_times.count == len(system.t_eval)
    text = "\n".join(page.reproduce_lines(recipe))
    assert call["call"] in text and all(f"{k}=" in text for k in call["options"])
    return problem, system, record, recipe


def _options(options: dict, functions: dict) -> dict:
    """The recipe's options for the library: a function named by the system's
    (``"system.jac"``) as ``functions`` write it for the library, a list as an array."""
    return {k: functions[v] if isinstance(v, str) and v in functions
            else np.array(v) if isinstance(v, list) else v for k, v in options.items()}


def _error(problem, t, Y) -> float:
    """The mixed error the harness records (``err_max``) of ``Y`` at ``t``."""
    ref = references.load(problem, REFERENCE_DIR, compute_missing=False)
    np.testing.assert_allclose(t, ref.t, rtol=0, atol=1e-12)
    idx = problem.component_index(problem.error_components)
    return mixed_max(np.asarray(Y)[:, idx], ref.Y[:, idx], problem.atol_scale_vector()[idx])


def test_scipy_recipe_gives_the_recorded_error():
    problem, system, record, recipe = _case("scipy-Radau")
    call = recipe.library_call
    assert call["jacobian"] == library_call.ANALYTIC and call["options"]["jac"] == "system.jac"
    options = _options(call["options"], {"system.jac": system.jac})
    res = solve_ivp(system.fun, (system.t0, system.t_end), system.y0, method=call["method"],
                    t_eval=system.t_eval, **options)
    assert res.success
    got = _error(problem, res.t, system.output(res.t, res.y.T))
    assert got == pytest.approx(record["err_max"], rel=1e-9)


def test_sundials_recipe_gives_the_recorded_error():
    from sksundae import cvode
    problem, system, record, recipe = _case("cvode-bdf", max_order=4)
    call = recipe.library_call
    assert call["method"] == "BDF" and call["options"]["linsolver"] == "dense"
    assert call["options"]["max_order"] == 4 and call["jacobian"] == library_call.ANALYTIC

    def rhsfn(t, y, yp):
        yp[:] = system.fun(t, y)

    def jacfn(t, y, yp, JJ):
        JJ[:, :] = system.jac(t, y)

    options = _options(call["options"], {"system.jac": jacfn})
    res = cvode.CVODE(rhsfn, **options).solve(system.t_eval, system.y0)
    assert res.success
    got = _error(problem, res.t, system.output(res.t, res.y))
    assert got == pytest.approx(record["err_max"], rel=1e-9)


def test_assimulo_recipe_gives_the_recorded_error():
    pytest.importorskip("assimulo")
    from assimulo import solvers
    from assimulo.problem import Explicit_Problem
    problem, system, record, recipe = _case("assimulo-cvode-bdf")
    call = recipe.library_call
    # the one-step mode the counted solve needs, which changes CVODE's steps
    assert call["options"]["report_continuously"] is True
    assert call["jacobian"] == library_call.ANALYTIC and call["options"]["usejac"] is True
    model = Explicit_Problem(system.fun, system.y0, system.t0)
    model.jac = lambda t, y: np.ascontiguousarray(system.jac(t, y))
    solver = getattr(solvers, call["method"])(model)
    for name, value in _options(call["options"], {}).items():
        setattr(solver, name, value)
    t, y = solver.simulate(system.t_end, ncp_list=system.t_eval)[:2]
    got = _error(problem, np.asarray(t), system.output(np.asarray(t), np.asarray(y)))
    assert got == pytest.approx(record["err_max"], rel=1e-9)


def test_a_code_of_this_project_has_no_library_call():
    """An integrator implemented here (the shared driver's) is reproduced by its
    name and settings: the recipe says so, with the Jacobian's source."""
    problem = registry.get_problem_class(PROBLEM)()
    recipe = certificate.reproduction(problem, Candidate("ode", "rk4"), RTOL)
    assert recipe.library_call is None and recipe.jacobian == library_call.NONE


def test_fmpy_recipe_gives_the_recorded_error(built_fmus, tmp_path):
    """fmpy's CVode on an FMU (the project's two-mass FMU, its stiff spring softened
    so that its reference takes seconds): ``simulate_fmu`` called with the recipe's
    options and the FMU file gives the error the harness recorded."""
    fmpy = pytest.importorskip("fmpy")
    from integrator_bench.problems.fmu import FmuProblem

    native = registry.get_problem_class("two_mass")(k2=100.0)
    problem = FmuProblem(path=str(built_fmus["two_mass"]), k2=100.0,
                         score="+".join(native.error_components))
    references.load(problem, tmp_path)          # computed here, never in results/
    line = Candidate("ode", "fmpy-cvode")
    record = execute(line.case(problem, RTOL), reference_dir=tmp_path, repeat=1)
    assert record["status"] == "ok", record["message"]
    recipe = certificate.reproduction(problem, line, RTOL)
    call = recipe.library_call
    assert call["jacobian"] == library_call.DIFFERENCES
    options = {k: v for k, v in call["options"].items() if k != "filename"}
    assert options["relative_tolerance"] == RTOL and options["solver"] == call["method"]
    result = fmpy.simulate_fmu(str(built_fmus["two_mass"]), **options)
    # fmpy records a row at each output time, and one more at each event: none here
    t = result["time"]
    Y = np.column_stack([result[name] for name in recipe.variables])
    ref = references.load(problem, tmp_path, compute_missing=False)
    np.testing.assert_allclose(t, ref.t, rtol=0, atol=1e-12)
    idx = problem.component_index(problem.error_components)
    got = mixed_max(Y[:, idx], ref.Y[:, idx], problem.atol_scale_vector()[idx])
    assert got == pytest.approx(record["err_max"], rel=1e-9)


def test_radau5_on_a_dae_states_its_index_counts_beyond_assimulos_options():
    """RADAU5 on an index-3 DAE is given IWORK(5..7), which Assimulo's Radau5DAE has no
    option for: the recipe names them, with the values the solve sets."""
    pytest.importorskip("assimulo")
    from integrator_bench.integrators.assimulo_radau5 import _index_counts

    problem = registry.get_problem_class("pendulum")()
    recipe = certificate.reproduction(problem, Candidate("i3", "assimulo-radau5"), RTOL)
    system = problem.formulate("i3")
    n1, n2, n3 = _index_counts(system)
    assert (n1, n2, n3) == (int(np.sum(system.var_index == 1)),
                            int(np.sum(system.var_index == 2)),
                            int(np.sum(system.var_index == 3)) + system.n)
    (line,) = recipe.library_call["beyond_options"]
    assert "IWORK(5), IWORK(6), IWORK(7)" in line and f"= {n1}, {n2}, {n3}" in line
    assert f"  beyond the options: {line}" in page.reproduce_lines(recipe)
    ode = certificate.reproduction(problem, Candidate("ode", "assimulo-radau5"), RTOL)
    assert "beyond_options" not in ode.library_call
