"""Build hook: stamp the commit being built into the package.

``integrator_bench.harness.version.code_version`` asks git when the package runs from its
checkout (an editable install). A wheel installed elsewhere, such as the one
asv builds from each benchmarked commit, has no checkout of its own beside it,
and git would answer for whatever repository happens to enclose the
installation. So ``build_py`` writes the commit of the tree being built (with
``-dirty`` for uncommitted changes to tracked files) to
``integrator_bench/harness/_commit.txt`` in the build, never into the source tree.
Everything else is in pyproject.toml.
"""

import subprocess
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

HERE = Path(__file__).resolve().parent


def _git(*args) -> str:
    return subprocess.run(["git", *args], cwd=HERE, capture_output=True, text=True,
                          check=True).stdout.strip()


class BuildPyWithCommit(build_py):
    def run(self):
        super().run()
        try:
            if Path(_git("rev-parse", "--show-toplevel")).resolve() != HERE:
                return  # not a checkout of this project: leave the version unknown
            commit = _git("rev-parse", "--short=12", "HEAD")
            dirty = _git("status", "--porcelain", "--untracked-files=no")
        except (OSError, subprocess.CalledProcessError):
            return
        target = Path(self.build_lib) / "integrator_bench" / "harness" / "_commit.txt"
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text(commit + ("-dirty" if dirty else "") + "\n")


setup(cmdclass={"build_py": BuildPyWithCommit})
