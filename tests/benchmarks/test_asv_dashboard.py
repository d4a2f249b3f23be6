"""asv end to end: run, publish offline, open in headless Chromium; history; regression.

The first test runs in CI (a minute or two): asv runs a small suite (:data:`SMOKE`,
one code on each problem) on the installed project (``--python=same``, the
current commit), the dashboard is published with local copies of its
JavaScript and CSS, and Chromium, driven over the DevTools protocol, must load
it with no failed or external request and draw a graph whose plot area is not
blank. The slow tests (``pytest -m slow``) do the same with the README's quick
suite (every problem's graphs, about five minutes), build three commits in
asv's own environments, and let ``tools/regression_demo.py`` show that a
deliberately less accurate integrator is flagged by ``asv continuous``.

Needs Debian's chromium (``.ci/run`` installs it when missing) and npm.
"""

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "tools"))

import dashboard_check  # noqa: E402
import regression_demo  # noqa: E402

# the README's quick suite: ODE and index-3 forms at the loose tolerance; of the chain
# drive, the bushing chain and the CVT chain (over 100 states, left out of the quick
# preset too; an explicit code takes minutes on them) one or two cases each, and of
# the event problems one (CVODE-Adams), so that every problem's graphs exist while the
# suite stays a few minutes (asv runs each of a case's seven benchmarks apart)
QUICK = (r"^cases\.(?!chain_|cvt_|woodpecker|bouncing_ball|n_four_bar).*'(ode|i3)', '[^']+', 'loose'\)"
         r"|n_four_bar:n=2', 'i3', '[^']+', 'loose'\)"
         r"|chain_drive:.*n_links=30,.*'ode', 'scipy-DOP853', 'loose'\)"
         r"|chain_bushing:.*n_links=30,.*'ode', '(cvode-bdf|hht)', 'loose'\)"
         r"|cvt_chain:.*friction=1,.*'ode', 'dumka3', 'loose'\)"
         r"|(woodpecker|bouncing_ball):.*'ode', 'cvode-adams', 'loose'\)")
# the CI's suite: enough benchmarks for a dashboard with graphs, in a minute
# (one code per problem: the summary page asks for every benchmark's graph)
SMOKE = (r"^cases\.(?!chain_|cvt_|n_four_bar).*'ode', 'cvode-bdf', 'loose'\)"
         r"|n_four_bar:n=2', 'i3', 'ida', 'loose'\)"
         r"|chain_drive:.*n_links=30,.*'ode', 'scipy-DOP853', 'loose'\)"
         r"|chain_bushing:.*n_links=30,.*'ode', 'cvode-bdf', 'loose'\)"
         r"|cvt_chain:.*friction=1,.*'ode', 'dumka3', 'loose'\)")
# one combination per problem parameter set: every benchmark gets results
ONE_PER_PROBLEM = r"(?<!n_four_bar:n=40)', 'ode', 'scipy-DOP853', 'loose'\)"


def _need_tools():
    missing = [t for t in ("chromium", "npm", "git") if shutil.which(t) is None]
    if missing and os.environ.get("CI") != "true":
        pytest.skip(f"not installed here: {', '.join(missing)} (CI installs them)")
    assert not missing, f"missing tools: {missing}"


def _asv(*args, cwd, timeout=1800):
    proc = subprocess.run([sys.executable, "-m", "asv", *args], cwd=cwd, text=True,
                          capture_output=True, timeout=timeout)
    assert proc.returncode == 0, f"asv {' '.join(args)} failed:\n{proc.stdout[-4000:]}\n{proc.stderr[-4000:]}"
    return proc.stdout


def _clone(tmp_path) -> Path:
    clone = tmp_path / "clone"
    subprocess.run(["git", "clone", "-q", str(REPO), str(clone)], check=True)
    return clone


def _publish_and_check(clone: Path, screenshot: Path):
    proc = subprocess.run([sys.executable, "tools/publish_offline.py"], cwd=clone,
                          text=True, capture_output=True, timeout=600)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert "loads no external file" in proc.stdout
    html = clone / ".asv" / "html"
    report = dashboard_check.check(html, screenshot=screenshot)
    assert not report.failed, report.failed
    assert not report.external, report.external
    assert not report.errors, report.errors
    assert not report.error_dialog
    assert report.grid_canvases > 0 and report.plot_canvases > 0
    assert report.plot_ink > 0.002 and report.plot_colors >= 3, (report.plot_ink,
                                                                 report.plot_colors)
    assert report.plot_points > 0 and report.series_pixels > 0, (report.plot_points,
                                                                 report.series_pixels)
    assert report.ok
    assert screenshot.stat().st_size > 10_000
    return html


def _run_on_current_commit(tmp_path, suite: str):
    _need_tools()
    clone = _clone(tmp_path)
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=clone, text=True,
                          capture_output=True, check=True).stdout.strip()
    _asv("machine", "--yes", cwd=clone)
    out = _asv("run", "--python=same", "--quick", "-b", suite,
               "--set-commit-hash", head, cwd=clone)
    assert "cases." in out
    return _publish_and_check(clone, tmp_path / "dashboard.png")


def test_small_suite_on_current_commit_dashboard_renders_offline(tmp_path):
    html = _run_on_current_commit(tmp_path, SMOKE)
    assert _revisions_with_data(html, "cases.two_mass.track_nfev") == 1


@pytest.mark.slow
def test_quick_suite_on_current_commit_dashboard_renders_offline(tmp_path):
    _run_on_current_commit(tmp_path, QUICK)


def _revisions_with_data(html: Path, name: str) -> int:
    revisions = set()
    for f in (html / "graphs").rglob(f"{name}.json"):
        if f.parent.name == "summary":
            continue
        for revision, values in json.loads(f.read_text()):
            if any(v is not None for v in (values if isinstance(values, list) else [values])):
                revisions.add(revision)
    return len(revisions)


@pytest.mark.slow
def test_history_of_three_commits_renders_offline(tmp_path):
    _need_tools()
    clone = _clone(tmp_path)
    _asv("machine", "--yes", cwd=clone)
    _asv("run", "--quick", "-b", ONE_PER_PROBLEM, "HEAD~3..HEAD", cwd=clone, timeout=3600)
    html = _publish_and_check(clone, tmp_path / "history.png")
    assert _revisions_with_data(html, "cases.two_mass.track_nfev") >= 3


@pytest.mark.slow
def test_deliberately_less_accurate_integrator_is_flagged(capsys):
    _need_tools()
    status = regression_demo.main(["--kind", "accuracy", "-i", "scipy-RK45", "-p", "two_mass"])
    out = capsys.readouterr().out
    assert status == 0, out[-5000:]
    assert "track_error flagged as a regression" in out


def test_readme_quick_suite_is_the_one_tested():
    readme = (REPO / "README.md").read_text()
    line = next(l for l in readme.splitlines() if l.startswith("Q="))
    assert line.split("=", 1)[1].split("#")[0].strip() == f'"{QUICK}"'
