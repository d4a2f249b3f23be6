"""A full disk or a directory that cannot be written ends a command in one line
naming the path, exit 2: the store's (at the start or mid-run, the run's row
closed as interrupted, every record before kept), the report's (no partial or
temporary file left) and the references' (a read-only reference directory).
The faults are injected: SQLite's "database or disk is full", and ENOSPC or EACCES
from the file system."""

from __future__ import annotations

import errno
import json
import sqlite3
from pathlib import Path

import pytest

from integrator_bench.harness import cli
from integrator_bench.harness.matrix import store as store_module


class FullAfter:
    """A store's connection whose statements starting with ``prefix`` fail as on a
    full disk once ``n`` of them went through."""

    def __init__(self, db, prefix: str, n: int):
        self.db, self.prefix, self.n = db, prefix, n

    def execute(self, sql, *args):
        if sql.startswith(self.prefix):
            if self.n <= 0:
                raise sqlite3.OperationalError("database or disk is full")
            self.n -= 1
        return self.db.execute(sql, *args)

    def __getattr__(self, name):
        return getattr(self.db, name)


@pytest.fixture
def full_after(monkeypatch):
    def make(prefix: str, n: int):
        real = store_module._open

        def opened(path, readonly):
            db, tables = real(path, readonly)
            return (db if readonly else FullAfter(db, prefix, n)), tables
        monkeypatch.setattr(store_module, "_open", opened)
    return make


RUN = ["run", "-p", "two_mass:c2=0.1", "-i", "scipy-RK45", "--rtol", "1e-3", "1e-4", "1e-5",
       "--jobs", "1", "--no-contenders", "--json"]


def _error_lines(err: str) -> list[str]:
    assert "Traceback" not in err, err
    return [line for line in err.splitlines() if line.startswith("ibench: error:")]


def _run_on_a_full_store(path, capsys) -> str:
    """:data:`RUN` into the store ``path``, which fills: exit 2 and one line naming
    it; its standard output."""
    assert cli.main([*RUN, "--store", str(path)]) == 2
    out, err = capsys.readouterr()
    assert _error_lines(err) == [f"ibench: error: store {path} cannot be written: "
                                 "database or disk is full"], err
    return out


def test_a_store_full_mid_run_ends_in_one_line_its_run_interrupted(tmp_path, full_after,
                                                                   capsys):
    path = tmp_path / "s.sqlite"
    full_after("INSERT INTO records", 1)
    out = _run_on_a_full_store(path, capsys)
    assert len(out.splitlines()) == 1   # the one record stored was printed
    runs, records = store_module.load_runs(path), store_module.load(path)
    assert list(runs["status"]) == ["interrupted"] and len(records) == 1


def test_a_store_full_at_the_start_ends_in_one_line_with_nothing_run(tmp_path, full_after,
                                                                     capsys):
    path = tmp_path / "s.sqlite"
    full_after("INSERT INTO runs", 0)
    assert _run_on_a_full_store(path, capsys) == ""
    assert len(store_module.load(path)) == 0


def test_a_report_on_a_full_disk_ends_in_one_line_and_leaves_no_temporary_file(
        tmp_path, monkeypatch, capsys):
    path = tmp_path / "s.sqlite"
    assert cli.main([*RUN, "--store", str(path)]) == 0
    capsys.readouterr()
    out_dir = tmp_path / "report"
    real = Path.write_text

    def write_text(self, data, *args, **kw):
        if self.name.startswith("index.html."):   # half written, then the disk is full
            real(self, data[:100], *args, **kw)
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(self, data, *args, **kw)

    monkeypatch.setattr(Path, "write_text", write_text)
    assert cli.main(["report", "--store", str(path), "--out", str(out_dir)]) == 2
    _, err = capsys.readouterr()
    assert _error_lines(err) == [f"ibench: error: cannot write {out_dir / 'index.html'}: "
                                 "No space left on device"], err
    assert not list(out_dir.rglob("*.part")) and not (out_dir / "index.html").exists()


def test_a_reference_directory_that_cannot_be_written_is_one_line(tmp_path, monkeypatch,
                                                                   capsys):
    from integrator_bench.harness.measure import references

    refs = tmp_path / "read-only"
    monkeypatch.setattr(references, "REFERENCE_DIR", refs)
    real = Path.mkdir

    def mkdir(self, *args, **kw):
        if str(self).startswith(str(refs)):
            raise PermissionError(errno.EACCES, "Permission denied", str(self))
        return real(self, *args, **kw)

    monkeypatch.setattr(Path, "mkdir", mkdir)
    assert cli.main(["reference", "-p", "two_mass:c2=0.1", "--recompute", "--json"]) == 2
    out, err = capsys.readouterr()
    assert _error_lines(err) == [f"ibench: error: cannot write {refs / 'two_mass'}: "
                                 "Permission denied"] and out == ""
    assert not refs.exists()


def test_ctrl_c_to_a_report_leaves_no_temporary_file(tmp_path, capsys):
    """The report's drawing processes, stopped with SIGKILL halfway through their
    figures' atomic writes, leave no ``.part``: the report removes them."""
    import os
    import signal
    import subprocess
    import sys
    import textwrap
    import time

    path, out_dir = tmp_path / "s.sqlite", tmp_path / "report"
    assert cli.main([*RUN, "--store", str(path)]) == 0
    capsys.readouterr()
    script = textwrap.dedent(f"""
        import sys, time
        from pathlib import Path
        import matplotlib.figure

        def savefig(self, fname, *args, **kw):   # half a figure, then stuck
            Path(fname).write_bytes(b"half")
            time.sleep(600)

        matplotlib.figure.Figure.savefig = savefig
        from integrator_bench.harness import cli
        sys.exit(cli.main(["report", "--store", {str(path)!r}, "--out", {str(out_dir)!r}]))
    """)
    proc = subprocess.Popen([sys.executable, "-c", script], start_new_session=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    end = time.monotonic() + 120
    while not list(out_dir.rglob("*.part")):
        assert time.monotonic() < end and proc.poll() is None, proc.communicate()
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGINT)   # Ctrl-C: to the whole process group
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130 and "ibench: interrupted" in err, err
    assert not list(out_dir.rglob("*.part"))
