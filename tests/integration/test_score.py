"""``score=``: the components the error is scored on, named by the user for every
problem (built-in or plugin) as for an FMU; the reference stays the problem's own."""

import json
import subprocess
import sys

import numpy as np
import pytest

from integrator_bench.harness.advise.certificate import perturbed_sets
from integrator_bench.harness.measure import references
from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.cases import expand, parse_problem_spec
from integrator_bench.harness.matrix.line import ProblemSpec
from integrator_bench.harness.matrix.record import CaseStatus
from integrator_bench.harness.report.names import params_label
from integrator_bench.harness.run.execution import execute
from integrator_bench.problems.base import Problem, ProblemError
from integrator_bench.problems.system import convert

PROBLEMS = sorted(registry.problems())


def _first(name):
    cls = registry.get_problem_class(name)
    return cls, dict(cls.benchmark_parameters[0]) if cls.benchmark_parameters else {}


@pytest.mark.parametrize("name", PROBLEMS)
def test_score_replaces_the_error_components_and_keeps_the_reference(name):
    """Scored on its last component and its first (a velocity and a position for a
    mechanical system): those are its error components, the option is in its params
    and label, and its key, fingerprint and committed reference are the plain one's."""
    cls, params = _first(name)
    plain = cls(**params)
    names = (plain.components[-1], plain.components[0])
    scored = cls(**params, score="+".join(names))
    assert scored.error_components == names and scored.score == "+".join(names)
    assert scored.declared_error_components == plain.error_components
    assert scored.params == {**plain.params, "score": "+".join(names)}
    assert "score=" + "+".join(names) in scored.label()
    assert scored.key_params() == plain.key_params()
    assert scored.fingerprint() == plain.fingerprint()
    assert references.paths(scored) == references.paths(plain)
    ref, why = references.read(plain)          # the committed reference is still found
    assert ref is not None, why
    shared, why = references.read(scored)
    assert shared is not None and shared.id == ref.id, why
    assert scored.unscored().params == plain.params
    # rebuilt from its params (as a worker does), it is scored the same
    assert cls(**scored.params).error_components == names


@pytest.mark.parametrize("name", PROBLEMS)
def test_an_unknown_component_is_refused_naming_the_valid_ones(name):
    cls, params = _first(name)
    valid = ", ".join(cls(**params).components)
    for bad in ("no_such", f"{cls(**params).components[0]}+no_such", ""):
        with pytest.raises(ProblemError) as info:
            cls(**params, score=bad)
        assert f"score={bad!r}" in str(info.value) and f"valid: {valid}" in str(info.value)


class Chain(Problem):
    """A plugin problem whose components depend on a parameter, set in its own
    ``__init__`` after the base's (as the built-in chains do)."""

    name = "test_score_chain"
    parameters = ()

    def __init__(self, **params):
        super().__init__(**params)
        self.components = ("a", "b", "c")
        self.error_components = ("a",)


def test_a_plugins_components_set_in_its_own_init_are_scored():
    registry.register(Chain)
    try:
        assert Chain(score="c+b").error_components == ("c", "b")
        with pytest.raises(ProblemError, match=r"'d', not a component of test_score_chain; "
                                               r"valid: a, b, c"):
            Chain(score="d")
        assert [s.params_dict for s in parse_problem_spec("test_score_chain:score=b")] == \
            [{"score": "b"}]
    finally:
        registry.unregister(Chain.name)


def test_a_score_alone_stands_for_the_bare_names_sets():
    sets = [s.params_dict for s in parse_problem_spec("two_mass:score=x1|v2")]
    assert [(s["c2"], s["score"]) for s in sets] == [(0.1, "x1"), (1000.0, "x1"),
                                                     (0.1, "v2"), (1000.0, "v2")]
    assert [s.params_dict["c2"] for s in parse_problem_spec("two_mass:c2=5,score=x1")] == [5.0]
    (first,) = parse_problem_spec("two_mass", first_set_only=True)
    assert parse_problem_spec("two_mass:score=x1", first_set_only=True) == \
        [ProblemSpec.of("two_mass", {**first.params_dict, "score": "x1"})]


