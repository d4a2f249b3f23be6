"""``ibench advise``: its budget is a hard limit and its figures are the real ones;
the robustness check (never the time span, a miss tried tighter before the line is
dropped, winner and runner-up checked alike, the ranks telling who failed)."""

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from integrator_bench.harness.advise import certificate, page
from integrator_bench.harness.matrix import registry
from integrator_bench.harness.paths import REFERENCE_DIR
from integrator_bench.harness.run.limits import Limits
from integrator_bench.harness.run.context import RunContext


def _refs(tmp_path, *names):
    refs = tmp_path / "data" / "reference"
    refs.mkdir(parents=True)
    for name in names:
        shutil.copytree(Path(REFERENCE_DIR) / name, refs / name)
    return refs


def test_a_budget_too_small_is_said_at_the_start_and_kept_with_the_real_figures(tmp_path):
    """A budget of 3 s cannot hold a search round and the robustness check: one line
    on stderr says so first, with the figure needed; the advice stops within the
    budget (a generous 5 s of slack for the machine's load) with a partial answer whose
    message states the budget and the seconds spent, as the JSON's cost does; the
    page goes to a folder of the problem, its parameters, target and error."""
    refs = _refs(tmp_path, "two_mass")
    env = {**os.environ, "IBENCH_DATA_DIR": str(tmp_path / "data"),
           "IBENCH_REFERENCE_DIR": str(refs)}
    got = subprocess.run(
        [sys.executable, "-m", "integrator_bench.harness.cli", "advise", "-p",
         "two_mass:c2=1000", "--target", "1e-5", "-i", "scipy-DOP853", "-i", "scipy-Radau",
         "--budget", "3s", "--store", str(tmp_path / "s.sqlite"), "--json", "--jobs", "2"],
        capture_output=True, text=True, env=env, timeout=300)
    assert got.returncode == 1, got.stderr
    assert "cannot suffice, 8 s at least" in got.stderr.splitlines()[0]
    answer = json.loads(got.stdout)
    cost = answer["cost"]
    assert answer["status"] == "partial" and answer["budget_s"] == 3.0
    assert cost["wall_s"] <= 3.0 + 5.0, cost
    spent = re.search(r"the budget of 3 s did not suffice \(([0-9.e+-]+) s spent\)",
                      answer["why"])
    assert spent and float(spent.group(1)) == pytest.approx(cost["wall_s"], rel=0.01)
    assert cost["cases"] == cost["search_cases"] + cost["robustness_cases"]
    assert cost["cpu_s"] >= cost["search_cpu_s"]
    problem = registry.get_problem_class("two_mass")(c2=1000.0)
    folder = page.default_dir(tmp_path / "s.sqlite", problem, 1e-5, "max",
                              ["scipy-DOP853", "scipy-Radau"])
    assert folder.parent == tmp_path / "advice" / "two_mass"
    assert "c2=1000" in folder.name and "target=1e-05,error=max,candidates=" in folder.name
    assert (folder / "index.html").exists() and answer["page"] == str(folder / "index.html")


def test_a_missing_reference_is_computed_within_the_budget_with_its_progress(tmp_path):
    """A fresh data directory: the pendulum's reference (about 12 s) is computed within
    what is left of a 3 s budget, its progress on stderr; it does not fit, so the
    advice is partial, says so with the real figures, and stores no reference."""
    refs = tmp_path / "data" / "reference"
    env = {**os.environ, "IBENCH_DATA_DIR": str(tmp_path / "data"),
           "IBENCH_REFERENCE_DIR": str(refs)}
    got = subprocess.run(
        [sys.executable, "-m", "integrator_bench.harness.cli", "advise", "-p", "pendulum",
         "--target", "1e-5", "-i", "scipy-DOP853", "-f", "ode", "--budget", "3",
         "--store", str(tmp_path / "s.sqlite"), "--json", "--out", str(tmp_path / "page")],
        capture_output=True, text=True, env=env, timeout=300)
    assert got.returncode == 1, got.stderr
    assert re.search(r"computing reference for pendulum.*limit [0-9.]+ s", got.stderr)
    answer = json.loads(got.stdout)
    assert answer["status"] == "partial" and "reference not computed" in answer["why"]
    assert answer["why"].startswith("the budget of 3 s did not suffice (")
    assert answer["cost"]["wall_s"] <= 3.0 + 5.0, answer["cost"]
    assert not list(refs.rglob("*.npz"))


