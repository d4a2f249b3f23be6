"""References: agreement, staleness detection, integrity, --check."""

import json

import numpy as np
import pytest

from integrator_bench.harness.measure import references

from integrator_bench.harness.matrix import registry
from integrator_bench.problems.models.two_mass import TwoMass
from integrator_bench.harness.run.context import RunContext
from integrator_bench.harness.run.limits import Limits


def stored():
    for name, cls in registry.problems().items():
        for params in cls.benchmark_parameters:
            yield pytest.param(cls, params, id=f"{name}-{params}")


def test_a_handed_reference_is_read_in_place_of_a_folder_and_never_computed(refdir,
                                                                           monkeypatch):
    problem = TwoMass(c2=1000)
    stored = references.read(problem, refdir)[0]
    monkeypatch.setattr(references, "compute", lambda p: pytest.fail("computed"))
    handed = references.Handed(stored)
    assert references.load(problem, handed).id == stored.id
    ref, why = references.read(TwoMass(c2=999), handed)
    assert ref is None and "another problem definition" in why
    with pytest.raises(references.ReferenceFailure, match="no reference was handed to this "
                       r"Dask worker \(no stored reference\); a worker never computes one"):
        references.load(problem, references.Handed(None, "no stored reference"))


@pytest.mark.parametrize("cls, params", list(stored()))
def test_reference_agrees_to_the_declared_digits(cls, params):
    problem = cls(**params)
    ref, why = references.read(problem)
    assert ref is not None, f"{problem.label()}: {why} (run `ibench reference`)"
    digits, least = ref.meta["agreement_digits"], problem.reference_digits
    # a problem may ask less than 10 digits, not much less; one whose reference is its
    # exact solution may ask less of the run that checks it (n_four_bar: 6, through 40
    # singular passages)
    assert least >= (6 if problem.exact(problem.t_eval[:1]) is not None else 8)
    for comp in problem.error_components or problem.components:
        assert digits[comp] >= least, f"{comp}: {digits[comp]}"
    assert ref.meta["claimed_digits"] >= least
    assert len(ref.meta["methods"]) == 2
    assert ref.Y.shape == (problem.t_eval.size, problem.dimension)


@pytest.fixture
def refdir(tmp_path):
    problem = TwoMass(c2=1000)
    references.save(references.compute(problem), problem, tmp_path)
    return tmp_path


def test_changed_definition_is_detected_and_recomputed(refdir, monkeypatch):
    problem = TwoMass(c2=1000)
    assert references.read(problem, refdir)[0] is not None
    monkeypatch.setattr(TwoMass, "initial_state", lambda self: np.array([1.0, 1.02, 0.0, 0.0]))
    ref, why = references.read(problem, refdir)
    assert ref is None and "definition changed" in why
    with pytest.warns(UserWarning, match="recomputed"):
        new = references.load(problem, refdir)
    assert new.meta["fingerprint"] == problem.fingerprint()
    assert new.Y[0, 1] == 1.02


def test_corrupted_data_is_detected(refdir):
    problem = TwoMass(c2=1000)
    npz, js = references.paths(problem, refdir)
    with np.load(npz) as d:
        t, Y = d["t"], d["Y"].copy()
    Y[-1, 0] += 1e-9
    np.savez(npz, t=t, Y=Y)
    ref, why = references.read(problem, refdir)
    assert ref is None and "checksum" in why


def test_check_passes_and_fails_on_a_false_claim(refdir):
    problem = TwoMass(c2=1000)
    ok, detail = references.check(problem, refdir)
    assert ok, detail
    npz, js = references.paths(problem, refdir)
    meta = json.loads(js.read_text())
    meta["claimed_digits"] = 15
    js.write_text(json.dumps(meta))
    ok, detail = references.check(problem, refdir)
    assert not ok and "claimed 15" in detail


def test_check_compares_the_stored_solution_with_the_recomputed_one(refdir):
    """A stored position off by 1e-6 whose checksum was rewritten to match (so
    that reading it succeeds) fails ``--check`` on the comparison itself."""
    problem = TwoMass(c2=1000)
    ref, why = references.read(problem, refdir)
    Y = ref.Y.copy()
    Y[-1, problem.component_index(problem.error_components)[0]] += 1e-6
    meta = dict(ref.meta, checksum=references._checksum(ref.t, Y))
    references.save(references.Reference(ref.t, Y, meta), problem, refdir)
    assert references.read(problem, refdir)[0] is not None     # it reads as intact
    ok, detail = references.check(problem, refdir)
    assert not ok, detail
    claimed = ref.meta["claimed_digits"]
    stored_vs_new = float(detail.rpartition("stored vs recomputed ")[2])
    assert stored_vs_new < claimed and f"claimed {claimed} digits" in detail


def test_missing_reference_without_compute_is_an_error(tmp_path):
    with pytest.raises(references.ReferenceFailure, match="no stored reference"):
        references.load(TwoMass(c2=1000), tmp_path, compute_missing=False)


