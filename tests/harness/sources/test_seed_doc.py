"""docs/seed-numbers.md is generated, not hand-copied: it is the page "The sources,
number by number" of the records embedded at its end (harness/sources/page.py,
``document``), it names the code that ran them, and no row of it is marked explained
without its measuring run."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pandas as pd
import pytest

import math

from integrator_bench.harness.report import write_report
from integrator_bench.harness.sources import claims, numbers as sn, page

DOC = Path(__file__).resolve().parents[3] / "docs" / "seed-numbers.md"


def records_of(text: str) -> pd.DataFrame:
    """The records embedded in a :func:`page.document`."""
    _, _, rest = text.partition(page.DOC_RECORDS)
    body = rest.split("```json", 1)[1].split("```", 1)[0]
    return pd.DataFrame(json.loads(body))


@pytest.fixture(scope="module")
def doc():
    text = DOC.read_text(encoding="utf-8")
    return text, records_of(text)


def test_the_document_is_the_page_of_its_own_records(doc):
    text, records = doc
    assert len(records) > 50
    assert page.document(records) == text


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


def test_the_summary_counts_the_six_verdicts(doc):
    text, _ = doc
    caption = next(x for x in text.splitlines() if re.match(r"\d+ rows: ", x))
    assert all(f" {v}" in caption for v in sn.VERDICTS) and len(sn.VERDICTS) == 6


def test_the_page_states_its_rule(doc):
    text, _ = doc
    stated = page.rule_text()
    assert markdown_escaped(stated) in text
    assert all(sn.RULE[v] and markdown_escaped(sn.RULE[v]) in text for v in sn.VERDICTS)


def markdown_escaped(text: str) -> str:
    from integrator_bench.harness.report import markdown
    return markdown.escaped(text)


def _rule_for_a_row(c) -> str:
    """A table row's verdict from :data:`sn.RULE`, recomputed from its figures."""
    if c.row.not_run or not c.ours or c.row.ratios_only:
        return "cannot test"
    judged = [k for k in sn.JUDGED if k in c.ratios]
    if not judged:
        return "cannot test"
    if all(abs(c.ours[k] / c.row.published[k] - 1) <= sn.AGREE for k in judged):
        return "agrees"
    ok = not c.status.startswith("ran to the end") and not c.cause_note
    moved = [k for k in judged if k in c.measured_ratios]
    if c.row.cause is None or not ok or not moved or "no evidence" in c.status:
        return "differs, unexplained"
    if all(abs(c.measured_ratios[k] - 1) <= sn.AGREE for k in moved):
        return "differs, cause measured"
    if all(abs(math.log(c.measured_ratios[k])) < abs(math.log(c.ratios[k])) for k in moved):
        return "differs, cause explains part"
    return "differs, unexplained"


def test_every_row_of_the_page_holds_to_the_stated_rule(doc):
    """Each table row, each judged ratio between codes, each seed 000 ratio, each
    speed-up and cell, and each headline claim: the verdict the stated rule gives
    from the figures shown is the one on the page."""
    from integrator_bench.harness.ranking.records import clean_records
    records = clean_records(page._doc_records(doc[1]))
    compared = sn.compare(records)
    for c in compared:
        assert c.verdict == _rule_for_a_row(c), c.row.row
        assert all(c.ratios[k] == c.ours[k] / c.row.published[k] for k in c.ratios)
        if c.verdict == "differs, cause measured":
            assert "cause explains part" not in c.status
    judged = {r[1]: r[-1] for r in sn.within_table_ratios(compared) if r[-1] != "–"}
    for c in compared:
        if c.row.ratios_only and c.row.row in judged:     # each code over the table's first
            base = next(b for b in compared if b.row.table == c.row.table)
            inside = [abs((c.ours[k] / base.ours[k])
                          / (c.row.published[k] / base.row.published[k]) - 1) <= sn.AGREE
                      for k in sn.JUDGED]
            assert judged.pop(c.row.row) == ("agrees" if all(inside)
                                             else "differs, unexplained")
    assert not judged         # only rows whose counts cannot agree are judged by ratios
    ratios = page.compare_ratios(records)
    for c in ratios:
        cpu = [v for v, how in [*c.matched.values(), (c.at_tol, "=")]
               if how == "=" and not math.isnan(v)]
        upper = [v for v, how in c.matched.values() if how == "≤"]
        if c.verdict == "contradicts":
            assert cpu + upper and all(v < 1 for v in cpu + upper)
        if cpu and all(v < 1 for v in cpu + upper):
            assert c.verdict == "contradicts"     # whatever the counts and work say
    orlov = page.compare_orlov(records)
    for c in orlov:
        ends = [c.edge_cpu, c.cpu]
        inside = [abs(v / c.published - 1) <= sn.AGREE for v in ends]
        if c.verdict == "agrees":
            assert all(inside)
        if c.verdict == "differs, unexplained":
            assert not any(inside) and all(v > 1 for v in ends)
            assert (min(ends) > c.published) == (max(ends) > c.published)
    cells = page.compare_cells(records)
    assert all(c.verdict == "cannot test" for c in cells if c.slides == "untested")
    heads = {(r[0], r[1][:20]): r[-1] for r in
             claims.claims(records, compared, ratios, orlov, cells)}
    assert all(v in sn.VERDICTS for v in heads.values())
    by_seed = {r[0]: r[-1] for r in claims.claims(records, compared, ratios, orlov,
                                                         cells)}
    assert by_seed["000"] == sn.combine([c.verdict for c in ratios])
    assert by_seed["004 (slides)"] == sn.combine([c.verdict for c in orlov])