def test_every_advice_has_a_page_folder_of_its_own():
    two_mass = registry.get_problem_class("two_mass")
    a, b = two_mass(c2=1000.0), two_mass(c2=0.1)
    folders = {page.default_dir("s.sqlite", p, t, m) for p in (a, b) for t in (1e-3, 1e-5)
               for m in ("max", "final")}
    assert len(folders) == 8
    # restricted to other candidates (-i, -f): a folder of its own, whatever the order given
    restricted = {page.default_dir("s.sqlite", a, 1e-3, "max", i, f)
                  for i, f in ((["cvode-bdf", "rk4"], None), (["rk4", "cvode-bdf"], None),
                               (["rk4"], None), (None, ["ode"]), (["rk4"], ["ode"]))}
    assert len(restricted) == 4 and not restricted & folders
    assert page.default_dir("s.sqlite", a, 1e-3, "max", [], []) in folders


def test_the_time_span_and_output_times_are_never_perturbed():
    """The bouncing ball's end time is a parameter: it moves the time span, so the
    perturbed sets leave it, and every set runs on the model's own output times."""
    ball = registry.get_problem_class("bouncing_ball")()
    moved = certificate.perturbation(ball, 3)
    assert "t_end" not in moved.names and {"e", "g", "h0"} <= set(moved.names)
    for params in moved.sets:
        variant = type(ball)(**params)
        assert variant.t_span == ball.t_span
        np.testing.assert_array_equal(variant.t_eval, ball.t_eval)


def test_a_robustness_check_the_budget_cut_short_is_unfinished_not_failed():
    """Runs the budget left unrun are no failure: each leader's check is unfinished
    (``holds`` None), none is tried tighter, and the text says so."""
    import pandas as pd

    problem = registry.get_problem_class("two_mass")(c2=1000.0)
    cands, ranked = _leaders(problem, ["scipy-Radau", "cvode-bdf"])
    asked = []

    def run(cases):
        asked.append(len(cases))
        return pd.DataFrame({"case_id": [], "status": []})

    robust = certificate.robustness(problem, ranked, cands, 1e-5, "max", 2, run)
    assert [c.holds for c in robust.checked] == [None, None] and asked == [2, 2]
    assert robust.holds is None and robust.holders == ()
    assert page.CHECK_WORDS[None].startswith("unfinished")


def _leaders(problem, names):
    from integrator_bench.harness.advise.candidates import Candidate
    from integrator_bench.harness.advise.evidence import LineEntry, Run

    cands, ranked = {}, []
    for rank, name in enumerate(names, 1):
        c = Candidate("ode", name, (), "implicit")
        cands[c.key] = c
        ranked.append(LineEntry(name, "ode", "implicit", rank=rank,
                                run=Run(1e-4, 1e-5, 1e-3 * rank)))
    return cands, ranked


def _fake_run(fails, target=1e-5, c2=1000.0):
    """A robustness ``run`` with made-up records: every run ok, error 0.3 times
    ``target``, CPU 1e-3 s times ``(1e-4 / rtol)^0.2``; the line ``fails`` names
    (its integrator label, or the first one asked for on a perturbed set, the
    robustness check's first, when ``fails`` is None) errs twice the target on the
    perturbed sets at every rtol."""
    from integrator_bench.harness.run.execution import base_record
    from integrator_bench.harness.run.runner import to_dataframe

    first = []

    def run(cases):
        first.extend([] if first else [c.line.label for c in cases
                                       if dict(c.params) != nominal][:1])
        bad = fails or (first[0] if first else None)
        records = []
        for c in cases:
            perturbed = dict(c.params) != nominal
            err = (2.0 if c.line.label == bad and perturbed else 0.3) * target
            records.append({**base_record(c), "status": "ok", "err_max": err,
                            "cpu_s": 1e-3 * (1e-4 / c.rtol) ** 0.2})
        return to_dataframe(records)

    nominal = registry.get_problem_class("two_mass")(c2=c2).params
    return run


