"""tests/ mirrors the house (docs/layout.md, "Tests"): the tests of every package of
problems/, integrators/ and harness/ live in the folder of the same path under tests/,
and every other folder of tests/ is one the map names."""

from __future__ import annotations

from pathlib import Path

from integrator_bench.harness.layout import FOLDERS

REPO = Path(__file__).resolve().parents[2]
TESTS = REPO / "tests"
#: folders of tests/ that mirror no package: what each holds (docs/layout.md, "Tests")
OTHER = {
    "project": "the repository as a whole: docs, layout, import graph, signatures, the wheel",
    "benchmarks": "the asv suite, its environment and dashboard",
    "studies": "the study scripts of studies/",
    "integration": "stories through several packages: one answer, scores, large runs",
    "data": "stored files the tests read",
}


def packages() -> list[str]:
    """Every package folder of the three, as a path from the checkout's root."""
    return sorted(str(init.parent.relative_to(REPO)) for folder in FOLDERS
                  for init in (REPO / folder).rglob("__init__.py")
                  if "__pycache__" not in init.parts)


def test_every_package_has_its_tests_in_the_mirrored_folder():
    missing = [p for p in packages() if not any((TESTS / p).glob("test_*.py"))]
    assert not missing, f"packages without tests in tests/<same path>/: {missing}"


def test_every_folder_of_tests_mirrors_a_package_or_is_on_the_map():
    mirrored = set(packages())
    folders = {str(d.relative_to(TESTS)) for d in TESTS.rglob("*") if d.is_dir()
               and any(d.glob("test_*.py"))}
    stray = sorted(f for f in folders if f not in mirrored and f.split("/")[0] not in OTHER)
    assert not stray, f"test folders that mirror no package and are not on the map: {stray}"
    assert not list(TESTS.glob("test_*.py")), "a test file at the top of tests/: give it its folder"


def test_the_map_is_the_documented_one():
    page = (REPO / "docs" / "layout.md").read_text()
    for folder in OTHER:
        assert f"`tests/{folder}/`" in page, folder
