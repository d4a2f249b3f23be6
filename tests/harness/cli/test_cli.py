"""The command line: listing, errors, JSON output, report."""

import itertools
import json
import os
import shlex
import sqlite3
import subprocess
import sys

import pytest

from integrator_bench.harness.matrix import registry
from integrator_bench.harness.matrix.record import CaseStatus

IBENCH = [sys.executable, "-m", "integrator_bench.harness.cli"]


def ibench(*args, **kw):
    return subprocess.run([*IBENCH, *args], capture_output=True, text=True, timeout=600, **kw)


@pytest.mark.parametrize("args, needle", [
    (["run", "-p", "no_such_problem"], "'no_such_problem'; valid: "),
    (["run", "-i", "no-such-integrator"], "'no-such-integrator'; valid: "),
    (["run", "-f", "no_such_form"], "'no_such_form'; valid: "),
    (["run", "-p", "spring_pendulum:k=abc"], "k='abc' is not a number"),
    (["run", "-p", "spring_pendulum:k=1e9"], "k=1e+09 is outside its range"),
    (["run", "-p", "spring_pendulum:q=3"], "unknown parameter 'q'"),
    (["run", "-p", "spring_pendulum:k"], "malformed parameter 'k'"),
    # a link length that moves the mechanism's joints off its given start
    (["run", "-p", "manipulator:l3=0.206", "-i", "rk4"],
     "start too far from consistent (positions moved by"),
    (["run", "--rtol", "0"], "--rtol '0' must be a positive"),
    (["run", "--rtol", "-1e-3"], "--rtol '-1e-3' must be a positive"),
    (["run", "--rtol", "1"], "--rtol '1' must be a positive finite number below 1"),
    (["run", "--rtol", "1e-3", "2"], "--rtol '2' must be a positive finite number below 1"),
    (["run", "-p", "spring_pendulum:k=inf"], "parameter k=inf is not a finite number"),
    (["run", "-p", "spring_pendulum:k=1e400"], "parameter k=1e400 is not a finite number"),
    (["run", "--h", "1e-2", "-2.5E-1"], "--h '-2.5E-1' must be a positive"),
    (["run", "--timeout", "-5"], "--timeout '-5' must be a positive"),
    (["run", "--preset", "huge"], "invalid choice: 'huge'"),
    (["list", "things"], "invalid choice: 'things'"),
])
def test_bad_input_exits_2_with_one_line(args, needle, tmp_path):
    r = ibench(*args, "--store", str(tmp_path / "s.sqlite")) if args[0] == "run" else ibench(*args)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], r.stderr
    assert not (tmp_path / "s.sqlite").exists()


def _snapshot(folder):
    return {str(p.relative_to(folder)): p.read_bytes() if p.is_file() else None
            for p in folder.rglob("*")}


def _foreign_sqlite(path):
    db = sqlite3.connect(path)
    db.execute("CREATE TABLE x (a)")
    db.commit()
    db.close()


@pytest.mark.parametrize("make, needle", [
    (lambda p: p.write_bytes(b""), "is empty, not an integrator-bench store"),
    (lambda p: p.mkdir(), "is not a file"),
    (lambda p: p.write_text("hello"), "not a readable SQLite"),
    (_foreign_sqlite, "another program"),
], ids=["empty", "directory", "text", "foreign-sqlite"])
def test_report_refuses_what_is_not_a_store_and_writes_nothing(make, needle, tmp_path):
    bad = tmp_path / "x.sqlite"
    make(bad)
    before = _snapshot(tmp_path)
    r = ibench("report", "--store", str(bad))
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0] and str(bad) in lines[0], r.stderr
    assert _snapshot(tmp_path) == before  # no byte changed, no -wal file, no report


