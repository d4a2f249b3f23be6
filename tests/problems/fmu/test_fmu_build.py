"""FMI 2.0 and FMI 3.0 model-exchange FMUs of native problems, built from C sources.

Each FMU is built once per module (gcc and cmake through fmpy's build support;
the FMI 2.0 ones once per session, tests/conftest.py ``built_fmus``) and
checked, for both FMI versions with the same test code, against its native
problem: model description, initial state, right-hand side, Jacobian
(directional derivatives), FMU state, the impact law, and a whole run of
``fmpy.simulate_fmu`` against the exact solution or a tight scipy solution;
and the computed output ``energy`` of spring_pendulum and bouncing_ball
(formula in every mode, gradient, conservation in a run).
"""

import zipfile
import xml.etree.ElementTree as ET
from ctypes import POINTER, c_double

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import fmpy
from fmpy import read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Model
from fmpy.fmi3 import FMU3Model
from fmpy.validation import validate_fmu

from integrator_bench.problems import fmu_build
from integrator_bench.problems.models.bouncing_ball import BouncingBall
from integrator_bench.problems.models.spring_pendulum import SpringPendulum
from integrator_bench.problems.models.two_mass import TwoMass

NATIVE = {"spring_pendulum": SpringPendulum, "two_mass": TwoMass,
          "bouncing_ball": BouncingBall}
#: Parameters other than the defaults, to see that they reach the equations.
OTHER_PARAMS = {"spring_pendulum": {"k": 1000.0},
                "two_mass": {"k1": 7.0, "c1": 0.3, "k2": 500.0, "c2": 1000.0},
                "bouncing_ball": {"h0": 2.0, "g": 3.7, "e": 0.6}}
VERSIONS = pytest.mark.parametrize("version", fmu_build.FMI_VERSIONS, ids=["fmi2", "fmi3"])


@pytest.fixture(scope="module")
def fmus(built_fmus, built_fmus3, tmp_path_factory):
    """FMI version -> model -> (fmu path, extracted folder)."""
    out = tmp_path_factory.mktemp("fmus_x")
    return {version: {model: (path, fmpy.extract(str(path),
                                                 unzipdir=str(out / f"{model}_{version}")))
                      for model, path in built.items()}
            for version, built in (("2.0", built_fmus), ("3.0", built_fmus3))}


def _open(fmus, version, model, params=None, t0=0.0):
    """An instance in continuous-time mode after initialization: FMI 2.0
    through FMU2Model, FMI 3.0 through FMU3Model."""
    path, unzipdir = fmus[version][model]
    md = read_model_description(str(path))
    cls = FMU2Model if version == "2.0" else FMU3Model
    fmu = cls(guid=md.guid, unzipDirectory=unzipdir,
              modelIdentifier=md.modelExchange.modelIdentifier, instanceName="t")
    fmu.instantiate()
    vrs = {v.name: v.valueReference for v in md.modelVariables}
    if version == "2.0":
        fmu.setupExperiment(startTime=t0)
        fmu.enterInitializationMode()
        for name, value in (params or {}).items():
            fmu.setReal([vrs[name]], [value])
    else:
        fmu.enterInitializationMode(startTime=t0)
        for name, value in (params or {}).items():
            fmu.setFloat64([vrs[name]], [value])
    fmu.exitInitializationMode()
    info = _update(fmu)
    assert not info[3]                               # valuesOfContinuousStatesChanged
    fmu.enterContinuousTimeMode()
    return fmu, md, vrs


def _update(fmu):
    """The event-mode update; both versions return (discrete states need an
    update, terminate, nominals changed, values of the continuous states
    changed, next event time defined, next event time)."""
    return fmu.newDiscreteStates() if isinstance(fmu, FMU2Model) else fmu.updateDiscreteStates()


def _derivatives(fmu):
    return (fmu.getDerivatives if isinstance(fmu, FMU2Model)
            else fmu.getContinuousStateDerivatives)


def _get(method, n):
    """Call one of the array getters (getContinuousStates, getDerivatives,
    ...), which take a ctypes pointer and a length; returns the array."""
    out = np.zeros(n)
    method(out.ctypes.data_as(POINTER(c_double)), n)
    return out


def _set_x(fmu, x):
    x = np.ascontiguousarray(x, dtype=float)
    fmu.setContinuousStates(x.ctypes.data_as(POINTER(c_double)), x.size)


def _states(md):
    return [d.variable.derivative for d in md.derivatives]


def _xml_root(path):
    with zipfile.ZipFile(path) as zf:
        return ET.fromstring(zf.read("modelDescription.xml"))