def test_a_line_that_misses_is_tried_tighter_before_it_is_dropped_and_two_are_checked():
    """The first leader misses on a perturbed set: it is tried a decade tighter at
    once (on the model and every set) before the next is checked, and the check goes
    on until two lines hold: the winner and the runner-up are checked alike."""
    problem = registry.get_problem_class("two_mass")(c2=1000.0)
    cands, ranked = _leaders(problem, ["scipy-Radau", "cvode-bdf", "scipy-BDF"])
    robust = certificate.robustness(problem, ranked, cands, 1e-5, "max", 2,
                                    _fake_run("scipy-Radau"))
    tried = [(c.label, c.rtol, c.holds) for c in robust.checked]
    assert tried == [("scipy-Radau", 1e-4, False), ("scipy-Radau", 1e-5, False),
                     ("cvode-bdf", 1e-4, True), ("scipy-BDF", 1e-4, True)]
    assert [e.label for e in robust.holders] == ["cvode-bdf", "scipy-BDF"]


def test_a_tighter_try_that_holds_keeps_the_line_at_its_tighter_rtol():
    problem = registry.get_problem_class("two_mass")(c2=1000.0)
    cands, ranked = _leaders(problem, ["scipy-Radau", "cvode-bdf"])

    def run(cases, inner=_fake_run("scipy-Radau")):   # Radau holds once a decade tighter
        df = inner(cases)
        df.loc[df["rtol"] <= 1e-5, "err_max"] = 3e-6
        return df

    robust = certificate.robustness(problem, ranked, cands, 1e-5, "max", 2, run)
    radau = next(e for e in robust.holders if e.label == "scipy-Radau")
    assert radau.retightened_from == 1e-4 and radau.run.rtol == 1e-5
    assert radau.run.error == 3e-6


def _made_up_advice(monkeypatch, tmp_path):
    """An advice on two_mass (c2 = 0.1) to 1e-3 whose search and runs are made up
    (:func:`_fake_run`): every line at rtol 1e-4, the first line checked missing on
    the perturbed sets."""
    from integrator_bench.harness.advise import advice, search
    from integrator_bench.harness.run.context import RunContext
    from integrator_bench.harness.run.runner import Session

    refs = _refs(tmp_path, "two_mass")
    fake = _fake_run(None, 1e-3, c2=0.1)

    def made_up_search(problem, cands, target, measure, budget_s, session, **kw):
        cases = [c.case(problem, 1e-4) for c in cands]
        return search.SearchResult([search.Line(c, calibrated=True) for c in cands],
                                   fake(cases), target, measure, rounds=1, cases=len(cases))

    monkeypatch.setattr(advice.search, "search", made_up_search)
    monkeypatch.setattr(Session, "run", lambda self, cases, **kw: fake(cases))
    problem = registry.get_problem_class("two_mass")(c2=0.1)
    answer = advice.advise(problem, advice.Question(
        1e-3, budget_s=120.0, integrators=["scipy-DOP853", "scipy-RK45", "cvode-adams"]),
        RunContext(reference_dir=refs, jobs=1, progress=False))
    return answer


