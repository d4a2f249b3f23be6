"""Refused before any work, in one line with exit status 2, nothing written: an
``--out`` that cannot be the output directory, and a non-finite start value of
an FMU's state."""

import pytest

from integrator_bench.harness.cli import main

STATE = "../../../../escaped/pwned/x"   # the hostile FMU's state (tests/fmu_hostile)


def _files(root):
    return sorted(p for p in root.rglob("*"))


@pytest.fixture(autouse=True)
def _references_in_tmp(tmp_path, monkeypatch):
    """A command that is not refused computes its references under ``tmp_path``
    (where the test sees them as written), never in the checkout."""
    from integrator_bench.harness.measure import references
    monkeypatch.setattr(references, "REFERENCE_DIR", tmp_path / "reference")


def _refused(args, capsys, root, needle):
    before = _files(root)
    assert main(args) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("ibench: error: ") and needle in lines[0], lines
    assert _files(root) == before


@pytest.mark.parametrize("command", ["report", "stiffness", "advise"])
@pytest.mark.parametrize("make, needle", [
    (lambda out: out.write_text("x"), "is an existing file, not a directory"),
    (lambda out: (out.parent / "f").write_text("x"), "lies under the file"),
], ids=["file", "under-a-file"])
def test_an_out_that_is_no_directory_is_refused_before_any_work(command, make, needle,
                                                                  tmp_path, capsys):
    out = tmp_path / "out"
    make(out)
    if needle.startswith("lies"):
        out = tmp_path / "f" / "out"
    if command == "report":   # a store to report: the store is checked first
        from integrator_bench.harness.matrix.store import Store
        Store(tmp_path / "s.sqlite").close()
    args = {"report": ["report"], "stiffness": ["stiffness", "-p", "two_mass"],
            "advise": ["advise", "-p", "two_mass", "--target", "1e-3"]}[command]
    _refused([*args, "--store", str(tmp_path / "s.sqlite"), "--out", str(out)], capsys,
             tmp_path, needle)


def test_an_out_in_a_read_only_directory_is_refused(tmp_path, capsys):
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o500)
    try:
        import os
        if os.access(locked, os.W_OK):
            pytest.skip("running as a user who may write anywhere")
        _refused(["report", "--store", str(tmp_path / "s.sqlite"), "--out",
                  str(locked / "out")], capsys, tmp_path, "is not writable")
    finally:
        locked.chmod(0o700)


def _options(command, tmp_path) -> list:
    """What ``command`` needs beside ``-p`` to run, its files under ``tmp_path``."""
    return {"run": ["--store", str(tmp_path / "s.sqlite")],
            "advise": ["--target", "1e-3", "--store", str(tmp_path / "s.sqlite"),
                       "--out", str(tmp_path / "page")],
            "reference": [], "stiffness": ["--store", str(tmp_path / "s.sqlite")]}[command]


@pytest.mark.parametrize("command", ["run", "advise", "reference", "stiffness"])
@pytest.mark.parametrize("value", ["inf", "-inf", "1e400", "nan"])
def test_a_non_finite_fmu_start_is_refused(hostile_fmu, command, value, tmp_path, capsys):
    spec = f"fmu:path={hostile_fmu},start.{STATE}={value}"
    _refused([command, "-p", spec, *_options(command, tmp_path)], capsys, tmp_path,
             f"parameter start.{STATE}={value} is not a finite number")


@pytest.mark.parametrize("command", ["run", "advise", "reference", "stiffness"])
def test_a_directory_given_as_an_fmu_is_called_a_directory(command, tmp_path, capsys):
    folder = tmp_path / "model.fmu"
    folder.mkdir()
    _refused([command, "-p", f"fmu:path={folder}", *_options(command, tmp_path)], capsys,
             tmp_path, f"FMU file '{folder}' is a directory, not an FMU file")
