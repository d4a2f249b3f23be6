"""FMI 2.0 model-exchange FMUs of native problems, built from C sources.

Each FMU is built once per module (gcc and cmake through fmpy's build support)
and checked against its native problem: model description, initial state,
right-hand side, Jacobian (directional derivatives), FMU state, the impact
law, and a whole run of ``fmpy.simulate_fmu`` against the exact solution or a
tight scipy solution.
"""

from ctypes import POINTER, c_double

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import fmpy
from fmpy import read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Model
from fmpy.validation import validate_fmu

from integrator_bench.problems import fmu_build
from integrator_bench.problems.bouncing_ball import BouncingBall
from integrator_bench.problems.spring_pendulum import SpringPendulum
from integrator_bench.problems.two_mass import TwoMass

NATIVE = {"spring_pendulum": SpringPendulum, "two_mass": TwoMass,
          "bouncing_ball": BouncingBall}
#: Parameters other than the defaults, to see that they reach the equations.
OTHER_PARAMS = {"spring_pendulum": {"k": 1000.0},
                "two_mass": {"k1": 7.0, "c1": 0.3, "k2": 500.0, "c2": 1000.0},
                "bouncing_ball": {"h0": 2.0, "g": 3.7, "e": 0.6}}


@pytest.fixture(scope="module")
def fmus(built_fmus, tmp_path_factory):
    """model -> (fmu path, extracted folder)."""
    out = tmp_path_factory.mktemp("fmus_x")
    return {model: (path, fmpy.extract(str(path), unzipdir=str(out / model)))
            for model, path in built_fmus.items()}


def _open(fmus, model, params=None, t0=0.0):
    """An instance in continuous-time mode after initialization."""
    path, unzipdir = fmus[model]
    md = read_model_description(str(path))
    fmu = FMU2Model(guid=md.guid, unzipDirectory=unzipdir,
                    modelIdentifier=md.modelExchange.modelIdentifier, instanceName="t")
    fmu.instantiate()
    fmu.setupExperiment(startTime=t0)
    vrs = {v.name: v.valueReference for v in md.modelVariables}
    fmu.enterInitializationMode()
    for name, value in (params or {}).items():
        fmu.setReal([vrs[name]], [value])
    fmu.exitInitializationMode()
    info = fmu.newDiscreteStates()
    assert not info[3]                               # valuesOfContinuousStatesChanged
    fmu.enterContinuousTimeMode()
    return fmu, md, vrs


def _get(method, n):
    """Call one of FMU2Model's array getters (getContinuousStates, getDerivatives,
    ...), which take a ctypes pointer and a length; returns the array."""
    out = np.zeros(n)
    method(out.ctypes.data_as(POINTER(c_double)), n)
    return out


def _set_x(fmu, x):
    x = np.ascontiguousarray(x, dtype=float)
    fmu.setContinuousStates(x.ctypes.data_as(POINTER(c_double)), x.size)


def _states(md):
    return [d.variable.derivative for d in md.derivatives]


def test_unknown_model_and_missing_tools(tmp_path, monkeypatch):
    with pytest.raises(ValueError, match=r"'pendulum'.*spring_pendulum, two_mass, bouncing_ball"):
        fmu_build.build_fmu("pendulum", tmp_path)
    monkeypatch.setenv("PATH", str(tmp_path))                # no cmake, no compiler
    with pytest.raises(RuntimeError, match="cmake is not installed"):
        fmu_build.build_fmu("two_mass", tmp_path)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("model", fmu_build.MODELS)
def test_valid_and_only_the_fmu_written(fmus, model):
    path, _ = fmus[model]
    assert validate_fmu(str(path)) == []
    assert sorted(p.name for p in path.parent.iterdir() if p.suffix == ".fmu") == \
        sorted(f"{m}.fmu" for m in fmu_build.MODELS)


@pytest.mark.parametrize("model", fmu_build.MODELS)
def test_model_description_mirrors_native(fmus, model):
    md = read_model_description(str(fmus[model][0]))
    native = NATIVE[model]()
    assert md.modelExchange.modelIdentifier == model and md.coSimulation is None
    states = _states(md)
    assert tuple(s.name for s in states) == native.components
    assert [d.variable.name for d in md.derivatives] == [f"der({c})" for c in native.components]
    assert all(float(s.nominal) == native.atol_scale for s in states)
    params = {v.name: float(v.start) for v in md.modelVariables if v.causality == "parameter"}
    assert params == {p.name: p.default for p in native.parameters if p.name != "t_end"}
    ex = md.defaultExperiment
    assert (float(ex.startTime), float(ex.stopTime)) == tuple(native.t_span)
    assert ex.tolerance is not None
    assert md.modelExchange.providesDirectionalDerivative == (model != "bouncing_ball")
    assert md.numberOfEventIndicators == (1 if model == "bouncing_ball" else 0)
    assert md.modelExchange.canGetAndSetFMUstate