def test_the_ranks_say_failed_robustness_and_the_runner_up_is_checked(tmp_path, monkeypatch):
    """The advice's search and robustness runs made up (every line at rtol 1e-4 under
    the target; the first line checked misses on the perturbed sets at every rtol):
    that line reads "failed robustness" in the table, never "reached"; the winner and
    the runner-up both hold, and the text says so for both."""
    answer = _made_up_advice(monkeypatch, tmp_path)
    assert answer.status == "answer", answer.why
    failed = [e for e in answer.lines if e.robustness == "failed"]
    assert len(failed) == 1 and failed[0].rank == 1
    rows = page.table(answer)
    name = failed[0].label
    assert [r.endswith(" failed robustness") for r in rows if f" {name} " in r] == [True]
    assert answer.winner.robustness == answer.runner_up.robustness == "holds"
    shown = page.text(answer)
    assert shown.splitlines()[-1].endswith("verified on 2 perturbed sets")
    assert re.search(r"runner-up: .*; verified on 2 perturbed sets", shown)
    assert "no settings" not in shown and "(default settings)" in shown
    assert answer.cost.robustness_cases == 2 + 3 + 2 + 2   # a tighter try: model too


def test_a_run_past_its_deadline_stops_and_records_nothing_unfinished(tmp_path, run_cases):
    """The advice's hard limit in the run engine: a case still running at the
    deadline is killed and not stored (a resumed run does it), the cases not handed
    out stay so, the run is marked interrupted, and what finished is kept."""
    import time

    from integrator_bench.harness.matrix.cases import Case
    from integrator_bench.harness.matrix.store import Store

    refs = _refs(tmp_path, "pendulum")
    params = tuple(sorted(registry.get_problem_class("pendulum")().params.items()))
    quick = Case("pendulum", params, "ode", "scipy-DOP853", rtol=1e-3)
    # 5 s and 11 s of CPU on this project's machine, past the 3 s deadline; a worker
    # each, so that the dearer-first order cannot keep the quick case waiting
    slow = [Case("pendulum", params, "ode", i, rtol=1e-13) for i in ("scipy-Radau", "scipy-RK23")]
    with Store(tmp_path / "s.sqlite") as store:
        start = time.monotonic()
        df = run_cases([quick, *slow],
                       RunContext(store=store, jobs=3, progress=False, reference_dir=refs,
                                  skip=False, limits=Limits(budget_s=100)),
                       deadline=time.monotonic() + 3.0)
        assert time.monotonic() - start < 30          # not the slow cases' seconds
        assert df["case_id"].tolist() == [quick.case_id] and df["status"].tolist() == ["ok"]
        assert store.dataframe()["case_id"].tolist() == [quick.case_id]
        assert store.runs()["status"].tolist() == ["interrupted"]


#: the ``--json`` object's keys, in their order (docs/advise.md, docs/command-line.md: a
#: contract; ``page`` is added by the command line, after ``why``)
ANSWER_KEYS = ["problem", "target", "measure", "ranked_by", "scored", "budget_s", "candidates",
               "ruled_out", "reference", "lines", "families", "robustness", "cost",
               "contenders", "winner", "runner_up", "margin", "verdict", "tied", "same_code",
               "verified_sets", "reproduce", "status", "why"]
MARGIN_KEYS = ["ratio", "tie", "low", "high", "paired", "line"]
CONTENDERS_KEYS = ["contests", "retimed", "blocks", "cpu_s", "cap_s", "stopped", "left_open",
                   "why"]
COST_KEYS = ["wall_s", "cpu_s", "cases", "search_cases", "robustness_cases", "rounds",
             "search_wall_s", "search_cpu_s"]
#: a line of the ranking (``lines``, ``winner``, ``runner_up``, the robustness check's
#: ``holders``) that reached the target; one that did not has its least error in place of
#: its rank and CPU to the target; one re-tightened on the perturbed sets says from what rtol
ENTRY_KEYS = ["integrator", "formulation", "family", "runs", "calibrated", "note", "points",
              "run", "rank", "to_target", "how", "robustness"]