def _measured(Y, R, scale):
    """The record's error measures of ``Y`` against ``R`` (times x components)."""
    mixed = np.abs(Y - R) / (scale + np.abs(R))
    rel = np.abs(Y - R) / np.max(np.abs(R), axis=0)
    return {"err_max": mixed.max(), "err_rms": np.sqrt(np.mean(mixed ** 2)),
            "mescd": -np.log10(mixed[-1].max()),
            "scd": -np.log10((np.abs(Y[-1] - R[-1]) / np.abs(R[-1])).max()),
            "err_max_rel": rel.max(), "err_rms_rel": np.sqrt(np.mean(rel ** 2)),
            "err_floor": scale.min()}


@pytest.mark.parametrize("plain_spec, names", [("two_mass:c2=1000", ("x1", "v1")),
                                               ("squeezer", ("beta", "Theta"))])
def test_the_errors_are_those_of_the_named_components(plain_spec, names):
    """The record's errors equal those computed here from the reference and the same
    solve on the named components only, and differ from the unscored case's."""
    spec = f"{plain_spec}{',' if ':' in plain_spec else ':'}score={'+'.join(names)}"
    case, plain = expand(problems=[spec, plain_spec], integrators=["scipy-RK45"],
                         rtols=[1e-5], formulations=["ode"])
    assert case.case_id != plain.case_id and "score" not in plain.params_dict
    record, unscored = execute(case), execute(plain)
    assert record["status"] == unscored["status"] == CaseStatus.OK, record["message"]
    assert record["reference"] == unscored["reference"]
    problem = registry.get_problem_class(case.problem)(**case.params_dict)
    system = convert(problem.formulate("ode"), registry.get_integrator("scipy-RK45"))
    sol = registry.get_integrator("scipy-RK45")().solve(system, rtol=1e-5,
                                                         atol=system.atol(1e-5))
    Y = np.asarray(system.output(sol.t, sol.y), float)
    ref = references.load(problem, compute_missing=False)
    idx = [problem.components.index(n) for n in names]
    want = _measured(Y[:, idx], ref.Y[:, idx], problem.atol_scale_vector()[idx])
    for key, value in want.items():
        assert record[key] == pytest.approx(value, rel=1e-9), key
    assert record["err_max"] != pytest.approx(unscored["err_max"], rel=1e-3)
    for key in ("err_vel", "drift_pos", "drift_vel", "nfev", "nsteps"):
        assert record[key] == unscored[key], key


def test_events_are_measured_on_the_declared_components_whatever_the_score():
    """The ball scored on its velocity: errors on v, the event state error on y as
    without the option."""
    scored, plain = (execute(c) for c in expand(
        problems=["bouncing_ball:score=v", "bouncing_ball"], integrators=["scipy-RK45"],
        rtols=[1e-6]))
    assert scored["status"] == plain["status"] == CaseStatus.OK
    assert scored["err_max"] != plain["err_max"]
    for key in ("events_matched", "event_time_err", "event_state_err", "events_by_kind"):
        assert scored[key] == plain[key], key


def test_the_report_labels_a_scored_group_apart():
    """Its group's title and file names carry the option, its captions the components."""
    from integrator_bench.harness.report.names import slug
    from integrator_bench.harness.report.write import _components

    scored, plain = expand(problems=["two_mass:c2=1000,score=x1+v1", "two_mass:c2=1000"],
                           integrators=["scipy-RK45"], rtols=[1e-3])
    assert "score=x1+v1" in params_label(scored.params_json)
    assert "score" not in params_label(plain.params_json)
    assert slug("two_mass", scored.params_json) != slug("two_mass", plain.params_json)
    assert _components("two_mass", scored.params_json) == "x1, v1"
    assert _components("two_mass", plain.params_json) == "x1, x2"


def test_perturbed_sets_keep_the_score_and_perturb_numbers_only():
    problem = registry.get_problem_class("two_mass")(c2=1000.0, score="x1+v1")
    sets = perturbed_sets(problem, 2)
    assert len(sets) == 2 and all(s["score"] == "x1+v1" for s in sets)
    assert all(s["k1"] != problem.params["k1"] for s in sets)
    assert [type(problem)(**s).error_components for s in sets] == [("x1", "v1")] * 2