@pytest.mark.parametrize("cls, params", list(stored()))
def test_stored_events_agree_to_8_digits(cls, params):
    """A stored reference of a problem with events carries its event sequence
    from two agreeing runs (times to at least 8 digits); one without
    events carries none."""
    problem = cls(**params)
    ref, why = references.read(problem)
    assert ref is not None, f"{problem.label()}: {why} (run `ibench reference`)"
    has_events = bool(problem.formulate(problem.formulations[0]).events)
    assert ref.has_events == has_events
    if has_events:
        assert ref.meta["event_digits"] >= 8
        assert len(ref.meta["event_states"]) == len(ref.meta["events"])
        times = [t for t, _ in ref.meta["events"]]
        assert times == sorted(times) and problem.t_span[0] < times[0] <= problem.t_span[1]


def test_exact_problem_with_events_checks_its_exact_events(tmp_path):
    from integrator_bench.problems.models.bouncing_ball import BouncingBall

    problem = BouncingBall(e=0.9, t_end=4.0)
    references.save(references.compute(problem), problem, tmp_path)
    ok, detail = references.check(problem, tmp_path)
    assert ok and "6 events, claimed" in detail, detail


def test_a_reference_past_its_limit_leaves_clear_records_and_no_files(tmp_path, run_cases):
    """Computing a reference runs under a time limit: past it nothing is stored and the
    problem's cases are recorded error, reason no_reference, not run; the progress of
    the solve under way is reported meanwhile."""
    from integrator_bench.harness.matrix.cases import expand
    from integrator_bench.integrators.driver import Budget

    cases = expand(problems=["two_mass:c2=0.1"], integrators=["scipy-RK45", "cvode-bdf"],
                   rtols=[1e-3])
    df = run_cases(cases,
                   RunContext(reference_dir=tmp_path, progress=False, jobs=1,
                              limits=Limits(reference_timeout=1e-6)))
    assert len(df) == 2 and (df["status"] == "error").all()
    assert (df["reason"] == "no_reference").all() and df["cpu_s"].isna().all()
    assert "reference not computed within its limit of 1e-06 s" in df["message"].iloc[0]
    assert not [p for p in tmp_path.rglob("*") if p.is_file()]
    seen = []
    budget = Budget(60.0, report=lambda t, percent, elapsed: seen.append(percent), every=0.0)
    assert budget.verdict(0.0, 4.0, 1.0) is None and seen == [25.0]


def test_missing_references_are_computed_side_by_side_and_stored(tmp_path):
    """With several workers the missing references of several parameter sets are
    computed each in a forked process: both stored, the same as one computed here,
    and a set past its limit is reported as missing, its file not written."""
    from integrator_bench.harness.matrix.cases import expand
    from integrator_bench.harness.run.referencing import prepare_references

    cases = expand(problems=["bouncing_ball:e=0.85", "bouncing_ball:e=0.9"], integrators=["scipy-RK45"],
                   rtols=[1e-3])
    assert prepare_references(cases, tmp_path, jobs=2) == {}
    for case in cases:
        problem = registry.get_problem_class("bouncing_ball")(**case.params_dict)
        stored, why = references.read(problem, tmp_path)
        assert stored is not None, why
        np.testing.assert_array_equal(stored.Y, references.compute(problem).Y)
    late = expand(problems=["bouncing_ball:e=0.82", "bouncing_ball:e=0.87"], integrators=["scipy-RK45"],
                  rtols=[1e-3])
    missing = prepare_references(late, tmp_path, jobs=2, limit=1e-6)
    assert set(missing) == {c.spec for c in late}
    assert all("within its limit" in m.why and m.status == "error" for m in missing.values())


def test_a_set_that_changes_every_parameter_has_a_short_file_name(tmp_path):
    """A perturbed set of a problem with many parameters (every continuous one moved a
    little, as the advice's robustness check does) still names files the file system
    takes, distinct per set, and its reference saves."""
    from integrator_bench.problems.models.chain_bushing import ChainBushing

    base = ChainBushing().params
    sets = [{k: v * f if isinstance(v, float) and k not in ("n_links", "teeth") else v
             for k, v in base.items()} for f in (1.0123, 1.0124)]
    (npz, js), (other, _) = (references.paths(ChainBushing(**s), tmp_path) for s in sets)
    assert len(npz.name) + len(".part") <= 255 and len(js.name) + len(".part") <= 255
    assert npz != other
    ref = references.Reference(np.zeros(2), np.zeros((2, 3)), {"label": "x"})
    references.save(ref, ChainBushing(**sets[0]), tmp_path)
    assert npz.exists() and js.exists()


def test_two_saves_of_one_reference_at_once_both_succeed(refdir, monkeypatch):
    """A second save that runs while the first is writing its data (another process
    saving the same reference, here nested in the first) uses temporary files of
    its own: neither renames away the other's, both end with the files in place."""
    problem = TwoMass(c2=1000)
    ref = references.read(problem, refdir)[0]
    savez, nested = np.savez, []

    def save_while_saving(f, **arrays):
        savez(f, **arrays)
        if not nested:
            nested.append(True)
            references.save(ref, problem, refdir)   # the other saver, in the middle

    monkeypatch.setattr(np, "savez", save_while_saving)
    references.save(ref, problem, refdir)
    assert nested
    npz, js = references.paths(problem, refdir)
    assert sorted(p.name for p in npz.parent.iterdir() if p.name.endswith(".part")) == []
    assert references.read(problem, refdir)[0].id == ref.id
