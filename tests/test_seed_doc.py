"""docs/seed-numbers.md is generated, not hand-copied: it is the page "The sources,
number by number" of the records embedded at its end (harness/report/sources.py,
``document``), it names the code that ran them, and no row of it is marked explained
without its measuring run."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from integrator_bench.harness.matrix import source_numbers as sn
from integrator_bench.harness.report import sources, write_report

DOC = Path(__file__).resolve().parents[1] / "docs" / "seed-numbers.md"


@pytest.fixture(scope="module")
def doc():
    text = DOC.read_text(encoding="utf-8")
    return text, sources.records_of(text)


def test_the_document_is_the_page_of_its_own_records(doc):
    text, records = doc
    assert len(records) > 50
    assert sources.document(records) == text


def test_the_document_names_the_commit_that_ran_its_records(doc):
    text, records = doc
    (line,) = [x for x in text.splitlines() if x.startswith("Run by code ")]
    named = re.findall(r"[0-9a-f]{12}(?:-dirty)?", line)
    assert named and set(named) == set(records["code_version"].dropna())
    assert not any(n.endswith("-dirty") for n in named)


def test_no_row_is_explained_without_its_measuring_run(doc):
    _, records = doc
    for c in sn.compare(records):
        if c.verdict == "differs, cause measured":
            assert c.row.cause is not None
            case = sn.cause_case(c.row.cause, records)
            assert case == c.cause_case and sn.usable(sn.match(records, *case))
            assert c.measured


def test_the_summary_counts_the_five_verdicts(doc):
    text, _ = doc
    caption = next(x for x in text.splitlines() if re.match(r"\d+ rows: ", x))
    assert all(f" {v}" in caption for v in sn.VERDICTS)


def test_the_ics_alpha_is_the_sweeps_choice_by_the_papers_two_indicators(doc):
    """The tuned alpha is admissible (every TOL ran), has the least rank sum of
    constraint violation and failed steps, and the ICS rows' cause runs use it."""
    _, records = doc
    for problem in sn.ICS_PROBLEMS:
        t = sn.tune_alpha(records, problem)
        assert t.chosen is not None and all(t.runs[t.chosen].values())
        assert t.rank_sum[t.chosen] == min(t.rank_sum.values())
        ics = [c for c in sn.compare(records) if c.row.problem == problem
               and c.row.row.startswith("ICS") and c.cause_case is not None]
        assert ics and all(f"baumgarte_alpha={t.chosen:g}" in c.cause_case[0] for c in ics)


def test_the_report_writes_the_document_of_its_records(doc, tmp_path):
    """``ibench report`` makes the part and ``sources.md`` (what this file is copied
    from) on one of the processes that draw the problems' pages: the file is
    :func:`sources.document` of the records, and ``index.md`` has the part."""
    _, records = doc
    some = records[records["problem"].isin(["squeezer", "two_mass"])].reset_index(drop=True)
    files = write_report(some, tmp_path, scaling_dir=tmp_path / "none", jobs=2)
    written = (tmp_path / "sources.md").read_text(encoding="utf-8")
    assert tmp_path / "sources.md" in files and written == sources.document(some)
    assert "## The sources, number by number" in (tmp_path / "index.md").read_text(
        encoding="utf-8")