@pytest.mark.parametrize("args", [["list", "integrators"], ["list", "problems", "--json"]])
def test_output_into_a_closed_pipe_ends_quietly(args):
    """A reader that is gone before anything is written: no traceback, exit 0."""
    proc = subprocess.Popen([*IBENCH, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    proc.stdout.close()
    err = proc.stderr.read()
    assert proc.wait(timeout=600) == 0 and err == ""


def test_output_piped_into_head_ends_quietly():
    """`ibench list integrators | head`, with a head that has all it wants (no
    line) before ibench writes, so the pipe is closed every time."""
    command = " ".join(map(shlex.quote, [*IBENCH, "list", "integrators"])) + " | head -n 0"
    r = subprocess.run(["bash", "-o", "pipefail", "-c", command], capture_output=True,
                       text=True, timeout=600)
    assert (r.returncode, r.stderr) == (0, "")


def test_list_problems_shows_parameters_with_defaults_and_ranges():
    lines = ibench("list", "problems").stdout.splitlines()
    start = lines.index("parameters:") + 2             # after the title and the header
    rows = lines[start:lines.index("", start)]
    assert "  fmu: " + registry.FAMILIES["fmu"].description in lines
    shown = {tuple(row.split()[:5]) for row in rows}  # problem, name, default, [low, high]
    declared = {(name, p.name, f"{p.default:g}", f"[{p.low:g},", f"{p.high:g}]")
                for name, cls in registry.problems().items() for p in cls.parameters}
    assert declared and shown == declared


def test_list_json_covers_the_live_registries():
    problems = json.loads(ibench("list", "problems", "--json").stdout)
    assert {p["name"] for p in problems} == set(registry.problems())
    for p in problems:
        for key in ("description", "dimension", "t_span", "parameters", "components",
                    "initial_values", "formulations"):
            assert key in p
        assert p["origin"] == registry.problems()[p["name"]].origin    # built-in, or the plugin
        declared = registry.problems()[p["name"]].parameters
        assert [(q["name"], q["default"], q["low"], q["high"]) for q in p["parameters"]] == \
            [(q.name, q.default, q.low if q.low > -float("inf") else None,
              q.high if q.high < float("inf") else None) for q in declared]
    integrators = json.loads(ibench("list", "integrators", "--json").stdout)
    assert {i["name"] for i in integrators} == set(registry.integrators())
    for i in integrators:
        assert i["origin"] == "built-in"
        assert {"accepts", "order", "adaptive", "events", "max_index"} <= set(i)


def test_run_json_and_report(tmp_path):
    store = tmp_path / "s.sqlite"
    r = ibench("run", "-p", "two_mass:c2=1000", "-i", "scipy-RK45", "-i", "ida",
               "--rtol", "1e-4", "--rtol", "1e-7", "--store", str(store), "--json")
    assert r.returncode == 0, r.stderr
    lines = [json.loads(line) for line in r.stdout.splitlines()]
    assert len(lines) == 4 and all(rec["status"] == CaseStatus.OK for rec in lines)
    assert sorted(rec["rtol"] for rec in lines) == [1e-7, 1e-7, 1e-4, 1e-4]  # both --rtol
    out = tmp_path / "report"
    r = ibench("report", "--store", str(store), "--out", str(out))
    assert r.returncode == 0, r.stderr
    assert list(out.glob("*.png")) and list(out.glob("*.csv")) and list(out.glob("*.md"))


def test_reference_json_gives_final_values():
    r = ibench("reference", "-p", "two_mass", "--json")
    assert r.returncode == 0, r.stderr
    metas = [json.loads(line) for line in r.stdout.splitlines()]
    assert len(metas) == 2
    for m in metas:
        assert set(m["final"]) == {"x1", "x2", "v1", "v2"}
        assert m["claimed_digits"] >= 10 and m["code_version"]


def test_report_all_keeps_unsupported_rows(tmp_path):
    """`ibench report` leaves unsupported combinations out of the Markdown tables;
    `--all` keeps them."""
    store = tmp_path / "s.sqlite"
    run = ibench("run", "-p", "two_mass:c2=1000", "-i", "rk4", "-i", "scipy-RK45",
                 "--rtol", "1e-4", "--store", str(store))
    assert run.returncode == 0, run.stderr
    tables = {}
    for flag in ([], ["--all"]):
        out = tmp_path / f"report{len(flag)}"
        done = ibench("report", "--store", str(store), "--out", str(out), *flag)
        assert done.returncode == 0, done.stderr
        tables[bool(flag)] = "".join(p.read_text() for p in out.glob("two_mass*.md"))
    assert "| unsupported |" not in tables[False] and "1 unsupported cases left out" in tables[False]
    assert "| unsupported |" in tables[True]


def test_run_json_stream_holds_records_only_c_output_goes_into_the_message(tmp_path):
    """SUNDIALS warns from C, on the process's own stdout/stderr, that the
    woodpecker's root functions are still zero after the first step: the
    warning goes into the record's message, never into the JSON stream."""
    r = ibench("run", "-p", "woodpecker", "-i", "cvode-bdf", "--rtol", "1e-8", "--json",
               "--store", str(tmp_path / "s.sqlite"))
    assert r.returncode == 0, r.stderr
    records = [json.loads(line) for line in r.stdout.splitlines()]  # every line is a record
    assert len(records) == 1 and records[0]["status"] == "ok", records
    assert "root functions identically 0" in records[0]["message"]
    assert "[WARNING]" not in r.stderr


@pytest.mark.parametrize("command, option", [("run", "--rtol"), ("run", "--h"),
                                             ("stiffness", "--at")])
def test_repeated_values_accumulate(command, option):
    from integrator_bench.harness.cli import build_parser

    required = ["-p", "two_mass"] if command == "stiffness" else []
    args = build_parser().parse_args([command, *required, option, "0.1", option, "0.05", "0.01"])
    assert getattr(args, option.lstrip("-")) == [0.1, 0.05, 0.01]


def _subcommands():
    from integrator_bench.harness.cli import build_parser

    (sub,) = [a for a in build_parser()._actions if a.dest == "command"]
    return sub.choices


def _options(command):
    return [a for a in _subcommands()[command]._actions if a.dest != "help"]


@pytest.mark.parametrize("command", list(_subcommands()))
def test_every_option_has_a_help_line(command, capsys):
    from integrator_bench.harness.cli import main

    with pytest.raises(SystemExit) as stop:
        main([command, "--help"])
    assert stop.value.code == 0
    shown = capsys.readouterr().out
    for action in _options(command):
        assert action.help and action.help.strip(), action.option_strings or action.dest
        assert (action.option_strings or [action.dest])[-1] in shown


@pytest.mark.parametrize("command, option", [
    (command, action.option_strings[-1]) for command in _subcommands()
    for action in _options(command) if type(action).__name__ == "_Once"])
def test_an_option_of_one_value_given_twice_is_refused(command, option, capsys):
    from integrator_bench.harness.cli import main

    action = next(a for a in _options(command) if option in a.option_strings)
    values = [str(c) for c in action.choices][:2] if action.choices else ["1", "2"]
    with pytest.raises(SystemExit) as stop:
        main([command, option, values[0], option, values[-1]])
    assert stop.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{option} given twice" in err[0], err


@pytest.fixture
def recorded_run(monkeypatch):
    """``cli.main(["run", ...])`` with the matrix recorded instead of run: the cases
    and the timeout it would have run them with."""
    from integrator_bench.harness.run import runner

    seen = {}

    def fake_run(session, cases, **kw):
        seen.update(cases=cases, timeout=session.context.limits.budget_s)
        return runner.to_dataframe([])

    monkeypatch.setattr(runner.Session, "run", fake_run)
    return seen


@pytest.mark.parametrize("args, timeout", [
    (["-p", "two_mass"], 2.5),                            # the quick preset's own matrix
    (["-p", "two_mass", "-f", "ode"], 2.5),
    (["-p", "two_mass", "--rtol", "1e-8"], 60.0),         # named tolerances: the default
    (["-p", "two_mass", "--h", "0.01"], 60.0),
    (["-p", "two_mass", "-i", "scipy-Radau"], 60.0),
    (["-p", "two_mass", "-i", "scipy-Radau", "--rtol", "1e-8", "--timeout", "7"], 7.0),
    (["-p", "two_mass", "--timeout", "2"], 2.0),
    (["-p", "two_mass", "--preset", "seeds"], 60.0),      # a preset without a budget
])
def test_timeout_is_the_presets_budget_only_for_its_own_matrix(args, timeout, recorded_run,
                                                               tmp_path):
    from integrator_bench.harness.cli import main
    from integrator_bench.harness.run.limits import DEFAULT_BUDGET_S

    assert main(["run", *args, "--store", str(tmp_path / "s.sqlite")]) == 0
    assert recorded_run["timeout"] == timeout
    assert DEFAULT_BUDGET_S == 60.0  # the README's and the contract's default


@pytest.mark.parametrize("name", [n for n, c in registry.problems().items()
                                  if len(c.benchmark_parameters) > 1])
def test_a_bare_name_runs_every_benchmark_set_a_bare_run_the_first(name, recorded_run,
                                                                   tmp_path):
    """README: ``a bare name runs the problem's benchmark parameter sets`` (the
    chain drive's "both sets"); the quick preset without -p takes the first."""
    from integrator_bench.harness.cli import main

    cls = registry.problems()[name]
    sets = {tuple(sorted(cls(**p).params.items())) for p in cls.benchmark_parameters}
    store = str(tmp_path / "s.sqlite")
    assert main(["run", "-p", name, "-i", "rk4", "-f", "ode", "--store", store]) == 0
    assert {c.params for c in recorded_run["cases"]} == sets
    assert main(["run", "-i", "rk4", "-f", "ode", "--preset", "quick", "--store", store]) == 0
    named = {c.params for c in recorded_run["cases"] if c.problem == name}
    first = tuple(sorted(cls(**cls.benchmark_parameters[0]).params.items()))
    assert named <= {first}


def test_a_damaged_reference_is_recomputed_like_a_failed_checksum(tmp_path):
    """One flipped byte in a copy of a committed reference: the run warns,
    recomputes it and goes on (no BadZipFile traceback)."""
    from integrator_bench.harness.measure import references
    from integrator_bench.harness.paths import REFERENCE_DIR

    cls = registry.get_problem_class("bouncing_ball")  # exact: recomputed in milliseconds
    npz, js = references.paths(cls(), REFERENCE_DIR)
    copy_npz, copy_js = references.paths(cls(), tmp_path)
    copy_npz.parent.mkdir(parents=True)
    data = bytearray(npz.read_bytes())
    data[len(data) // 2] ^= 0xFF
    copy_npz.write_bytes(bytes(data))
    copy_js.write_bytes(js.read_bytes())
    r = ibench("run", "-p", "bouncing_ball", "-i", "scipy-RK45", "--rtol", "1e-4", "--json",
               "--store", str(tmp_path / "s.sqlite"),
               env={**os.environ, "IBENCH_REFERENCE_DIR": str(tmp_path)})
    assert r.returncode == 0, r.stderr
    assert "Traceback" not in r.stderr and "cannot be read" in r.stderr, r.stderr
    (record,) = [json.loads(line) for line in r.stdout.splitlines()]
    assert record["status"] == "ok", record["message"]
    assert references.read(cls(), tmp_path)[0] is not None  # the copy was rewritten, sound


@pytest.mark.parametrize("where", ["start", "middle", "end"])
@pytest.mark.parametrize("which", ["npz", "json"])
def test_a_flipped_byte_anywhere_never_raises_nor_gives_changed_values(where, which,
                                                                             tmp_path):
    from integrator_bench.harness.measure import references
    from integrator_bench.harness.paths import REFERENCE_DIR

    problem = registry.get_problem_class("bouncing_ball")()
    originals = references.paths(problem, REFERENCE_DIR)
    copies = references.paths(problem, tmp_path)
    copies[0].parent.mkdir(parents=True)
    for original, copy in zip(originals, copies):
        data = bytearray(original.read_bytes())
        if original.suffix == f".{which}":
            data[{"start": 0, "middle": len(data) // 2, "end": len(data) - 1}[where]] ^= 0xFF
        copy.write_bytes(bytes(data))
    ref, why = references.read(problem, tmp_path)   # never raises
    if ref is None:
        assert why.startswith(("stored files cannot be read", "stored data does not match"))
    else:  # a byte the data do not depend on (the zip's trailer): the values are intact
        original = references.read(problem, REFERENCE_DIR)[0]
        assert (ref.t == original.t).all() and (ref.Y == original.Y).all()


def test_end_of_run_summary_fits_in_100_columns(tmp_path):
    """A line per problem and parameter set (a long one shortened): status counts,
    the cheapest line to 1e-5 as the report's target table computes it, and how
    to make the report."""
    from integrator_bench.harness.matrix.store import load
    from integrator_bench.harness.ranking.reach import cheapest, target_table
    from integrator_bench.harness.ranking.records import clean_records

    from integrator_bench.harness.measure import references
    from integrator_bench.harness.paths import REFERENCE_DIR

    store, refs = tmp_path / "s.sqlite", tmp_path / "reference"
    problem = registry.get_problem_class("two_mass")(c2=1000)
    for committed, copy in zip(references.paths(problem, REFERENCE_DIR),
                               references.paths(problem, refs)):
        copy.parent.mkdir(parents=True, exist_ok=True)
        copy.write_bytes(committed.read_bytes())
    # a long label, and an exact problem: its reference is computed (into refs) at once
    long_spec = "bouncing_ball:e=0.75,g=9.80665,h0=1.25,t_end=3.3"
    r = ibench("run", "-p", "two_mass:c2=1000", "-p", long_spec, "-i", "scipy-RK45",
               "-i", "scipy-Radau", "-i", "rk4", "--rtol", "1e-4", "1e-7", "--store", str(store),
               env={**os.environ, "IBENCH_REFERENCE_DIR": str(refs)})
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    widths = [len(s.replace(str(store), "").replace(str(tmp_path), "")) for s in lines]
    assert lines and max(widths) <= 100, lines  # but for the paths the user chose
    df = clean_records(load(store))     # the newest record of each case (contenders timed again)
    for (problem, params), rows in df.groupby(["problem", "params"]):
        (at,) = [i for i, s in enumerate(lines) if s.startswith(problem)]
        line = lines[at]
        counts = rows.status.value_counts()
        assert f"{counts.get('ok', 0)} ok" in line and f"{counts.get('failed', 0)} failed" in line
        top = cheapest(target_table(rows), 1e-5)      # the report's answer line
        best = "not reached" if top is None else f"{top['label']}/{top['formulation']}"
        # the answer on the problem's line, or in words on the indented lines below it
        block = [line] + list(itertools.takewhile(lambda s: s.startswith(" "), lines[at + 1:]))
        assert best in " ".join(block)
    assert f"ibench report --store {store}" in r.stdout


def test_a_formulation_the_problem_does_not_offer_names_those_it_does(tmp_path):
    from integrator_bench.harness.matrix.cases import expand
    from integrator_bench.harness.errors import BadInput

    with pytest.raises(BadInput, match="problem bouncing_ball offers no formulation i3; "
                                       "it offers: ode"):
        expand(problems=["bouncing_ball"], formulations=["i3"])
    assert expand(formulations=["i3"], integrators=["ida"])      # no -p: those that offer it
    r = ibench("run", "-p", "bouncing_ball", "-f", "i3", "--store", str(tmp_path / "s.sqlite"))
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "it offers: ode" in r.stderr and not (tmp_path / "s.sqlite").exists()


def test_summary_labels_of_two_files_stay_apart():
    from integrator_bench.harness.cli.summary import fit_label

    a, b = (fit_label(f"fmu:path=/home/user/models/BouncingBall_fmi{v}.fmu", 26, 3) for v in (2, 3))
    assert a != b and len(a) == len(b) == 26 and a.startswith("fmu:path")
    assert fit_label("bouncing_ball:e=0.75,g=9.80665,h0=1.25,t_end=3.3", 26, 13).startswith(
        "bouncing_ball") and fit_label("short", 26) == "short"
