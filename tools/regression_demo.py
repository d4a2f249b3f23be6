"""Show that ``asv continuous`` flags a deliberate regression.

In a throwaway clone of the repository's HEAD, a temporary commit makes one
integrator worse, then ``asv continuous HEAD~1 HEAD`` benchmarks both commits
(each built and installed in asv's own environment) on that integrator's cases
of one problem:

``--kind accuracy`` (default)
    the integrator's tolerances are scaled by 100: fewer steps and function
    evaluations, two digits less accuracy. ``track_error`` (10**-scd) must be
    flagged.
``--kind slower``
    after each solve the integrator burns as much CPU time again: counts and
    errors unchanged, ``time_solve`` doubles and must be flagged.

The change is appended to the module that registers the integrator (found
through the entry points of pyproject.toml), so it works for any registered
adaptive integrator. Prints asv's report and exits 0 when the regression was
flagged, 1 when it was not. Nothing is written to the repository.

    python tools/regression_demo.py [--kind accuracy|slower] [-i scipy-RK45] [-p two_mass]
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import tempfile
import tomllib
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

PATCHES = {
    "accuracy": '''

# --- deliberate regression (tools/regression_demo.py): tolerances x 100
def _sloppy(solve):
    def solve_loosely(self, system, *, rtol=None, atol=None, h=None):
        return solve(self, system, rtol=None if rtol is None else rtol * 100,
                     atol=None if atol is None else atol * 100, h=h)
    return solve_loosely


{cls}.solve = _sloppy({cls}.solve)
''',
    "slower": '''

# --- deliberate regression (tools/regression_demo.py): twice the CPU time
def _slow(solve):
    import time

    def solve_slowly(self, system, **kw):
        start = time.process_time()
        sol = solve(self, system, **kw)
        spent = time.process_time() - start
        while time.process_time() - start < 2 * spent:
            sum(i * i for i in range(1000))
        return sol
    return solve_slowly


{cls}.solve = _slow({cls}.solve)
''',
}
FLAGGED = {"accuracy": "track_error", "slower": "time_solve"}


def run(cmd, cwd, check=True):
    print("$", " ".join(cmd), flush=True)
    return subprocess.run(cmd, cwd=cwd, check=check, text=True)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--kind", choices=sorted(PATCHES), default="accuracy")
    parser.add_argument("-i", "--integrator", default="scipy-RK45")
    parser.add_argument("-p", "--problem", default="two_mass")
    parser.add_argument("--keep", action="store_true", help="keep the throwaway clone")
    args = parser.parse_args(argv)

    targets = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["entry-points"][
        "integrator_bench.integrators"]
    if args.integrator not in targets:
        print(f"regression_demo: unknown integrator {args.integrator!r}; valid: "
              f"{', '.join(targets)}", file=sys.stderr)
        return 2
    module, _, cls = targets[args.integrator].partition(":")
    work = Path(tempfile.mkdtemp(prefix="ibench-regression-"))
    clone = work / "clone"
    run(["git", "clone", "-q", str(REPO), str(clone)], cwd=work)
    source = clone / (module.replace(".", "/") + ".py")
    source.write_text(source.read_text() + PATCHES[args.kind].format(cls=cls))
    git = ["git", "-c", "user.name=regression-demo", "-c", "user.email=demo@localhost"]
    run(git + ["commit", "-q", "-am", f"deliberate regression ({args.kind}) in {args.integrator}"],
        cwd=clone)

    asv = [sys.executable, "-m", "asv"]
    run(asv + ["machine", "--yes"], cwd=clone)
    selection = rf"cases\.{args.problem}\..*'{re.escape(args.integrator)}', '[a-z]+'\)"
    options = ["--quick"] if args.kind == "accuracy" else ["-a", "repeat=(5,10,30)"]
    proc = subprocess.run(asv + ["continuous", *options, "-b", selection, "--factor", "1.3",
                                 "--show-stderr", "HEAD~1", "HEAD"],
                          cwd=clone, text=True, capture_output=True)
    # asv's comparison table and verdict (its per-benchmark tables are long)
    report = [line for line in proc.stdout.splitlines()
              if line.startswith("|") or line.isupper() or "asv:" in line]
    print("\n".join(report) or proc.stdout[-8000:])
    if proc.returncode not in (0, 1):
        print(proc.stdout[-8000:] + proc.stderr[-3000:], file=sys.stderr)
    # asv's table (GitHub format): "| +  | before | after | ratio | benchmark(params) |"
    flagged = proc.returncode == 1 and re.search(
        rf"^\|?\s*\+\s*\|.*\.{FLAGGED[args.kind]}\(", proc.stdout, re.M) is not None
    print(f"asv continuous exited {proc.returncode}; {FLAGGED[args.kind]} "
          f"{'flagged as a regression' if flagged else 'NOT flagged'}")
    if not args.keep:
        subprocess.run(["rm", "-rf", str(work)])
    return 0 if flagged else 1


if __name__ == "__main__":
    sys.exit(main())
