"""The folder -> package mapping is stated once (harness/layout.py) and agrees with the
build's own statement of it (pyproject.toml)."""

import tomllib
from pathlib import Path

from integrator_bench.harness import layout

REPO = Path(__file__).resolve().parents[2]


def test_the_layout_is_the_builds():
    conf = tomllib.loads((REPO / "pyproject.toml").read_text())
    package_dir = conf["tool"]["setuptools"]["package-dir"]
    code = {package: folder for package, folder in package_dir.items()
            if folder in layout.FOLDERS}
    assert code == {package: folder for folder, package in layout.FOLDERS.items()}
    assert conf["project"]["name"] == layout.DISTRIBUTION
    for folder, package in layout.FOLDERS.items():
        assert (REPO / folder / "__init__.py").is_file(), folder
        assert package.startswith(layout.ROOT + ".")

