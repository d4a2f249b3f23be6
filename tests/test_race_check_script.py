"""studies/race_check.py: a raced store against an exhaustive one."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from integrator_bench.harness.matrix.cases import expand
from integrator_bench.harness.matrix.store import Store
from integrator_bench.harness.run.execution import base_record

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "studies"))
import race_check  # noqa: E402

SMALL = "two_mass:c1=0.1,c2=1000,k1=10,k2=10000"


def _store(path, outcomes):
    """A store of one record per ``(integrator, rtol) -> (status, cpu_s, err)``."""
    cases = expand(problems=[SMALL], integrators=sorted({i for i, _ in outcomes}),
                   rtols=sorted({r for _, r in outcomes}), formulations=["ode"])
    with Store(path) as store:
        for case in cases:
            status, cpu, err = outcomes[(case.integrator, case.rtol)]
            record = base_record(case)
            record.update(status=status, cpu_s=cpu, err_max=err, repeat=1, budget_s=5.0,
                          cpu_samples=json.dumps([cpu]), budget_edge=0, created="2026-12-07")
            if status == "dominated":
                record.update(reason="race_bound", cpu_s=None, err_max=None, race_bound_s=0.16)
            store.add(record)


EXHAUSTIVE = {("scipy-DOP853", 1e-3): ("ok", 0.005, 1e-4), ("scipy-DOP853", 1e-6): ("ok", 0.01, 1e-7),
              ("scipy-RK23", 1e-3): ("ok", 0.01, 1e-3), ("scipy-RK23", 1e-6): ("ok", 1.0, 1e-6)}


def test_a_cut_beyond_tau_changes_nothing_and_a_lost_answer_is_found(tmp_path, capsys):
    _store(tmp_path / "exh.sqlite", EXHAUSTIVE)
    # RK23 at rtol 1e-6 is 100 times the best: cut, and nothing within tau moves
    _store(tmp_path / "raced.sqlite", {**EXHAUSTIVE, ("scipy-RK23", 1e-6): ("dominated", 0, 0)})
    assert race_check.main([str(tmp_path / "raced.sqlite"), str(tmp_path / "exh.sqlite")]) == 0
    out = capsys.readouterr().out
    assert "answers differ on 0" in out and "raced: 4 cases (3 ok, 1 dominated)" in out
    # a cut of the best line's crossing changes the answer: found
    _store(tmp_path / "bad.sqlite", {**EXHAUSTIVE, ("scipy-DOP853", 1e-6): ("dominated", 0, 0)})
    assert race_check.main([str(tmp_path / "bad.sqlite"), str(tmp_path / "exh.sqlite")]) == 1
    assert "answers differ on 1" in capsys.readouterr().out