@pytest.mark.parametrize("model", fmu_build.MODELS)
@pytest.mark.parametrize("use_defaults", [True, False])
def test_initial_state_and_rhs_equal_native(fmus, model, use_defaults):
    params = {} if use_defaults else OTHER_PARAMS[model]
    native = NATIVE[model](**params)
    fmu, md, _ = _open(fmus, model, params)
    N = md.numberOfContinuousStates
    try:
        np.testing.assert_array_equal(_get(fmu.getContinuousStates, N), native.initial_state())
        rng = np.random.default_rng(7)
        for _ in range(5):
            t = rng.uniform(0.0, 10.0)
            y = native.initial_state() + rng.normal(size=len(native.components))
            fmu.setTime(t)
            _set_x(fmu, y)
            np.testing.assert_allclose(_get(fmu.getDerivatives, N), native.rhs(t, y),
                                       rtol=1e-13, atol=1e-12)
        np.testing.assert_array_equal(_get(fmu.getNominalsOfContinuousStates, N),
                                      np.full(len(native.components), native.atol_scale))
    finally:
        fmu.terminate()
        fmu.freeInstance()


@pytest.mark.parametrize("model", ["spring_pendulum", "two_mass"])
def test_directional_derivatives(fmus, model):
    params = OTHER_PARAMS[model]
    native = NATIVE[model](**params)
    fmu, md, vrs = _open(fmus, model, params)
    x_ref = [vrs[c] for c in native.components]
    dx_ref = [vrs[f"der({c})"] for c in native.components]
    n = N = len(x_ref)
    try:
        t, y = 1.3, native.initial_state() + np.array([0.2, -0.3, 0.5, -0.7])
        fmu.setTime(t)
        _set_x(fmu, y)
        J = np.column_stack([fmu.getDirectionalDerivative(dx_ref, x_ref, np.eye(n)[j])
                             for j in range(n)])
        fd = np.empty((n, n))
        for j in range(n):
            h = 1e-6 * max(1.0, abs(y[j]))
            cols = []
            for s in (1.0, -1.0):
                _set_x(fmu, y + s * h * np.eye(n)[j])
                cols.append(_get(fmu.getDerivatives, N))
            fd[:, j] = (cols[0] - cols[1]) / (2 * h)
        scale = np.abs(J).max()
        np.testing.assert_allclose(J, fd, rtol=1e-6, atol=1e-7 * scale)
        np.testing.assert_allclose(J, native.jac(t, y), rtol=1e-13, atol=1e-13 * scale)
        # several knowns at once: J @ dv; a state as unknown: the identity
        dv = np.array([0.3, -1.0, 2.0, 0.5])
        _set_x(fmu, y)
        np.testing.assert_allclose(fmu.getDirectionalDerivative(dx_ref, x_ref, dv), J @ dv,
                                   rtol=1e-13, atol=1e-13 * scale)
        assert fmu.getDirectionalDerivative(x_ref[:1], x_ref, dv) == [dv[0]]
    finally:
        fmu.terminate()
        fmu.freeInstance()


def test_bouncing_ball_no_directional_derivatives_and_impact_law(fmus):
    fmu, md, vrs = _open(fmus, "bouncing_ball", {"e": 0.6})
    N = 2
    try:
        with pytest.raises(FMICallException):
            fmu.getDirectionalDerivative([vrs["der(v)"]], [vrs["v"]], [1.0])
        cases = [((1e-14, -2.0), True, (1e-14, 1.2)),      # located a hair before y = 0
                 ((-1e-12, -2.0), True, (-1e-12, 1.2)),    # a hair after
                 ((-1e-12, 1.2), False, (-1e-12, 1.2)),    # rising crossing: nothing
                 ((0.5, -2.0), False, (0.5, -2.0))]        # in flight: nothing
        for y, changed, after in cases:
            _set_x(fmu, np.array(y))
            assert _get(fmu.getEventIndicators, 1).tolist() == [y[0]]
            fmu.enterEventMode()
            info = fmu.newDiscreteStates()
            assert bool(info[3]) is changed and not info[0] and not info[4]
            assert _get(fmu.getContinuousStates, N).tolist() == list(after)
            fmu.enterContinuousTimeMode()
    finally:
        fmu.terminate()
        fmu.freeInstance()


