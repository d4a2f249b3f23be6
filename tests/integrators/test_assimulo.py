"""Assimulo's solvers (integrators/assimulo.py): cross-checks against scikit-sundae's
SUNDIALS and the committed references, their counters, typed failures, silence, the
refusal of large sparse systems, and their absence without the package.

The registry-parametrized suites (test_integrators_classical, test_events,
test_verify) pick these integrators up by what they declare.
"""

import builtins
import sys
import warnings

import numpy as np
import pytest
import scipy.sparse as sp

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.cases import expand
from integrator_bench.harness.run.execution import execute
from integrator_bench.integrators.base import Status
from integrator_bench.integrators.sparse import DENSE_LIMIT
from integrator_bench.problems.system import OdeSystem, convert

assimulo = pytest.importorskip("integrator_bench.integrators.assimulo")
from integrator_bench.integrators import assimulo_radau5  # noqa: E402

NAMES = sorted(n for n in registry.integrators() if n.startswith("assimulo-"))


def records(problem, formulation, integrators, rtol):
    cases = expand(problems=[problem], formulations=[formulation], integrators=integrators,
                   rtols=[rtol])
    return {c.integrator: execute(c) for c in cases}


def test_every_solver_of_the_issue_is_registered():
    assert NAMES == ["assimulo-cvode-adams", "assimulo-cvode-bdf", "assimulo-dopri5",
                     "assimulo-ida", "assimulo-lsodar", "assimulo-radau5", "assimulo-rk34",
                     "assimulo-rodas"]


@pytest.mark.parametrize("problem", ["spring_pendulum", "two_mass"])
def test_cvode_bdf_matches_scikit_sundae_within_a_few_per_cent(problem):
    """Same method (CVODE BDF, Newton, dense LU; SUNDIALS 2.7 in Assimulo, 7.9 in
    scikit-sundae), same defaults: the work agrees."""
    rec = records(problem, "ode", ["cvode-bdf", "assimulo-cvode-bdf"], 1e-6)
    ours, theirs = rec["assimulo-cvode-bdf"], rec["cvode-bdf"]
    assert ours["status"] == theirs["status"] == "ok"
    assert abs(ours["nfev"] - theirs["nfev"]) <= 0.05 * theirs["nfev"]
    assert abs(ours["scd"] - theirs["scd"]) <= 0.3
    assert ours["count_mismatch"] is None
    for key in ("nsteps", "nreject", "nniter", "nnfail", "njev"):
        assert ours[key] is not None, key


def test_ida_suppress_alg_on_the_squeezer_i3_beats_the_large_atol():
    """IDASetSuppressAlg keeps the index-3 variables in the Newton test: more digits than
    scikit-sundae's emulation by atol 1e10 (2.3 at rtol 1e-6)."""
    rec = records("squeezer", "i3", ["ida", "assimulo-ida"], 1e-6)
    ours, theirs = rec["assimulo-ida"], rec["ida"]
    assert ours["status"] == "ok" and theirs["status"] == "ok"
    assert ours["scd"] >= 2.8 and ours["scd"] >= theirs["scd"] + 0.5
    assert all(ours[k] is not None for k in ("nreject", "nniter", "nnfail"))


@pytest.mark.parametrize("formulation, digits", [("i3", 3.0), ("ggl", 5.5)])
def test_radau5_on_the_squeezer_against_the_reference(formulation, digits):
    rec = records("squeezer", formulation, ["assimulo-radau5"], 1e-6)["assimulo-radau5"]
    assert rec["status"] == "ok", rec["message"]
    assert rec["scd"] >= digits
    assert all(rec[k] is not None for k in ("nreject", "nniter", "nnfail", "nlu", "njev"))
    assert rec["count_mismatch"] is None