@pytest.mark.parametrize("command", [["run", "-i", "scipy-RK45", "--rtol", "1e-3"],
                                     ["advise", "--target", "1e-4"]])
def test_an_unknown_component_on_the_command_line_exits_2_writing_nothing(tmp_path, command):
    store = tmp_path / "s.sqlite"
    got = subprocess.run([sys.executable, "-m", "integrator_bench.harness.cli", command[0],
                          "-p", "two_mass:score=x1+q", *command[1:], "--store", str(store)],
                         capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert got.returncode == 2 and got.stdout == ""
    lines = got.stderr.strip().splitlines()
    assert len(lines) == 1 and "'q'" in lines[0] and "valid: x1, x2, v1, v2" in lines[0]
    assert not any(tmp_path.iterdir())


def test_advise_on_a_scored_problem_says_which_components(tmp_path):
    """``ibench advise`` on two_mass scored on x1 and v1: its target bounds those, its
    reference claim is taken on them, and the winner's error recomputed here on them
    is at or below the target."""
    import html
    import os
    import shutil

    from integrator_bench.harness.paths import REFERENCE_DIR

    refs = tmp_path / "data" / "reference"
    shutil.copytree(REFERENCE_DIR / "two_mass", refs / "two_mass")
    env = {**os.environ, "IBENCH_DATA_DIR": str(tmp_path / "data"),
           "IBENCH_REFERENCE_DIR": str(refs)}
    target = 1e-4
    got = subprocess.run(
        [sys.executable, "-m", "integrator_bench.harness.cli", "advise",
         "-p", "two_mass:c2=1000,score=x1+v1", "--target", str(target), "-i", "scipy-RK45",
         "-i", "cvode-bdf", "--perturbed", "1", "--budget", "2m", "--jobs", "1", "--json",
         "--store", str(tmp_path / "s.sqlite"), "--out", str(tmp_path / "page")],
        capture_output=True, text=True, timeout=300, env=env)
    assert got.returncode == 0, got.stderr
    answer = json.loads(got.stdout)
    assert answer["status"] == "answer", answer.get("why")
    assert answer["scored"] == answer["reproduce"]["scored"] == ["x1", "v1"]
    assert answer["problem"].endswith("score=x1+v1")
    problem = registry.get_problem_class("two_mass")(c2=1000.0, score="x1+v1")
    ref = references.load(problem, refs, compute_missing=False)
    agree = ref.meta["agreement_digits"]
    assert answer["reference"]["claimed_digits"] == int(np.floor(min(agree["x1"], agree["v1"])))
    certificate = html.unescape((tmp_path / "page" / "index.html").read_text()
                                .split("<pre>", 1)[1].split("</pre>", 1)[0])
    assert "on x1, v1" in certificate.splitlines()[1]
    assert answer["robustness"]["sets"] and \
        not any("score" in s for s in answer["robustness"]["sets"])   # never perturbed
    rep = answer["reproduce"]
    icls = registry.get_integrator(rep["integrator"])
    settings = {k: v for k, v in rep["settings"].items() if v is not None}
    system = convert(problem.formulate(rep["formulation"]), icls)
    sol = icls(**settings).solve(system, rtol=rep["rtol"], atol=system.atol(rep["rtol"]))
    Y = np.asarray(system.output(sol.t, sol.y), float)[:, [0, 2]]
    R, scale = ref.Y[:, [0, 2]], problem.atol_scale_vector()[[0, 2]]
    err = np.max(np.abs(Y - R) / (scale + np.abs(R)))
    assert err <= target and err == pytest.approx(answer["winner"]["run"]["error"], rel=1e-6)


def test_the_reference_claim_is_taken_on_the_scored_components():
    cls = registry.get_problem_class("two_mass")
    ref = references.Reference(np.zeros(1), np.zeros((1, 4)), {
        "claimed_digits": 11, "agreement_digits": {"x1": 11.5, "x2": 12.0, "v1": 9.7,
                                                   "v2": 10.2}})
    assert references.claimed_digits(ref, cls()) == 11
    assert references.claimed_digits(ref, cls(score="v1+x1")) == 9
    assert references.claimed_digits(ref, cls(score="v2")) == 10