MISSED_KEYS = [*ENTRY_KEYS[:8], "best_error", "robustness"]
RETIGHTENED_KEYS = [*ENTRY_KEYS[:11], "retightened_from", "robustness"]
RUN_KEYS = ["rtol", "error", "cpu_s", "cpu_s_iqr", "repeat", "case_id", "nfev", "njev", "nlu",
            "nsteps", "nreject", "drift_pos", "drift_vel"]
ROBUSTNESS_KEYS = ["perturbed", "sets", "checked", "holders", "why"]
CHECKED_KEYS = ["integrator", "formulation", "rtol", "holds", "runs"]
CHECK_RUN_KEYS = ["params", "error", "status"]
#: of perturbed parameters; perturbed initial states add ``rule`` and ``starts``
PERTURBED_KEYS = ["what", "names", "relative", "seed"]
#: a reference had tighter than the stored one adds ``tightened``
REFERENCE_KEYS = ["id", "methods", "claimed_digits", "needed_digits"]
REPRODUCE_KEYS = ["integrator", "settings", "formulation", "system_kind", "states", "rtol",
                  "atol", "atol_scale_min", "atol_scale_max", "atol_scale", "jacobian", "loop",
                  "library_call", "output_times", "variables", "scored"]
OUTPUT_TIMES_KEYS = ["first", "last", "count", "spacing"]
FAMILY_KEYS = ["integrator", "formulation", "rtol", "cpu_s"]
RULED_OUT_KEYS = ["label", "formulation", "reason"]


def test_the_json_answer_keeps_every_field_of_its_contract(tmp_path, monkeypatch):
    """The typed answer turned into the ``--json`` object has every key the docs
    promise, in the order it always had, down to each line's run, the robustness
    check's runs, the reference's methods and the recipe; an advice stopped without
    a reference ends at ``cost``, ``why``."""
    from integrator_bench.harness.advise.answer import Advice, Asked, Cost

    answer = _made_up_advice(monkeypatch, tmp_path)
    got = json.loads(json.dumps(answer.to_dict(), default=str))
    assert list(got) == ANSWER_KEYS
    assert list(got["cost"]) == COST_KEYS
    assert list(got["margin"]) == MARGIN_KEYS
    assert list(got["contenders"]) == CONTENDERS_KEYS
    assert got["verdict"] in ("winner", "tie")
    assert isinstance(got["tied"], list) and isinstance(got["same_code"], dict)
    rob = got["robustness"]
    assert list(rob) == ROBUSTNESS_KEYS and len(rob["holders"]) == 2
    for entry in (got["winner"], got["runner_up"], *got["lines"], *rob["holders"]):
        assert list(entry) == ENTRY_KEYS and list(entry["run"]) == RUN_KEYS
    assert all(list(f) == FAMILY_KEYS for f in got["families"].values())
    assert list(rob["perturbed"]) == PERTURBED_KEYS and rob["checked"]
    for checked in rob["checked"]:
        assert list(checked) == CHECKED_KEYS
        assert all(list(r) == CHECK_RUN_KEYS for r in checked["runs"])
    assert list(got["reproduce"]) == REPRODUCE_KEYS
    assert list(got["reproduce"]["output_times"]) == OUTPUT_TIMES_KEYS
    assert list(got["reference"]) == REFERENCE_KEYS
    assert all(list(m)[-2:] == ["family", "code"] for m in got["reference"]["methods"])
    stopped = Advice(Asked("two_mass", 1e-3, "max", "cpu", ("x1",), 3.0), 2, (), "none",
                     Cost(1.0, 1.0, 0, 0, 0), "no reference").to_dict()
    assert list(stopped) == [*ANSWER_KEYS[:8], "status", "cost", "why"]


