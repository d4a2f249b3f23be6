"""The command line: listing, errors, JSON output, report."""

import json
import subprocess
import sys

import pytest

from integrator_bench.harness import registry


def ibench(*args, **kw):
    return subprocess.run([sys.executable, "-m", "integrator_bench.harness.cli", *args], capture_output=True,
                          text=True, timeout=600, **kw)


@pytest.mark.parametrize("args, needle", [
    (["run", "-p", "no_such_problem"], "'no_such_problem'; valid: "),
    (["run", "-i", "no-such-integrator"], "'no-such-integrator'; valid: "),
    (["run", "-f", "no_such_form"], "'no_such_form'; valid: "),
    (["run", "-p", "spring_pendulum:k=abc"], "k='abc' is not a number"),
    (["run", "-p", "spring_pendulum:k=1e9"], "k=1e+09 is outside its range"),
    (["run", "-p", "spring_pendulum:q=3"], "unknown parameter 'q'"),
    (["run", "-p", "spring_pendulum:k"], "malformed parameter 'k'"),
    (["run", "--rtol", "0"], "--rtol '0' must be a positive"),
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


def test_foreign_store_is_refused(tmp_path):
    bad = tmp_path / "x.sqlite"
    bad.write_text("hello")
    r = ibench("report", "--store", str(bad))
    assert r.returncode == 2 and "not a readable SQLite" in r.stderr


def test_list_json_covers_the_live_registries():
    problems = json.loads(ibench("list", "problems", "--json").stdout)
    assert {p["name"] for p in problems} == set(registry.problems())
    for p in problems:
        for key in ("description", "dimension", "t_span", "parameters", "components",
                    "initial_values", "formulations"):
            assert key in p
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
    assert len(lines) == 4 and all(rec["status"] == "ok" for rec in lines)
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
