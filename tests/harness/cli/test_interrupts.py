"""However a command ends, it ends in one line and leaves nothing behind.

Ctrl-C on any command: one line, ``ibench: interrupted``, exit status 130; SIGTERM
likewise, exit 143. The folder the command extracts FMUs into (``ibench-fmu-*`` in
the system's temporary directory, ``TMPDIR`` here) is removed when it ends: after a
report of FMU records (whose pages are drawn in forked processes) and after a run
stopped by SIGTERM."""

import os
import signal
import subprocess
import sys

import pytest

IBENCH = [sys.executable, "-m", "integrator_bench.harness.cli"]


def _env(tmp_path) -> dict:
    (tmp_path / "tmp").mkdir(exist_ok=True)
    return {**os.environ, "TMPDIR": str(tmp_path / "tmp"),
            "IBENCH_DATA_DIR": str(tmp_path / "data"),
            "IBENCH_REFERENCE_DIR": str(tmp_path / "data" / "reference")}


def _stopped(args, tmp_path, signum):
    """Start ``ibench ARGS``, send ``signum`` once its first line is out, and
    return (exit status, standard error)."""
    proc = subprocess.Popen([*IBENCH, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=_env(tmp_path), cwd=tmp_path,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    first = proc.stdout.readline()
    assert first, proc.communicate()[1]
    proc.send_signal(signum)
    _, err = proc.communicate(timeout=120)
    return proc.returncode, err


def _extractions(tmp_path):
    return sorted(p.name for p in (tmp_path / "tmp").glob("ibench-fmu-*"))


@pytest.mark.parametrize("args", [
    ["verify", "--json"],
    ["stiffness", "-p", "two_mass", "--json"],
    ["reference", "-p", "two_mass", "--recompute", "--json"],
], ids=lambda args: args[0])
def test_ctrl_c_ends_any_command_in_one_line_with_status_130(args, tmp_path):
    status, err = _stopped(args, tmp_path, signal.SIGINT)
    assert status == 130, err
    assert err.strip().splitlines()[-1:] == ["ibench: interrupted"] and "Traceback" not in err
    assert not list((tmp_path / "data").rglob("*.part"))


def test_a_run_stopped_by_sigterm_ends_in_one_line_and_removes_its_fmu_extraction(
        hostile_fmu, tmp_path):
    """The fixed-step case is long (a million Euler steps); the adaptive one at a
    step size is recorded unsupported at once, the first line."""
    status, err = _stopped(["run", "-p", f"fmu:path={hostile_fmu}", "-i", "scipy-RK45",
                            "-i", "euler", "--h", "1e-6", "--json", "--timeout", "60"],
                           tmp_path, signal.SIGTERM)
    lines = err.strip().splitlines()
    assert status == 143 and len(lines) == 1 and "interrupted" in lines[0], err
    assert _extractions(tmp_path) == []


def test_a_report_of_fmu_records_leaves_no_extraction(hostile_fmu, tmp_path):
    env, store = _env(tmp_path), tmp_path / "s.sqlite"
    run = subprocess.run([*IBENCH, "run", "-p", f"fmu:path={hostile_fmu}", "-i", "scipy-RK45",
                          "--rtol", "1e-4", "--store", str(store)], env=env,
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    assert _extractions(tmp_path) == []
    report = subprocess.run([*IBENCH, "report", "--store", str(store), "--out",
                             str(tmp_path / "report")], env=env, capture_output=True, text=True)
    assert report.returncode == 0, report.stderr
    assert _extractions(tmp_path) == []


def test_an_interrupted_write_leaves_the_old_file_whole(tmp_path):
    """Every file a command writes (reference, report page, table, figure, advice)
    goes through ``write_atomically``: cut short, the old file stays, whole."""
    from integrator_bench.harness.paths import write_atomically

    path = tmp_path / "index.md"
    path.write_text("old")

    def cut_short(part):
        part.write_text("new, half of it")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        write_atomically(path, cut_short)
    assert path.read_text() == "old" and list(tmp_path.iterdir()) == [path]
    write_atomically(path, lambda part: part.write_text("new"))
    assert path.read_text() == "new" and list(tmp_path.iterdir()) == [path]