def test_every_typed_part_keeps_its_keys_with_its_optional_ones():
    """Each part of the answer with every optional field given: its ``to_dict`` has
    all its keys, in order (a part that dropped or renamed one fails here), each
    value the attribute's (a line's ``label`` is its ``integrator``)."""
    from dataclasses import replace

    from integrator_bench.harness.advise.answer import Advice, Asked, Cost, FamilyBest
    from integrator_bench.harness.advise.candidates import RuledOut
    from integrator_bench.harness.advise.evidence import (
        CheckRun, Checked, LineEntry, OutputTimes, Perturbed, Reference, ReferenceMethod,
        Reproduction, Robustness, Run)

    run = Run(*range(len(RUN_KEYS)))
    reached = LineEntry("cvode-bdf (max_order=2)", "ode", "implicit", 3, True, "left",
                        ((1e-3, 1e-4, 0.1),), run, rank=1, robustness="holds")
    retightened = replace(reached, retightened_from=1e-3)
    missed = LineEntry("rk4", "ode", "explicit", 1, False, None, ((1e-3, 1e-2, 0.1),),
                       best_error=1e-2)
    checked = Checked("cvode-bdf (max_order=2)", "ode", 1e-3, True,
                      (CheckRun({"c2": 1.0}, 1e-5, "ok"),))
    starts = Perturbed("initial states", ("start.x",), 0.03, 1, "rule",
                       {"start.x": {"start": 2.0, "scale": 2.0}})
    robust = Robustness(starts, ({"start.x": 2.01},), (checked,), (retightened,))
    method = ReferenceMethod({"formulation": "ode", "integrator": "scipy-Radau",
                              "rtol": 1e-13}, "implicit", "scipy")
    reference = Reference("abc", (method,), 9, 7, tightened=1e-4)
    recipe = Reproduction("cvode-bdf", {"max_order": 2}, "ode", "ode", 2, 1e-3, "atol",
                          1.0, 2.0, (1.0, 2.0), "analytic", "library", {"call": "CVode"},
                          OutputTimes(0.0, 1.0, 11, "uniform"), ("x", "v"), ("x",))
    assert list(run.to_dict()) == RUN_KEYS and list(run.to_dict().values()) == list(
        range(len(RUN_KEYS)))
    assert list(reached.to_dict()) == ENTRY_KEYS
    assert list(retightened.to_dict()) == RETIGHTENED_KEYS
    assert list(missed.to_dict()) == MISSED_KEYS and missed.to_dict()["run"] is None
    assert reached.to_dict()["integrator"] == "cvode-bdf (max_order=2)"
    assert reached.to_dict()["points"] == [[1e-3, 1e-4, 0.1]]
    assert list(checked.to_dict()) == CHECKED_KEYS
    assert [list(r) for r in checked.to_dict()["runs"]] == [CHECK_RUN_KEYS]
    assert list(starts.to_dict()) == [*PERTURBED_KEYS, "rule", "starts"]
    assert list(robust.to_dict()) == ROBUSTNESS_KEYS
    assert list(robust.to_dict()["holders"][0]) == RETIGHTENED_KEYS
    assert list(Robustness(None, why="no").to_dict()) == ["perturbed", "sets", "checked",
                                                          "why"]
    assert list(reference.to_dict()) == [*REFERENCE_KEYS, "tightened"]
    assert list(reference.to_dict()["methods"][0]) == ["formulation", "integrator", "rtol",
                                                       "family", "code"]
    assert list(recipe.to_dict()) == REPRODUCE_KEYS
    assert list(recipe.to_dict()["output_times"]) == OUTPUT_TIMES_KEYS
    assert list(FamilyBest("rk4", "ode", 1e-3, 0.1).to_dict()) == FAMILY_KEYS
    stopped = Advice(Asked("two_mass", 1e-3, "max", "cpu", ("x1",), 3.0), 3,
                     (RuledOut("rk4", "ode", "a fixed step"),), "none", Cost(1.0, 1.0, 0, 0, 0),
                     "no reference").to_dict()
    assert stopped["ruled_out"] == [dict(zip(RULED_OUT_KEYS, ("rk4", "ode", "a fixed step")))]
    assert [list(r) for r in stopped["ruled_out"]] == [RULED_OUT_KEYS]