def test_radau5_without_the_index_counts_fails_on_i3():
    """The reason for IWORK(5..7): Assimulo's own Radau5DAE (every y of index 1, every
    z of index 2) gives up on the squeezer's index-3 form (step size too small at
    t = 0.0078, RADAU5's IDID -3, typed as such)."""
    from integrator_bench.problems.models.squeezer import Squeezer

    system = Squeezer().formulate("i3")
    atol = system.atol(1e-6)
    indexed = assimulo_radau5.Radau5().solve(system, rtol=1e-6, atol=atol)

    class Plain(assimulo_radau5.Radau5):
        def make_solver(self, system, problem):
            return assimulo_radau5.solvers.Radau5DAE(problem)

    plain = Plain().solve(system, rtol=1e-6, atol=atol)
    assert indexed.success and indexed.t[-1] == system.t_end
    assert plain.status is Status.STEP_SIZE_UNDERFLOW and plain.t[-1] < 0.01


def test_a_library_failure_is_typed_from_its_flag():
    """IDA on the squeezer's GGL form from the first step its own rule takes
    (3e-11 s): Newton failures at t = 0 (IDA_CONV_FAIL, -4), typed; the wrapper's
    second start from 1e-3 of the span runs, with both starts counted."""
    from integrator_bench.problems.models.squeezer import Squeezer

    system = Squeezer().formulate("ggl")
    atol = system.atol(1e-6)
    sol = assimulo.IDA(first_step=3e-11).solve(system, rtol=1e-6, atol=atol)
    assert sol.status is Status.NEWTON_FAILURE and "IDAError" in sol.message
    assert sol.t.size == 1
    direct = assimulo.IDA(first_step=3e-5).solve(system, rtol=1e-6, atol=atol)
    again = assimulo.IDA().solve(system, rtol=1e-6, atol=atol)
    assert direct.success and again.success
    assert again.counts["nsteps"] == direct.counts["nsteps"]
    assert again.counts["nfev"] > direct.counts["nfev"]


@pytest.mark.parametrize("formulation", ["i3", "ggl"])
def test_the_issues_command_gives_filled_counters(formulation):
    """``ibench run -p squeezer -f i3 -f ggl -i assimulo-radau5 -i assimulo-ida --rtol 1e-6``."""
    rec = records("squeezer", formulation, ["assimulo-radau5", "assimulo-ida"], 1e-6)
    for r in rec.values():
        assert r["status"] == "ok", r["message"]
        assert all(r[k] is not None for k in ("nreject", "nniter", "nnfail")), r


@pytest.mark.parametrize("name", NAMES)
def test_solvers_print_nothing(name, capfd):
    system = OdeSystem(t0=0.0, t_end=1.0, y0=[1.0, 0.0], t_eval=np.linspace(0, 1, 5),
                       atol_scale=1.0, fun=lambda t, y: np.array([y[1], -y[0]]),
                       jac=lambda t, y: np.array([[0.0, 1.0], [-1.0, 0.0]]))
    from integrator_bench.problems.system import convert

    cls = registry.integrators()[name]
    s = convert(system, cls)
    sol = cls().solve(s, rtol=1e-6, atol=s.atol(1e-6))
    out, _ = capfd.readouterr()
    assert sol.success and out == ""
    assert abs(sol.y[-1, 0] - np.cos(1.0)) < 1e-4


@pytest.mark.parametrize("name", [n for n in NAMES
                                  if registry.integrators()[n].uses_jacobian])
def test_a_large_sparse_system_is_declined_not_densified(name):
    n = DENSE_LIMIT + 1
    system = OdeSystem(t0=0.0, t_end=1.0, y0=np.ones(n), t_eval=np.linspace(0, 1, 3),
                       atol_scale=1.0, fun=lambda t, y: -y,
                       jac=lambda t, y: -sp.identity(n, format="csc"),
                       jac_sparsity=sp.identity(n, format="csc"))
    cls = registry.integrators()[name]
    s = system if "ode" in cls.accepts else system.as_dae()
    sol = cls().solve(s, rtol=1e-6, atol=s.atol(1e-6))
    assert sol.status is Status.METHOD_LIMIT and str(DENSE_LIMIT) in sol.message


