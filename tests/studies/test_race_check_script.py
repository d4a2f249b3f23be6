"""studies/race_check.py: a raced store against an exhaustive one."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from integrator_bench.harness.matrix.cases import expand
from integrator_bench.harness.matrix.store import Store
from integrator_bench.harness.run.execution import base_record

ROOT = Path(__file__).resolve().parents[2]
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


def test_a_tie_is_the_same_answer_whichever_of_its_lines_came_cheaper(tmp_path, capsys):
    """Two lines within the noise of each other are a tie in both stores; which one
    timed the cheaper is not the answer. A tie against a winner is a difference."""
    near = {("scipy-DOP853", 1e-3): ("ok", 0.0100, 1e-4), ("scipy-DOP853", 1e-6): ("ok", 0.0200, 1e-7),
            ("scipy-RK45", 1e-3): ("ok", 0.0101, 1e-4), ("scipy-RK45", 1e-6): ("ok", 0.0201, 1e-7)}
    flipped = {**near, ("scipy-RK45", 1e-3): ("ok", 0.0099, 1e-4),
               ("scipy-RK45", 1e-6): ("ok", 0.0199, 1e-7)}
    _store(tmp_path / "a.sqlite", near)
    _store(tmp_path / "b.sqlite", flipped)
    a = race_check.answers(race_check.clean_records(race_check.load(tmp_path / "a.sqlite")), 1e-5)
    b = race_check.answers(race_check.clean_records(race_check.load(tmp_path / "b.sqlite")), 1e-5)
    (key,) = a
    assert a[key][0] != b[key][0] and race_check.same_answer(a[key], b[key])
    assert race_check.answer_words(a[key]) == "tie: scipy-DOP853 (ode), scipy-RK45 (ode)"
    # RK45 ten times dearer: DOP853 wins; a tie that names it too agrees with that
    _store(tmp_path / "c.sqlite", {**near, ("scipy-RK45", 1e-3): ("ok", 0.1, 1e-4),
                                   ("scipy-RK45", 1e-6): ("ok", 0.2, 1e-7)})
    c = race_check.answers(race_check.clean_records(race_check.load(tmp_path / "c.sqlite")), 1e-5)
    assert c[key][1] == {"scipy-DOP853 (ode)"} and race_check.same_answer(c[key], a[key])
    # RK45 ten times cheaper: it wins, and the tie whose cheapest is DOP853 differs
    _store(tmp_path / "d.sqlite", {**near, ("scipy-RK45", 1e-3): ("ok", 0.001, 1e-4),
                                   ("scipy-RK45", 1e-6): ("ok", 0.002, 1e-7)})
    assert race_check.main([str(tmp_path / "d.sqlite"), str(tmp_path / "a.sqlite"),
                            "--target", "1e-5"]) == 1
    assert ("answers differ on 1" in (out := capsys.readouterr().out)
            and "raced scipy-RK45 (ode), exhaustive tie: scipy-DOP853 (ode), scipy-RK45 (ode)"
            in out)