def test_unknown_model_and_missing_tools(tmp_path, monkeypatch):
    with pytest.raises(ValueError, match=r"'pendulum'.*spring_pendulum, two_mass, bouncing_ball"):
        fmu_build.build_fmu("pendulum", tmp_path)
    with pytest.raises(ValueError, match=r"FMI version '3'; valid choices: 2.0, 3.0"):
        fmu_build.build_fmu("two_mass", tmp_path, fmi_version="3")
    monkeypatch.setenv("PATH", str(tmp_path))        # no compiler; cmake from pip, beside Python
    with pytest.raises(RuntimeError, match="no C compiler"):
        fmu_build.build_fmu("two_mass", tmp_path)
    monkeypatch.setattr(fmu_build, "search_path", lambda: str(tmp_path))   # no cmake at all
    with pytest.raises(RuntimeError, match="cmake is not installed"):
        fmu_build.build_fmu("two_mass", tmp_path)
    with pytest.raises(RuntimeError, match="cmake is not installed"):
        fmu_build.build_fmu("two_mass", tmp_path, fmi_version="3.0")
    assert list(tmp_path.iterdir()) == []


@VERSIONS
@pytest.mark.parametrize("model", fmu_build.MODELS)
def test_valid_and_only_the_fmu_written(fmus, version, model):
    path, _ = fmus[version][model]
    assert validate_fmu(str(path)) == []
    suffix = "" if version == "2.0" else "_fmi3"
    assert sorted(p.name for p in path.parent.iterdir() if p.suffix == ".fmu") == \
        sorted(f"{m}{suffix}.fmu" for m in fmu_build.MODELS)
    platform = "linux64" if version == "2.0" else "x86_64-linux"
    with zipfile.ZipFile(path) as zf:
        names = set(zf.namelist())
    header = "fmu_common.h" if version == "2.0" else "fmu_common3.h"
    assert {f"binaries/{platform}/{model}.so", f"sources/{model}.c", f"sources/{header}",
            "sources/fmu_core.h",
            "modelDescription.xml"} <= names
    assert ("sources/buildDescription.xml" in names) == (version == "3.0")
    assert not any(n.startswith("modelDescription3") for n in names)


def test_both_versions_side_by_side(tmp_path):
    paths = [fmu_build.build_fmu("two_mass", tmp_path, fmi_version=v)
             for v in fmu_build.FMI_VERSIONS]
    assert [p.name for p in paths] == ["two_mass.fmu", "two_mass_fmi3.fmu"]
    assert [read_model_description(str(p)).fmiVersion for p in paths] == ["2.0", "3.0"]


@VERSIONS
def test_wrong_guid_is_refused(fmus, version):
    path, unzipdir = fmus[version]["two_mass"]
    cls = FMU2Model if version == "2.0" else FMU3Model
    fmu = cls(guid="{00000000-0000-0000-0000-000000000000}", unzipDirectory=unzipdir,
              modelIdentifier="two_mass", instanceName="t")
    with pytest.raises(Exception, match="Failed to instantiate"):
        fmu.instantiate()
    fmu.freeLibrary()


@VERSIONS
@pytest.mark.parametrize("model", fmu_build.MODELS)
def test_model_description_mirrors_native(fmus, version, model):
    path = fmus[version][model][0]
    md = read_model_description(str(path), validate_model_structure=True)
    native = NATIVE[model]()
    assert md.fmiVersion == version
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
    # fmpy 0.3.32 reads FMI 3.0's providesDirectionalDerivatives (plural) into
    # nothing, so the attribute is read from the XML here
    me = _xml_root(path).find("ModelExchange")
    attribute = "providesDirectionalDerivative" + ("s" if version == "3.0" else "")
    assert me.get(attribute) == ("false" if model == "bouncing_ball" else "true")
    assert md.numberOfEventIndicators == (1 if model == "bouncing_ball" else 0)
    assert md.modelExchange.canGetAndSetFMUstate
    assert all(v.type == ("Real" if version == "2.0" else "Float64") for v in md.modelVariables)
    if version == "3.0":
        assert md.guid == _xml_root(path).get("instantiationToken")
        assert all(v.variability == "fixed" for v in md.modelVariables
                   if v.causality == "parameter")
        assert [u.variable.name for u in md.eventIndicators] == \
            (["y"] if model == "bouncing_ball" else [])
        # same value references and names as the FMI 2.0 description
        md2 = read_model_description(str(fmus["2.0"][model][0]))
        assert [(v.name, v.valueReference, v.causality, v.start, v.nominal)
                for v in md.modelVariables] == \
            [(v.name, v.valueReference, v.causality, v.start, v.nominal)
             for v in md2.modelVariables]


