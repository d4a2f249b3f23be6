"""Open a published asv dashboard in headless Chromium and check that its graphs render.

The dashboard is served from 127.0.0.1 (asv's page reads its data with
XMLHttpRequest, which Chromium refuses for file:// pages); Chromium is driven
through the DevTools protocol (``websocket-client``), which reports every
request the page makes. The check fails on a request that failed or that left
the local server (the dashboard must render with no internet), on a script
error, on asv's "failed to load" dialog, and when the screenshot of the plot
area of a benchmark's graph is blank.

    python tools/dashboard_check.py [HTML_DIR] [--benchmark NAME] [--screenshot PNG]

Needs Debian's ``chromium`` (``apt-get install -y chromium``).
"""

from __future__ import annotations

import argparse
import base64
import contextlib
import functools
import http.server
import io
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--hide-scrollbars", "--window-size=1280,900", "--remote-debugging-port=0")
PLOT = "#main-graph canvas.flot-base"


@dataclass
class Report:
    requests: list = field(default_factory=list)
    failed: list = field(default_factory=list)
    external: list = field(default_factory=list)
    errors: list = field(default_factory=list)
    plot_canvases: int = 0
    grid_canvases: int = 0
    error_dialog: bool = False
    plot_ink: float = 0.0  # fraction of plot-area pixels that are not background
    plot_colors: int = 0
    plot_points: int = 0  # data points flot holds for the graph
    series_pixels: int = 0  # plot-area pixels in a series' color (legend hidden)

    @property
    def ok(self) -> bool:
        return (not self.failed and not self.external and not self.errors
                and not self.error_dialog and self.plot_canvases > 0 and self.grid_canvases > 0
                and self.plot_ink > 0.002 and self.plot_colors >= 3
                and self.plot_points > 0 and self.series_pixels > 0)


class _Quiet(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args):
        pass


