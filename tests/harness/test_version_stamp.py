"""code_version: git from the project's checkout, the build stamp from an installed wheel.

asv installs a wheel of each benchmarked commit inside its environment
directory, which lies inside the repository: asking git there would name the
repository's current commit, not the installed one.
"""

import shutil
import subprocess
import sys
from pathlib import Path

from integrator_bench.harness import version

REPO = Path(__file__).resolve().parents[2]


def _installed_copy(site: Path, stamp: str | None) -> str:
    """code_version() of a copy of harness/version.py installed under ``site``."""
    pkg = site / "integrator_bench" / "harness"
    pkg.mkdir(parents=True)
    shutil.copy(REPO / "harness" / "version.py", pkg / "version.py")
    (pkg / "__init__.py").write_text("")
    if stamp is not None:
        (pkg / "_commit.txt").write_text(stamp + "\n")
    code = "from integrator_bench.harness.version import code_version; print(code_version())"
    return subprocess.run([sys.executable, "-c", code], cwd=site, env={"PYTHONPATH": str(site)},
                          capture_output=True, text=True, check=True).stdout.strip()


def _git(cwd, *args):
    subprocess.run(["git", "-c", "user.name=t", "-c", "user.email=t@t", *args], cwd=cwd,
                   check=True, capture_output=True)


def test_checkout_is_asked_through_git():
    head = subprocess.run(["git", "rev-parse", "--short=12", "HEAD"], cwd=REPO,
                          capture_output=True, text=True).stdout.strip()
    assert version.code_version().split("-")[0] == head


def test_installed_wheel_inside_another_repository_reports_its_stamp(tmp_path):
    _git(tmp_path, "init", "-q")
    (tmp_path / "x").write_text("x")
    _git(tmp_path, "add", "x")
    _git(tmp_path, "commit", "-qm", "enclosing repository")
    site = tmp_path / "env" / "lib" / "site-packages"
    assert _installed_copy(site, "0123456789ab") == "0123456789ab"


def test_installed_without_stamp_is_unknown_not_the_enclosing_commit(tmp_path):
    _git(tmp_path, "init", "-q")
    (tmp_path / "x").write_text("x")
    _git(tmp_path, "add", "x")
    _git(tmp_path, "commit", "-qm", "enclosing repository")
    assert _installed_copy(tmp_path / "site", None) == "unknown"
