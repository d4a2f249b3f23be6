"""The documentation a reader can use: every relative link of the README and of
docs/ leads to a file of the repository, the README stays a guide (not a lab
notebook), and nothing points at what a clone does not have."""

import re
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
PAGES = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]
LINK = re.compile(r"\[[^\]]+\]\(([^)#\s]+)(?:#[^)]*)?\)")


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_every_relative_link_leads_to_a_file(page):
    text = page.read_text(encoding="utf-8")
    missing = [target for target in LINK.findall(text)
               if "://" not in target and not (page.parent / target).exists()]
    assert not missing, f"{page.name}: {missing}"


def test_the_readme_is_a_guide_of_a_few_hundred_lines():
    lines = (REPO / "README.md").read_text(encoding="utf-8").count("\n")
    assert 100 < lines <= 400, lines


def _tracked_text():
    files = subprocess.run(["git", "ls-files"], cwd=REPO, text=True, capture_output=True,
                           check=True).stdout.split()
    for name in files:
        path = REPO / name
        if path.suffix in (".py", ".md", ".toml", ".json", ".cfg", ".txt", "") and path.is_file():
            try:
                yield name, path.read_text(encoding="utf-8")
            except UnicodeDecodeError:
                continue


def test_nothing_cites_what_a_clone_does_not_have():
    # the tracker's issue numbers and the steering folder's files are not in a clone
    pattern = re.compile(r"\b[Ii]ssues? \d+\b|PROBLEMS\.md|\.\./shared\b")
    found = [f"{name}:{text[:m.start()].count(chr(10)) + 1}: {m.group(0)}"
             for name, text in _tracked_text() if name != "tests/project/test_docs.py"
             for m in pattern.finditer(text)]
    assert not found, found