@VERSIONS
@pytest.mark.parametrize("model", fmu_build.MODELS)
@pytest.mark.parametrize("use_defaults", [True, False])
def test_initial_state_and_rhs_equal_native(fmus, version, model, use_defaults):
    params = {} if use_defaults else OTHER_PARAMS[model]
    native = NATIVE[model](**params)
    fmu, md, _ = _open(fmus, version, model, params)
    N = md.numberOfContinuousStates
    try:
        np.testing.assert_array_equal(_get(fmu.getContinuousStates, N), native.initial_state())
        rng = np.random.default_rng(7)
        for _ in range(5):
            t = rng.uniform(0.0, 10.0)
            y = native.initial_state() + rng.normal(size=len(native.components))
            fmu.setTime(t)
            _set_x(fmu, y)
            np.testing.assert_allclose(_get(_derivatives(fmu), N), native.rhs(t, y),
                                       rtol=1e-13, atol=1e-12)
        np.testing.assert_array_equal(_get(fmu.getNominalsOfContinuousStates, N),
                                      np.full(len(native.components), native.atol_scale))
    finally:
        fmu.terminate()
        fmu.freeInstance()


@VERSIONS
@pytest.mark.parametrize("model", ["spring_pendulum", "two_mass"])
def test_directional_derivatives(fmus, version, model):
    params = OTHER_PARAMS[model]
    native = NATIVE[model](**params)
    fmu, md, vrs = _open(fmus, version, model, params)
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
                cols.append(_get(_derivatives(fmu), N))
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


@VERSIONS
def test_bouncing_ball_no_directional_derivatives_and_impact_law(fmus, version):
    fmu, md, vrs = _open(fmus, version, "bouncing_ball", {"e": 0.6})
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
            info = _update(fmu)
            assert bool(info[3]) is changed and not info[0] and not info[4]
            assert _get(fmu.getContinuousStates, N).tolist() == list(after)
            fmu.enterContinuousTimeMode()
    finally:
        fmu.terminate()
        fmu.freeInstance()


@VERSIONS
@pytest.mark.parametrize("model", fmu_build.MODELS)
def test_fmu_state_round_trip(fmus, version, model):
    fmu, md, _ = _open(fmus, version, model)
    N = md.numberOfContinuousStates
    fmi2 = version == "2.0"
    get_state, set_state, free_state = (
        (fmu.getFMUstate, fmu.setFMUstate, fmu.freeFMUstate) if fmi2
        else (fmu.getFMUState, fmu.setFMUState, fmu.freeFMUState))
    try:
        fmu.setTime(0.7)
        x0 = _get(fmu.getContinuousStates, N)
        dx0 = _get(_derivatives(fmu), N)
        state = get_state()
        fmu.setTime(2.1)
        _set_x(fmu, x0 + 0.25)
        assert np.any(_get(_derivatives(fmu), N) != dx0)
        set_state(state)
        np.testing.assert_array_equal(_get(fmu.getContinuousStates, N), x0)
        np.testing.assert_array_equal(_get(_derivatives(fmu), N), dx0)
        free_state(state)
    finally:
        fmu.terminate()
        fmu.freeInstance()


def _simulate(fmus, version, model, params=None, **kw):
    return simulate_fmu(str(fmus[version][model][0]), fmi_type="ModelExchange",
                        relative_tolerance=1e-8, start_values=params or {}, **kw)


@VERSIONS
def test_simulate_spring_pendulum(fmus, version):
    res = _simulate(fmus, version, "spring_pendulum", output_interval=0.1)
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


@VERSIONS
@pytest.mark.parametrize("c2", [0.1, 1000.0])
def test_simulate_two_mass_against_exact(fmus, version, c2):
    res = _simulate(fmus, version, "two_mass", {"c2": c2}, output_interval=0.1)
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