@pytest.mark.parametrize("name", NAMES)
def test_every_declared_setting_is_an_option_of_the_solver(name):
    """A setting Assimulo's solver does not have would be set as a plain attribute
    and ignored without a word (RungeKutta34 has no ``maxh``, LSODAR no ``inith``):
    each declared one must name an option of the solver it configures."""
    cls = registry.integrators()[name]
    system = OdeSystem(t0=0.0, t_end=1.0, y0=np.ones(2), t_eval=np.linspace(0, 1, 3),
                       atol_scale=1.0, fun=lambda t, y: -y)
    for kind in [k for k in ("ode", "dae") if k in cls.accepts]:
        s = system if kind == "ode" else system.as_dae()
        solver = cls().library_solver(s, 1e-6, s.atol(1e-6))
        for setting in cls.settings:
            assert assimulo.ASSIMULO_OPTIONS[setting.name] in solver.options, (kind, setting.name)


@pytest.mark.parametrize("name", [n for n in NAMES
                                  if registry.integrators()[n].uses_jacobian])
def test_the_plain_solver_takes_a_sparse_jacobian(name):
    """``library_solver``, the plain call studies/fidelity.py times, hands a CSC
    Jacobian over densified in C order (IDA's callback refused the Fortran-ordered
    dense copy)."""
    n = 5
    A = (sp.eye(n, k=1) - sp.identity(n)).tocsc()    # its dense copy is in Fortran order
    system = OdeSystem(t0=0.0, t_end=1.0, y0=np.ones(n), t_eval=np.linspace(0, 1, 3),
                       atol_scale=1.0, fun=lambda t, y: A @ y, jac=lambda t, y: A,
                       jac_sparsity=A != 0)
    cls = registry.integrators()[name]
    s = system if "ode" in cls.accepts else system.as_dae()
    t, y = cls().library_solver(s, 1e-6, s.atol(1e-6)).simulate(s.t_end, ncp_list=s.t_eval)[:2]
    assert np.isclose(t[-1], 1.0) and np.all(np.isfinite(y))


def test_without_the_package_the_integrators_are_absent_and_one_line_says_why(monkeypatch):
    real = builtins.__import__

    def no_assimulo(name, *args, **kwargs):
        if name == "assimulo" or name.startswith("assimulo."):
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)
        return real(name, *args, **kwargs)

    before = set(registry.integrators())
    monkeypatch.setattr(builtins, "__import__", no_assimulo)
    for module in ("assimulo", "assimulo_radau5"):
        monkeypatch.delitem(sys.modules, f"integrator_bench.integrators.{module}")
    registry.refresh()
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            names = set(registry.integrators())
        lines = [str(w.message) for w in caught if issubclass(w.category,
                                                              registry.RegistryWarning)]
        assert names == before - set(NAMES)
        assert registry.absent() == {name: "assimulo" for name in NAMES}
        assert len(lines) == 1 and "\n" not in lines[0]
        assert all(name in lines[0] for name in NAMES)
        assert "'assimulo'" in lines[0] and "integrator-bench[assimulo]" in lines[0]
    finally:
        monkeypatch.undo()
        registry.refresh()
    assert set(registry.integrators()) == before and registry.absent() == {}


