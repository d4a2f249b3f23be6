"""The run context and its session: several batches in one run (one provenance row,
the store read once), a context's changes to its limits, a bad combination named."""

import json

import pytest

from integrator_bench.harness.matrix.cases import expand
from integrator_bench.harness.matrix.store import Store
from integrator_bench.harness.run.context import RunContext
from integrator_bench.harness.run.limits import Limits
from integrator_bench.harness.run.runner import Session


def _cases():
    """Two cases of one line: two_mass's first parameter set, RK45 at rtol 1e-2 and 1e-3."""
    return expand(problems=["two_mass"], integrators=["scipy-RK45"], rtols=[1e-2, 1e-3],
                  formulations=["ode"])[:2]


def test_the_batches_of_a_session_are_one_run_and_read_the_store_once(tmp_path, monkeypatch,
                                                                      run_cases):
    reads = []
    for name in ("dataframe", "done_case_ids", "measured"):
        real = getattr(Store, name)
        monkeypatch.setattr(Store, name, lambda self, *a, _real=real, _name=name, **k:
                            reads.append(_name) or _real(self, *a, **k))
    first, second = _cases()
    with Store(tmp_path / "s.sqlite") as store:
        run_cases([first], RunContext(store=store, jobs=1, progress=False))   # done before
        reads.clear()
        context = RunContext(store=store, jobs=1, resume=True, progress=False,
                             purpose="advise", limits=Limits(budget_s=30.0, repeat=1))
        with Session(context) as session:
            again = session.run([first, second])          # the first one resumed
            third = session.run([first, second], budget_s=10.0)   # both resumed, in memory
        assert sorted(reads) == ["dataframe", "done_case_ids", "measured"]   # once each
        assert again["case_id"].tolist() == third["case_id"].tolist() \
            == [first.case_id, second.case_id]
        runs = store.runs()
        assert len(store.dataframe()) == 2
    assert runs["purpose"].tolist() == ["run", "advise"]
    assert runs["status"].tolist() == ["finished", "finished"]
    options = json.loads(runs["options"].iloc[-1])
    assert options["cases"] == 4 and options["pending"] == 1 and options["timeout"] == 30.0


def test_a_batch_cut_at_its_deadline_marks_the_session_interrupted(tmp_path):
    import time

    with Store(tmp_path / "s.sqlite") as store:
        with Session(RunContext(store=store, jobs=1, progress=False)) as session:
            session.run(_cases()[:1])
            assert session.run(_cases()[1:], deadline=time.monotonic() - 1).empty
        assert store.runs()["status"].tolist() == ["interrupted"]


def test_a_context_replaces_its_own_fields_and_its_limits_and_refuses_jobs_with_dask():
    context = RunContext(jobs=2, resume=True, limits=Limits(budget_s=5.0, memory_mb=None))
    changed = context.replace(budget_s=7.0, skip=False)
    assert changed.limits == Limits(budget_s=7.0, memory_mb=None) and not changed.skip
    assert changed.jobs == 2 and changed.resume
    with pytest.raises(ValueError, match="exclude each other"):
        RunContext(jobs=2, dask="local:1")