@VERSIONS
@pytest.mark.parametrize("params, stop", [({}, None), ({"h0": 2.0, "e": 0.9}, 3.4)])
def test_simulate_bouncing_ball_impacts(fmus, version, params, stop):
    native = BouncingBall(**params)
    res = _simulate(fmus, version, "bouncing_ball", params, stop_time=stop, output_interval=0.01,
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


@pytest.mark.parametrize("model, kw", [
    ("spring_pendulum", {"output_interval": 0.1}),
    ("two_mass", {"output_interval": 0.1, "params": {"c2": 1000.0}}),
    ("bouncing_ball", {"output_interval": 0.01, "record_events": True})])
def test_fmi3_run_identical_to_fmi2(fmus, model, kw):
    """One C model file, two function sets: fmpy's CVode sees the same numbers."""
    kw = dict(kw)
    params = kw.pop("params", None)
    res2, res3 = (_simulate(fmus, version, model, params, **kw)
                  for version in fmu_build.FMI_VERSIONS)
    assert res2.dtype.names == res3.dtype.names and len(res2) == len(res3) > 100
    for name in res2.dtype.names:
        np.testing.assert_array_equal(res3[name], res2[name])


# ------------------------------------------------------------------ energy output
def _energy(model, y, p):
    """The FMUs' output ``energy`` from states ``y`` and parameters ``p``: the
    spring pendulum's invariant (problems/models/spring_pendulum.py ``invariants``),
    the ball's v^2/2 + g y."""
    if model == "spring_pendulum":
        x, h, vx, vy = y
        return 0.5 * (vx**2 + vy**2) + h + 0.5 * p["k"] * (np.hypot(x, h) - 1.0) ** 2
    h, v = y
    return 0.5 * v**2 + p["g"] * h


#: value reference of ``energy``: the next free one after time
ENERGY_VR = {"spring_pendulum": 10, "bouncing_ball": 8}


@VERSIONS
@pytest.mark.parametrize("model", sorted(ENERGY_VR))
def test_energy_output_equals_formula_in_every_mode(fmus, version, model):
    path, unzipdir = fmus[version][model]
    md = read_model_description(str(path), validate_model_structure=True)
    vrs = {v.name: v.valueReference for v in md.modelVariables}
    energy = next(v for v in md.modelVariables if v.name == "energy")
    assert (energy.valueReference, energy.causality, energy.variability, energy.initial,
            float(energy.nominal), energy.start) == \
        (ENERGY_VR[model], "output", "continuous", "calculated", 1.0, None)
    assert [o.variable.name for o in md.outputs][-1] == "energy"
    assert "energy" in [u.variable.name for u in md.initialUnknowns]
    fmi2 = version == "2.0"
    native = NATIVE[model]()
    fmu = (FMU2Model if fmi2 else FMU3Model)(
        guid=md.guid, unzipDirectory=unzipdir,
        modelIdentifier=model, instanceName="t")
    get = fmu.getReal if fmi2 else fmu.getFloat64
    set_ = fmu.setReal if fmi2 else fmu.setFloat64
    rng = np.random.default_rng(11)
    N = len(native.components)

    def check(y, p):
        (value,) = get([vrs["energy"]])
        np.testing.assert_allclose(value, _energy(model, y, p), rtol=1e-14, atol=0)
        return value

    fmu.instantiate()
    try:
        with pytest.raises(FMICallException):          # a calculated output: not settable
            set_([vrs["energy"]], [1.0])
        # initialization mode: random parameters (and states, where they are exact)
        if fmi2:
            fmu.setupExperiment(startTime=0.0)
            fmu.enterInitializationMode()
        else:
            fmu.enterInitializationMode(startTime=0.0)
        if model == "spring_pendulum":
            p = {"k": float(rng.uniform(1.0, 1e4))}
            y = np.array([rng.normal(), rng.uniform(0.5, 2.0), rng.normal(), rng.normal()])
            set_([vrs[c] for c in native.components], list(y))
        else:
            p = {"h0": float(rng.uniform(0.1, 10.0)), "g": float(rng.uniform(1.0, 20.0)),
                 "e": 0.7}
            y = np.array([p["h0"], 0.0])               # calculated from h0
        set_([vrs[n] for n in p], list(p.values()))
        check(y, p)
        fmu.exitInitializationMode()                    # event mode
        check(y, p)
        _update(fmu)
        fmu.enterContinuousTimeMode()
        values = []
        for _ in range(5):                              # continuous-time mode
            t = rng.uniform(0.0, 10.0)
            y = (np.array([rng.normal(), rng.uniform(0.5, 2.0), rng.normal(), rng.normal()])
                 if model == "spring_pendulum"
                 else np.array([rng.uniform(0.0, p["h0"]), rng.normal(0.0, 5.0)]))
            fmu.setTime(t)
            _set_x(fmu, y)
            values.append(check(y, p))
            np.testing.assert_array_equal(_get(fmu.getContinuousStates, N), y)
        if model == "spring_pendulum":                  # the native invariant too
            invariant = NATIVE[model](**p).invariants()["energy"]
            np.testing.assert_allclose(values[-1], invariant(t, y[None, :]), rtol=1e-14)
        fmu.enterEventMode()                            # event mode again
        check(y, p)
        fmu.enterContinuousTimeMode()
        fmu.terminate()
    finally:
        fmu.freeInstance()


@VERSIONS
def test_simulate_spring_pendulum_conserves_energy(fmus, version):
    """fmpy's CVode run: the output energy is the invariant of the run's states and
    stays constant to the solver's accuracy (its drift shrinks with the tolerance)."""
    names = [*SpringPendulum.components, "energy"]
    drift = {}
    for rtol in (1e-8, 1e-10):
        res = simulate_fmu(str(fmus[version]["spring_pendulum"][0]), fmi_type="ModelExchange",
                           relative_tolerance=rtol, output=names, output_interval=0.1)
        assert res.dtype.names == ("time", *names) and res["time"][-1] == pytest.approx(10.0)
        E = np.asarray(res["energy"], float)
        Y = np.column_stack([res[c] for c in SpringPendulum.components])
        np.testing.assert_allclose(E, SpringPendulum().invariants()["energy"](res["time"], Y),
                                   rtol=1e-14)
        assert E[0] == pytest.approx(1.0 + 50.0 * (np.sqrt(2.0) - 1.0) ** 2, rel=1e-15)
        drift[rtol] = np.abs(E - E[0]).max()
        if rtol == 1e-8:
            # the invariant with a wrong constant (k = 101) is far from constant on
            # the same states
            wrong = SpringPendulum(k=101.0).invariants()["energy"](res["time"], Y)
            wrong_drift = np.abs(wrong - wrong[0]).max()
    bound = 1e-3                      # measured 2.3e-4 at rtol 1e-8, 4.9e-6 at 1e-10
    assert drift[1e-8] < bound and drift[1e-10] < drift[1e-8] / 10, drift
    assert wrong_drift > 20 * bound, wrong_drift


@VERSIONS
def test_energy_directional_derivative_is_its_gradient(fmus, version):
    params = OTHER_PARAMS["spring_pendulum"]
    fmu, md, vrs = _open(fmus, version, "spring_pendulum", params)
    x_ref = [vrs[c] for c in SpringPendulum.components]
    try:
        y = np.array([0.8, -0.9, 0.4, -1.1])
        fmu.setTime(0.5)
        _set_x(fmu, y)
        grad = np.array([fmu.getDirectionalDerivative([vrs["energy"]], x_ref, np.eye(4)[j])[0]
                         for j in range(4)])
        lam = params["k"] * (np.hypot(*y[:2]) - 1.0) / np.hypot(*y[:2])
        np.testing.assert_allclose(grad, [y[0] * lam, y[1] * lam + 1.0, y[2], y[3]],
                                   rtol=1e-13)
        fd = [(_energy("spring_pendulum", y + h, params)
               - _energy("spring_pendulum", y - h, params)) / 2e-6
              for h in 1e-6 * np.eye(4)]
        np.testing.assert_allclose(grad, fd, rtol=1e-6)
        # energy, derivatives and states in one call
        dv = np.array([0.3, -1.0, 2.0, 0.5])
        out = fmu.getDirectionalDerivative([vrs["der(vx)"], vrs["energy"], x_ref[0]], x_ref, dv)
        np.testing.assert_allclose(out[1], grad @ dv, rtol=1e-13)
        assert out[2] == dv[0]
    finally:
        fmu.terminate()
        fmu.freeInstance()


@VERSIONS
def test_simulate_bouncing_ball_energy(fmus, version):
    """In flight E = v^2/2 + g y stays g h0 e^(2 k) after the k-th impact."""
    params = {"h0": 2.0, "e": 0.9}
    native = BouncingBall(**params)
    res = _simulate(fmus, version, "bouncing_ball", params, output_interval=0.01,
                    record_events=True)
    t, E = np.asarray(res["time"], float), np.asarray(res["energy"], float)
    g, h0, e = (native.params[n] for n in ("g", "h0", "e"))
    np.testing.assert_allclose(E, 0.5 * res["v"] ** 2 + g * res["y"], rtol=1e-14)
    # fmpy records a row before and one after each event; an impact is a pair
    # whose velocity jumps from falling to rising (see the test above)
    v = np.asarray(res["v"], float)
    impact = np.r_[False, (np.diff(t) == 0) & (v[:-1] < 0) & (v[1:] > 0)]
    k = np.cumsum(impact)
    assert k[-1] == len(native.impact_times()) == 3
    np.testing.assert_allclose(E, g * h0 * e ** (2 * k), rtol=1e-5)
