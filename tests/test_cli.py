"""The command line: listing, errors, JSON output, report."""

import json
import shlex
import sqlite3
import subprocess
import sys

import pytest

from integrator_bench.harness import registry
from integrator_bench.harness.record import CaseStatus

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
    (["run", "--rtol", "0"], "--rtol '0' must be a positive"),
    (["run", "--rtol", "-1e-3"], "--rtol '-1e-3' must be a positive"),
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
               "--rtol", "1e-4", "1e-7", "--store", str(store), "--json")
    assert r.returncode == 0, r.stderr
    lines = [json.loads(line) for line in r.stdout.splitlines()]
    assert len(lines) == 4 and all(rec["status"] == CaseStatus.OK for rec in lines)
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