class DevTools:
    """A minimal DevTools protocol client over one websocket."""

    def __init__(self, ws_url: str):
        import websocket

        self.ws = websocket.create_connection(ws_url, timeout=60, suppress_origin=True)
        self.next_id, self.events = 0, []

    def send(self, method, params=None, session=None, timeout=60.0):
        self.next_id += 1
        msg = {"id": self.next_id, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = session
        self.ws.send(json.dumps(msg))
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            reply = json.loads(self.ws.recv())
            if reply.get("id") == self.next_id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply.get("result", {})
            self.events.append(reply)
        raise TimeoutError(method)

    def close(self):
        self.ws.close()


@contextlib.contextmanager
def browser(chromium: str):
    """Start headless ``chromium`` on a throw-away profile; yield its DevTools
    websocket URL.

    Chromium runs in its own process group, and on exit the whole group (the
    browser, its GPU, renderer and crash-handler children) is killed and reaped
    before the profile is removed: a child still writing to the profile would
    otherwise make the removal fail.
    """
    with tempfile.TemporaryDirectory(ignore_cleanup_errors=True) as profile:
        proc = subprocess.Popen([chromium, *FLAGS, f"--user-data-dir={profile}", "about:blank"],
                                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                                start_new_session=True)
        try:
            yield _devtools_url(proc, chromium)
        finally:
            try:
                os.killpg(proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            proc.wait(10)
            time.sleep(0.2)  # children of the group exit after the leader


def _devtools_url(proc, chromium: str) -> str:
    end = time.monotonic() + 60
    for line in proc.stderr:
        if "DevTools listening on" in line:
            threading.Thread(target=proc.stderr.read, daemon=True).start()  # keep draining
            return line.split("listening on", 1)[1].strip()
        if time.monotonic() > end:
            break
    raise RuntimeError(f"{chromium} did not start its DevTools endpoint")


def new_page(dt, width: int = 1280, height: int = 900) -> str:
    """A new blank page of ``width`` x ``height`` pixels with the Network, Page and
    Runtime events on; returns its DevTools session id."""
    target = dt.send("Target.createTarget", {"url": "about:blank"})["targetId"]
    session = dt.send("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
    for domain in ("Network", "Page", "Runtime"):
        dt.send(f"{domain}.enable", session=session)
    dt.send("Emulation.setDeviceMetricsOverride",
            {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": False}, session)
    return session


def _evaluate(dt, session, expression):
    return dt.send("Runtime.evaluate", {"expression": expression, "returnByValue": True},
                   session)["result"].get("value")


def _wait_for(dt, session, expression, timeout=30.0) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if _evaluate(dt, session, expression):
            return True
        time.sleep(0.25)
    return False


def _ink(png: bytes) -> tuple[float, int]:
    """Fraction of non-background pixels and number of distinct colors of a PNG."""
    import matplotlib.image

    rgb = (matplotlib.image.imread(io.BytesIO(png), format="png")[..., :3] * 255).round()
    pixels = rgb.reshape(-1, 3).astype(int)
    colors, counts = np.unique(pixels, axis=0, return_counts=True)
    background = colors[np.argmax(counts)]
    return float(np.mean(np.any(pixels != background, axis=1))), len(colors)


def graph_page(html_dir: Path, benchmark: str | None = None) -> str:
    """The URL fragment of a benchmark's graph, on its parameter combination with most data.

    Default benchmark: the first ``time_solve`` benchmark that has results.
    """
    from urllib.parse import quote

    index = json.loads((html_dir / "index.json").read_text())["benchmarks"]
    names = [benchmark] if benchmark else sorted(
        index, key=lambda n: (".time_solve" not in n, n))
    for name in names:
        files = [f for f in (html_dir / "graphs").rglob(f"{name}.json")
                 if f.parent.name != "summary"]
        if not files:
            continue
        info = index[name]
        if not info["params"]:
            return f"#{name}"
        counts = None
        for f in files:
            for _, values in json.loads(f.read_text()):
                have = np.array([v is not None for v in values], int)
                counts = have if counts is None else counts + have
        if counts is None or counts.max() == 0:
            continue
        combo = np.unravel_index(int(np.argmax(counts)), [len(p) for p in info["params"]])
        query = "&".join(f"p-{quote(n)}={quote(info['params'][k][i])}"
                         for k, (n, i) in enumerate(zip(info["param_names"], combo)))
        return f"#{name}?{query}"
    raise RuntimeError(f"no benchmark with results in {html_dir}")


def _rgb(color: str):
    """``#rrggbb`` or ``rgb(r, g, b)`` as a tuple of ints, or None."""
    color = (color or "").strip()
    if color.startswith("#") and len(color) == 7:
        return tuple(int(color[i:i + 2], 16) for i in (1, 3, 5))
    if color.startswith("rgb"):
        return tuple(int(float(v)) for v in color[color.index("(") + 1:-1].split(",")[:3])
    return None


def _series_pixels(png: bytes, colors) -> int:
    """Pixels of a PNG within a small distance of one of the series colors."""
    import matplotlib.image

    rgb = (matplotlib.image.imread(io.BytesIO(png), format="png")[..., :3] * 255).round()
    total = 0
    for color in filter(None, map(_rgb, colors)):
        total += int(np.sum(np.max(np.abs(rgb - np.array(color)), axis=-1) <= 40))
    return total


def check(html_dir: Path, benchmark: str | None = None, screenshot: Path | None = None,
          chromium: str | None = None) -> Report:
    """Open ``html_dir``'s dashboard, the summary grid then one benchmark's graph."""
    chromium = chromium or shutil.which("chromium") or shutil.which("chromium-browser")
    if not chromium:
        raise RuntimeError("chromium not found: apt-get install -y chromium")
    html_dir = Path(html_dir).resolve()
    page = graph_page(html_dir, benchmark)
    server = http.server.ThreadingHTTPServer(
        ("127.0.0.1", 0), functools.partial(_Quiet, directory=str(html_dir)))
    threading.Thread(target=server.serve_forever, daemon=True).start()
    base = f"http://127.0.0.1:{server.server_address[1]}/"
    report = Report()
    with browser(chromium) as ws_url:
        dt = DevTools(ws_url)
        try:
            session = new_page(dt)
            dt.send("Page.navigate", {"url": base + "index.html"}, session)
            _wait_for(dt, session, "document.querySelectorAll('.benchmark-plot canvas').length > 0")
            report.grid_canvases = _evaluate(
                dt, session, "document.querySelectorAll('.benchmark-plot canvas').length")
            dt.send("Page.navigate", {"url": base + "index.html" + page}, session)
            _wait_for(dt, session, f"document.querySelectorAll('{PLOT}').length > 0")
            time.sleep(1.0)  # let flot finish drawing
            report.plot_canvases = _evaluate(dt, session,
                                             f"document.querySelectorAll('{PLOT}').length")
            report.error_dialog = bool(_evaluate(
                dt, session, "$('#error').is(':visible')"))
            series = _evaluate(dt, session, "(() => { const p = $('#main-graph').data('plot');"
                               " return p ? p.getData().map(s => [s.color, s.data.filter("
                               "d => d && d[1] !== null).length]) : []; })()") or []
            report.plot_points = sum(n for _, n in series)
            if _evaluate(dt, session, "$('#show-legend').hasClass('active')"):
                _evaluate(dt, session, "$('#show-legend').click(); 1")  # its color box is no data
                time.sleep(0.5)
            if not _evaluate(dt, session, "$('#zoom-y-axis').hasClass('active')"):
                _evaluate(dt, session, "$('#zoom-y-axis').click(); 1")  # y axis fitted to the data
                time.sleep(0.5)
            rect = _evaluate(dt, session, "(() => { const r = document.querySelector("
                             "'#main-graph').getBoundingClientRect(); return "
                             "[r.x, r.y, r.width, r.height]; })()")
            if rect and rect[2] > 0 and rect[3] > 0:
                clip = dict(zip(("x", "y", "width", "height"), rect), scale=1)
                plot_png = base64.b64decode(dt.send("Page.captureScreenshot",
                                                    {"format": "png", "clip": clip},
                                                    session)["data"])
                report.plot_ink, report.plot_colors = _ink(plot_png)
                report.series_pixels = _series_pixels(plot_png, [c for c, _ in series])
            if screenshot is not None:
                Path(screenshot).write_bytes(base64.b64decode(
                    dt.send("Page.captureScreenshot", {"format": "png"}, session)["data"]))
            time.sleep(0.5)
            dt.send("Runtime.evaluate", {"expression": "1"}, session)  # flush pending events
        finally:
            dt.close()
            server.shutdown()
    _collect(dt.events, base, report)
    return report


def _collect(events, base, report):
    urls = {}
    for ev in events:
        method, params = ev.get("method"), ev.get("params", {})
        if method == "Network.requestWillBeSent":
            url = params["request"]["url"]
            urls[params["requestId"]] = url
            report.requests.append(url)
            if not url.startswith((base, "data:", "about:")):
                report.external.append(url)
        elif method == "Network.loadingFailed":
            report.failed.append(f"{urls.get(params['requestId'], '?')}: {params.get('errorText')}")
        elif method == "Network.responseReceived" and params["response"]["status"] >= 400:
            report.failed.append(f"{params['response']['url']}: HTTP {params['response']['status']}")
        elif method == "Runtime.exceptionThrown":
            report.errors.append(params["exceptionDetails"].get("text", "exception"))
        elif method == "Runtime.consoleAPICalled" and params.get("type") == "error":
            report.errors.append(" ".join(str(a.get("value", a.get("description", "")))
                                          for a in params.get("args", [])))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("html_dir", nargs="?", type=Path,
                        default=Path(__file__).resolve().parents[1] / ".asv" / "html")
    parser.add_argument("--benchmark", help="benchmark whose graph to open (default: a track_ one)")
    parser.add_argument("--screenshot", type=Path, help="write a screenshot of the graph page")
    args = parser.parse_args(argv)
    report = check(args.html_dir, args.benchmark, args.screenshot)
    print(f"requests: {len(report.requests)}, failed: {report.failed}, "
          f"external: {report.external}, script errors: {report.errors}")
    print(f"summary-grid plots: {report.grid_canvases}, graph canvases: {report.plot_canvases}, "
          f"plot area ink {report.plot_ink:.3f} in {report.plot_colors} colors, "
          f"{report.plot_points} data points, {report.series_pixels} pixels in series colors, "
          f"error dialog: {report.error_dialog}")
    print("dashboard renders offline" if report.ok else "dashboard check FAILED")
    return 0 if report.ok else 1


if __name__ == "__main__":
    sys.exit(main())