def test_seed_002s_runs_are_reproduced_to_the_step():
    """studies/seed002_assimulo.py's two rows that the report's numbers pin down:
    CVODE Adams on the spring pendulum (its Table 3) and IDA with algvar on the
    index-2 squeezer with difference-quotient Jacobians (its Table 5)."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "studies" / "seed002_assimulo.py"
    spec = importlib.util.spec_from_file_location("seed002_assimulo", path)
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    rows = [row for row in script.ROWS
            if row[0].startswith(("Table 3: CVODE", "Table 5: index 2, algvar"))]
    (_, _, adams), (_, _, ida) = script.run(rows)
    assert (adams["nsteps"], script._own_f(adams)) == (1007, 1227)
    assert (ida["nsteps"], script._own_f(ida), ida["njev"], ida["nnfail"]) == (617, 1613, 120, 0)
    assert "assimulo-ida-fd" not in registry.integrators()      # the variants unregistered
    assert "| Table 3: CVODE (Adams) | 1007 steps, 1227 f | ok | 1007 | 1227 |" in \
        script.table([("Table 3: CVODE (Adams)", "1007 steps, 1227 f", adams)])


class ModelFault(Exception):
    pass


@pytest.mark.parametrize("name", ["assimulo-cvode-bdf", "assimulo-radau5", "assimulo-dopri5",
                                  "assimulo-lsodar", "assimulo-rodas"])
def test_the_models_own_exception_comes_through(name):
    """An exception in the model's right-hand side ends the solve as that exception
    (the harness records ``error``/``exception``), not as the solver error Assimulo
    wraps it in."""
    def fun(t, y):
        if t > 0.3:
            raise ModelFault("deliberate")
        return -y

    system = OdeSystem(t0=0.0, t_end=1.0, y0=np.ones(2), t_eval=np.linspace(0, 1, 11),
                       atol_scale=1.0, fun=fun, jac=lambda t, y: -np.eye(2))
    with pytest.raises(ModelFault):
        registry.integrators()[name]().solve(system, rtol=1e-6, atol=system.atol(1e-6))


def test_rodas_on_a_nan_right_hand_side_ends_instead_of_looping():
    """RODAS accepts a NaN error estimate and loops inside its Fortran code: the
    wrapper ends the run at the model's first non-finite value."""
    system = OdeSystem(t0=0.0, t_end=1.0, y0=np.ones(1), t_eval=np.linspace(0, 1, 11),
                       atol_scale=1.0, fun=lambda t, y: -y if t < 0.3 else np.full(1, np.nan),
                       jac=lambda t, y: -np.eye(1))
    sol = registry.integrators()["assimulo-rodas"]().solve(system, rtol=1e-6,
                                                           atol=system.atol(1e-6))
    assert sol.status is Status.NONFINITE_STATE and 0.2 <= sol.t[-1] <= 0.3


@pytest.mark.parametrize("name", ["assimulo-rodas", "assimulo-dopri5"])
def test_hairer_codes_flag_in_the_message_is_typed(name):
    """RODAS and DOPRI5 raise a plain Exception naming their IDID: -3 (step size
    too small) is a step-size underflow, on the blow-up of y' = y^2."""
    system = OdeSystem(t0=0.0, t_end=2.0, y0=np.ones(1), t_eval=np.linspace(0, 2, 11),
                       atol_scale=1.0, fun=lambda t, y: y * y, jac=lambda t, y: 2 * y[None, :])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sol = registry.integrators()[name]().solve(system, rtol=1e-6, atol=system.atol(1e-6))
    assert sol.status is Status.STEP_SIZE_UNDERFLOW and "flag -3" in sol.message


@pytest.mark.parametrize("name", NAMES)
def test_a_run_short_of_t_end_is_the_codes_failure_in_both_solves(name):
    """``ibench run -p flyball -f ode -i assimulo-rk34 --rtol 1e-3``: RungeKutta34
    accepts every step (it has no rejection), so on the stiff flyball governor its
    step size collapses until it turns NaN; its loop then ends at t = NaN and
    ``simulate`` returns as if complete, with the start as its only output. That is
    the code's own failure, typed (``nonfinite_state``), in the record and in both
    solves alike, never the harness's ``error`` ("solution times do not match the
    output times"). Every Assimulo code that runs the case: a successful solve has
    every output time, a failed one the output times it reached."""
    (case,) = expand(problems=["flyball"], formulations=["ode"], integrators=[name],
                     rtols=[1e-3])
    record = execute(case)
    assert record["status"] in ("ok", "failed"), record["message"]
    if record["status"] == "failed":
        assert Status(record["reason"]) is not Status.SUCCESS
    icls = registry.integrators()[name]
    system = convert(registry.get_problem_class("flyball")().formulate("ode"), icls)
    atol = system.atol(1e-3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        timed = icls().timed_solve(system, rtol=1e-3, atol=atol)
        counted = icls().solve(system, rtol=1e-3, atol=atol)
    assert timed.status is counted.status
    for sol in (timed, counted):
        n = len(sol.t)
        np.testing.assert_array_equal(sol.t, system.t_eval[:n])
        assert (n == system.t_eval.size) == (sol.status is Status.SUCCESS), sol.message
    if name == "assimulo-rk34":
        assert record["status"] == "failed" and record["reason"] == "nonfinite_state"
        assert timed.t.size == counted.t.size == 1 and timed.counts["nsteps"] > 0
