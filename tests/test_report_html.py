"""The HTML report opened in headless Chromium (skipped when chromium is absent).

Drives Chromium with tools/dashboard_check.py's DevTools client; the page
is opened from file://, as a reader opens it offline.
"""

from __future__ import annotations

import base64
import os
import shutil
import sys
import time
from pathlib import Path
from urllib.parse import unquote, urlparse

import pandas as pd
import pytest

from integrator_bench.harness.model.record import FIELDS
from integrator_bench.harness.report import write_report

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))
import dashboard_check as dc  # noqa: E402

from test_report import NO_SCALING, make_records  # noqa: E402

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
LINKS = "Array.from(document.querySelectorAll('a[href]')).map(a => a.getAttribute('href'))"
IMAGES = ("Array.from(document.images).map(i => [i.getAttribute('src'), i.complete, "
          "i.naturalWidth])")


def open_page(html: Path, screenshot: Path):
    """Open ``html`` from file://; return (report, images, links) and write a
    full-page screenshot."""
    report = dc.Report()
    url = html.resolve().as_uri()
    with dc.browser(CHROMIUM) as ws_url:
        dt = dc.DevTools(ws_url)
        try:
            session = dc.new_page(dt)
            dt.send("Page.navigate", {"url": url}, session)
            dc._wait_for(dt, session, "document.readyState === 'complete'")
            time.sleep(0.5)
            images = dc._evaluate(dt, session, IMAGES)
            links = dc._evaluate(dt, session, LINKS)
            shot = dt.send("Page.captureScreenshot",
                           {"format": "png", "captureBeyondViewport": True}, session)
            screenshot.write_bytes(base64.b64decode(shot["data"]))
            dt.send("Runtime.evaluate", {"expression": "1"}, session)  # flush events
        finally:
            dt.close()
    dc._collect(dt.events, html.parent.resolve().as_uri() + "/", report)
    return report, images, links


def broken_links(html: Path, links: list[str], anchors: set[str]) -> list[str]:
    """Links to a missing file beside the page or to a missing anchor."""
    bad = []
    for href in links:
        parsed = urlparse(href)
        if parsed.scheme:
            bad.append(href)                     # nothing may leave the page's folder
        elif href.startswith("#"):
            if href[1:] not in anchors:
                bad.append(href)
        elif not (html.parent / unquote(parsed.path)).is_file():
            bad.append(href)
    return bad


@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed")
def test_page_renders_offline(tmp_path):
    import re

    write_report(make_records(), tmp_path, scaling_dir=NO_SCALING)
    html = tmp_path / "index.html"
    shots = Path(os.environ.get("IBENCH_SCREENSHOT_DIR", tmp_path))
    shots.mkdir(parents=True, exist_ok=True)
    report, images, links = open_page(html, shots / "report_synthetic.png")
    assert report.requests and not report.failed and not report.external, report
    assert not report.errors
    # one figure per problem, and the summary's performance profiles by CPU and by work
    assert len(images) == 5 and [i[0] for i in images[:2]] == ["profiles.png",
                                                               "profiles_work.png"]
    assert all(complete and width > 100 for _, complete, width in images), images
    anchors = set(re.findall(r'id="([^"]+)"', html.read_text(encoding="utf-8")))
    assert len(links) > 6
    assert broken_links(html, links, anchors) == []


def test_page_has_no_script_and_defines_metrics(tmp_path):
    write_report(make_records(), tmp_path, scaling_dir=NO_SCALING)
    text = (tmp_path / "index.html").read_text(encoding="utf-8")
    assert "<script" not in text and "http://" not in text and "https://" not in text
    for term in ("<b>mescd</b>", "<b>drift</b>", "<b>NF</b>", "<b>NS</b>", "<b>NJ</b>",
                 "CPU seconds to reach a target error; the error is the largest mixed error",
                 "The grey band is the Pareto front"):
        assert term in text
    # the failure map shows the failed case's message on hover
    assert 'title="rtol=1e-12: failed — Required step size' in text


def test_empty_store_writes_a_page(tmp_path):
    paths = write_report(pd.DataFrame(columns=list(FIELDS)), tmp_path, scaling_dir=NO_SCALING)
    assert [p.name for p in paths] == ["index.md", "index.html"]
    assert "<h1>" in paths[1].read_text(encoding="utf-8")
