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

from integrator_bench.harness.matrix.record import FIELDS
from integrator_bench.harness.report import write_report

sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "tools"))
import dashboard_check as dc  # noqa: E402

from test_report import NO_SCALING, make_records  # noqa: E402
from records_frame import records_frame

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


def test_page_loads_only_its_own_script_and_defines_metrics(tmp_path):
    import re

    write_report(make_records(), tmp_path, scaling_dir=NO_SCALING)
    text = (tmp_path / "index.html").read_text(encoding="utf-8")
    assert "http://" not in text and "https://" not in text
    # one script file, plotly.js beside the page (the plotly package's own), and inline ones
    assert re.findall(r'<script src="([^"]+)"', text) == ["plotly.min.js"]
    from plotly.offline import get_plotlyjs
    assert (tmp_path / "plotly.min.js").read_text(encoding="utf-8") == get_plotlyjs()
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


def many_lines() -> pd.DataFrame:
    """spring_pendulum under every registered integrator of the ode form that takes
    it (thirty lines and more), three tolerances each, every line at its own
    errors and CPU."""
    from integrator_bench.harness.matrix import registry
    from test_report import ok_row

    rows = []
    names = sorted(registry.integrators())
    for n, name in enumerate(names):
        for i, rtol in enumerate((1e-3, 1e-5, 1e-7)):
            digits = 3 + 2 * i + n / len(names)
            rows.append(ok_row(name, rtol, digits, cpu_s=1e-3 * (1 + n) * 3 ** i))
    rows.append(ok_row(names[0], 1e-9, 0, status="failed", mescd=None, scd=None,
                       err_max=None, cpu_s=0.2, message="<b>step</b> size too small"))
    return records_frame(rows)


HOVER_SCRIPT = """(() => {
  const gd = document.querySelector('.families').nextElementSibling;
  const traces = gd.querySelectorAll('.scatterlayer .trace');
  const k = %d;
  const point = traces[k].querySelectorAll('.point')[1].getBoundingClientRect();
  return [point.x + point.width / 2, point.y + point.height / 2, gd.data[k].meta.line];
})()"""
STATE_SCRIPT = """(() => {
  const gd = document.querySelector('.families').nextElementSibling;
  const legend = gd.querySelector('.legend').getBoundingClientRect();
  const area = gd.querySelector('.nsewdrag').getBoundingClientRect();
  const lines = gd.data.filter(t => t.meta && t.meta.family);
  const fams = {};
  lines.forEach(t => { fams[t.meta.family] = (fams[t.meta.family] || []).concat(
    [t.visible === undefined || t.visible === true]); });
  return {lines: lines.length, fams: fams, legendLeft: legend.left, areaRight: area.right,
          plots: document.querySelectorAll('.js-plotly-plot').length,
          hover: (gd.querySelector('.hoverlayer') || {}).textContent || ''};
})()"""


#: every interactive figure of the page drawn (its plot area there)
DRAWN = ("document.querySelectorAll('.plot').length > 0 && Array.from(document."
         "querySelectorAll('.plot')).every(d => d.querySelector('.nsewdrag'))")
#: the work-precision figure shows a hover label
HOVERED = ("document.querySelector('.families').nextElementSibling"
           ".querySelector('.hoverlayer').textContent")


def _click(dt, session, x, y):
    for kind in ("mouseMoved", "mousePressed", "mouseReleased"):
        dt.send("Input.dispatchMouseEvent", {"type": kind, "x": x, "y": y, "button": "left",
                                             "clickCount": 1}, session)


@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed")
def test_interactive_figures_hover_and_toggle_a_family_offline(tmp_path):
    """The work-precision figure of thirty lines and more in headless Chromium: every
    line drawn, the legend right of the plot area, a hovered point names its line,
    rtol, CPU and error, and a family's button hides then shows its lines alone."""
    write_report(many_lines(), tmp_path, scaling_dir=NO_SCALING)
    html = tmp_path / "index.html"
    report = dc.Report()
    with dc.browser(CHROMIUM) as ws_url:
        dt = dc.DevTools(ws_url)
        try:
            session = dc.new_page(dt, 1400, 1000)
            dt.send("Page.navigate", {"url": html.resolve().as_uri()}, session)
            # every figure drawn (plotly draws them one after the other: slow under load)
            assert dc._wait_for(dt, session, DRAWN, timeout=120)
            dc._evaluate(dt, session, "(() => { const f = document.querySelector('.families');"
                         " window.scrollTo(0, f.getBoundingClientRect().top + window.scrollY"
                         " - 20); return window.scrollY; })()")
            state = dc._evaluate(dt, session, STATE_SCRIPT)
            assert state["lines"] >= 30 and state["plots"] >= 2, state
            assert state["legendLeft"] >= state["areaRight"], state     # legend outside
            assert set(state["fams"]) >= {"explicit", "implicit"}, state
            # hover the second point of the tenth line (a real mouse move), the point's
            # place read again before each try (a figure may still be laid out)
            hover, end = "", time.monotonic() + 60
            while not hover and time.monotonic() < end:
                x, y, label = dc._evaluate(dt, session, HOVER_SCRIPT % 10)
                for dx in (3, 0):   # into the plot area, then onto the point
                    dt.send("Input.dispatchMouseEvent", {"type": "mouseMoved", "x": x + dx,
                                                         "y": y}, session)
                dc._wait_for(dt, session, HOVERED, timeout=5)
                hover = dc._evaluate(dt, session, STATE_SCRIPT)["hover"]
            assert label in hover and "rtol 1e-05" in hover, hover
            assert "CPU" in hover and "error" in hover, hover
            # a family's button hides its lines, and only those; a second click shows them
            button = dc._evaluate(dt, session, "(() => { const b = Array.from(document."
                                  "querySelectorAll('.families button')).find(b => "
                                  "b.textContent === 'Explicit'); const r = b."
                                  "getBoundingClientRect(); return [r.x + r.width / 2, "
                                  "r.y + r.height / 2]; })()")
            _click(dt, session, *button)
            dc._wait_for(dt, session, f"(() => {{ const f = {STATE_SCRIPT}.fams; return "
                         "!f.explicit.some(v => v); })()", timeout=30)
            fams = dc._evaluate(dt, session, STATE_SCRIPT)["fams"]
            assert not any(fams["explicit"]) and all(fams["implicit"]), fams
            _click(dt, session, *button)
            dc._wait_for(dt, session, f"(() => {{ const f = {STATE_SCRIPT}.fams; return "
                         "Object.values(f).every(v => v.every(x => x)); })()", timeout=30)
            fams = dc._evaluate(dt, session, STATE_SCRIPT)["fams"]
            assert all(all(v) for v in fams.values()), fams
            dt.send("Runtime.evaluate", {"expression": "1"}, session)  # flush events
        finally:
            dt.close()
    dc._collect(dt.events, html.parent.resolve().as_uri() + "/", report)
    assert report.requests and not report.failed and not report.external, report
    assert not report.errors, report.errors