def test_the_seminars_headline_reads_contradicts_with_its_measured_ratios(doc):
    text, _ = doc
    (line,) = [x for x in text.splitlines() if x.startswith("| 000 | the index-3")]
    assert line.endswith("| contradicts |")
    assert "cause unknown" in line
    # reversed on every measure it shows: each range's largest ratio below 1
    for measure in ("CPU", "work"):
        low, high = map(float, re.search(rf"{measure} ([\d.]+)-([\d.]+)", line).groups())
        assert low <= high < 1
    assert "compiled C" not in text and "one CPU of then" not in text
    assert "a 3-D model" not in text


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
    """``ibench report`` hands the report the sources' part (:func:`page.appendix`),
    made with ``sources.md`` (what this file is copied from) on one of the processes
    that draw the problems' pages: the file is :func:`page.document` of the
    records, and ``index.md`` has the part. The report alone knows no source."""
    from integrator_bench.harness.cli import main
    from integrator_bench.harness.matrix.store import Store, load

    _, records = doc
    some = records[records["problem"].isin(["squeezer", "two_mass"])].reset_index(drop=True)
    store, out = tmp_path / "s.sqlite", tmp_path / "report"
    with Store(store) as db:
        for i, record in enumerate(some.to_dict("records")):
            db.add({**record, "case_id": f"case{i}"})
    assert main(["report", "--store", str(store), "--out", str(out)]) == 0
    written = (out / "sources.md").read_text(encoding="utf-8")
    assert written == page.document(load(store)) == page.document(some)
    assert "## The sources, number by number" in (out / "index.md").read_text(
        encoding="utf-8")
    files = write_report(some, tmp_path / "alone", scaling_dir=tmp_path / "none", jobs=2)
    assert tmp_path / "alone" / "sources.md" not in files
    assert "## The sources" not in (tmp_path / "alone" / "index.md").read_text(
        encoding="utf-8")


@pytest.mark.parametrize("seed, claim", [
    ("002", "hits the bar 21 times"), ("002", "Lsodar is also the one"),
    ("002", "A higher order means more function evaluations"),
    ("004", "Newton's iterations"), ("004", "W-method"), ("001", "While slower")])
def test_every_claim_of_the_sources_is_on_the_page_with_its_verdict(doc, seed, claim):
    text, _ = doc
    (line,) = [x for x in text.splitlines() if x.startswith(f"| {seed} |") and claim in x]
    verdict = line.rstrip(" |").rpartition("| ")[2]
    assert verdict in sn.VERDICTS
    if verdict == "cannot test":        # and why, in the row
        assert any(w in line for w in ("not run", "lost"))


def test_the_cvt_study_quotes_the_pages_speed_ups(doc):
    """docs/study-cvt.md's speed-ups at Orlov's criterion are the page's, from its
    records (:func:`page.orlov_quote`)."""
    from integrator_bench.harness.ranking.records import clean_records
    _, records = doc
    quote = page.orlov_quote(clean_records(page._doc_records(records)))
    study = (DOC.parent / "study-cvt.md").read_text(encoding="utf-8")
    assert quote and " ".join(quote.split()) in " ".join(study.split())