@pytest.mark.parametrize("model", fmu_build.MODELS)
def test_fmu_state_round_trip(fmus, model):
    fmu, md, _ = _open(fmus, model)
    N = md.numberOfContinuousStates
    try:
        fmu.setTime(0.7)
        x0 = _get(fmu.getContinuousStates, N)
        dx0 = _get(fmu.getDerivatives, N)
        state = fmu.getFMUstate()
        fmu.setTime(2.1)
        _set_x(fmu, x0 + 0.25)
        assert np.any(_get(fmu.getDerivatives, N) != dx0)
        fmu.setFMUstate(state)
        np.testing.assert_array_equal(_get(fmu.getContinuousStates, N), x0)
        np.testing.assert_array_equal(_get(fmu.getDerivatives, N), dx0)
        fmu.freeFMUstate(state)
    finally:
        fmu.terminate()
        fmu.freeInstance()


def _simulate(fmus, model, params=None, **kw):
    return simulate_fmu(str(fmus[model][0]), fmi_type="ModelExchange", relative_tolerance=1e-8,
                        start_values=params or {}, **kw)


def test_simulate_spring_pendulum(fmus):
    res = _simulate(fmus, "spring_pendulum", output_interval=0.1)
    t = res["time"]
    assert t[-1] == pytest.approx(10.0)

    def tight(k):
        p = SpringPendulum(k=k)
        return solve_ivp(p.rhs, p.t_span, p.initial_state(), method="DOP853",
                         rtol=1e-12, atol=1e-12, t_eval=t).y.T

    ref = tight(100.0)
    err = np.abs(np.column_stack([res[c] for c in SpringPendulum.components]) - ref).max(axis=0)
    tol = np.array([1e-3, 1e-3, 1e-2, 1e-2])      # measured 3e-5 .. 3.4e-4 (fmpy's CVODE, BDF)
    assert np.all(err < tol), err
    # a wrong constant (k = 101) would be far outside the tolerance
    assert np.all(np.abs(tight(101.0) - ref).max(axis=0) > 20 * tol)


@pytest.mark.parametrize("c2", [0.1, 1000.0])
def test_simulate_two_mass_against_exact(fmus, c2):
    res = _simulate(fmus, "two_mass", {"c2": c2}, output_interval=0.1)
    native = TwoMass(c2=c2)
    t = res["time"]
    assert t[-1] == pytest.approx(10.0)
    exact = native.exact(t)
    err = np.abs(np.column_stack([res[c] for c in native.components]) - exact).max(axis=0)
    tol = np.array([3e-5, 3e-5, 3e-3, 3e-3])      # measured <= 3e-6 (x), 4e-4 (v)
    assert np.all(err < tol), err
    # a wrong constant (k1 = 11) would be far outside the tolerance
    wrong = TwoMass(c2=c2, k1=11.0).exact(t)
    assert np.all(np.abs(wrong - exact).max(axis=0) > 20 * tol)


@pytest.mark.parametrize("params, stop", [({}, None), ({"h0": 2.0, "e": 0.9}, 3.4)])
def test_simulate_bouncing_ball_impacts(fmus, params, stop):
    native = BouncingBall(**params)
    res = _simulate(fmus, "bouncing_ball", params, stop_time=stop, output_interval=0.01,
                    record_events=True)
    t, v = np.asarray(res["time"], float), np.asarray(res["v"], float)
    assert t[-1] == pytest.approx(3.4)
    # fmpy records a row before and one after each event. Besides the impacts
    # (v changes sign) CVODE reports the rising crossing of a ball reset a hair
    # below the floor, where the FMU must change nothing.
    events = np.unique(t[:-1][np.diff(t) == 0])
    jumps = np.array([v[t == tk].min() < 0 < v[t == tk].max() for tk in events], bool)
    assert all(np.ptp(v[t == tk]) == 0 for tk in events[~jumps])
    event_times = events[jumps]
    impacts = native.impact_times()
    assert len(event_times) == len(impacts) == (3 if params else 8)
    v1 = native.params["g"] * native.first_impact()
    e = native.params["e"]
    for k, tk in enumerate(event_times):
        at = v[t == tk]
        np.testing.assert_allclose([at.min(), at.max()], [-v1 * e**k, v1 * e**(k + 1)],
                                   rtol=1e-6)
    np.testing.assert_allclose(np.asarray(res["y"], float), native.exact(t)[:, 0], atol=1e-5)
    assert res["y"][0] == native.params["h0"]
