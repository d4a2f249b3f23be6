"""Publish the asv dashboard so that it renders with no internet.

``asv publish`` writes a page that loads jQuery, flot, bootstrap and other
libraries from public CDNs. This script runs it, installs the same libraries
from the npm registry (``tools/dashboard/package.json``, exact versions)
into a cache directory, copies the files the page asks for (and the files
their CSS refers to) into ``<html_dir>/vendor/`` and points every external
``<script src>`` and ``<link href>`` of the published pages at those copies.
It fails, naming the URL, when a page asks for something it cannot map, and
checks that no page is left loading anything from outside.

    python tools/publish_offline.py [--no-publish] [--html-dir DIR] [--cache DIR]

Run from the repository root (where asv.conf.json is). Nothing it writes is
committed: the dashboard goes to asv's ``html_dir`` (``.asv/html``), the npm
packages to ``.asv/npm``.
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
PACKAGE_JSON = HERE / "dashboard" / "package.json"
# library directory names on the CDN -> npm package names, where they differ
NPM_NAMES = {"stupidtable": "stupid-table-plugin"}
TAG = re.compile(r"<(script|link)\b[^>]*?\b(src|href)=\"(https?://[^\"]+)\"[^>]*>", re.I)
DROP_ATTRS = re.compile(r"\s+(integrity|crossorigin|referrerpolicy)=\"[^\"]*\"", re.I)
CSS_URL = re.compile(r"url\(\s*['\"]?([^'\")?#]+)[^)]*\)")


class VendorError(RuntimeError):
    """A page asks for a file that cannot be served locally."""


def npm_install(cache: Path) -> Path:
    """Install the packages of ``package.json`` into ``cache``; return its node_modules."""
    cache.mkdir(parents=True, exist_ok=True)
    wanted = PACKAGE_JSON.read_text()
    stamp = cache / "package.json"
    modules = cache / "node_modules"
    if not (modules.is_dir() and stamp.exists() and stamp.read_text() == wanted):
        stamp.write_text(wanted)
        subprocess.run(["npm", "install", "--no-audit", "--no-fund", "--no-package-lock",
                        "--loglevel=error"], cwd=cache, check=True)
    return modules


def locate(url: str) -> tuple[str, str]:
    """``(npm package, path inside it)`` for a CDN URL of asv's page."""
    path = url.split("://", 1)[1].split("?", 1)[0]
    if m := re.search(r"/npm/((?:@[^/]+/)?[^/@]+)@[^/]+/(.+)$", path):
        return m.group(1), m.group(2)
    if m := re.search(r"/ajax/libs/([^/]+)/[^/]+/(.+)$", path):
        return NPM_NAMES.get(m.group(1), m.group(1)), m.group(2)
    if m := re.search(r"/jquery-[\d.]+(\.min)?\.js$", path):
        return "jquery", f"dist/jquery{m.group(1) or ''}.js"
    raise VendorError(f"no npm package known for {url}")


def find_file(modules: Path, package: str, inner: str) -> Path:
    """The file ``inner`` of ``package``: as named, else by name anywhere in it (minified or not)."""
    root = modules / package
    if not root.is_dir():
        raise VendorError(f"npm package {package} is not installed (add it to {PACKAGE_JSON})")
    if (root / inner).is_file():
        return root / inner
    name = Path(inner).name
    for candidate in (name, name.replace(".min.", ".")):
        hits = sorted(p for p in root.rglob(candidate)
                      if "node_modules" not in p.relative_to(root).parts
                      and "examples" not in p.relative_to(root).parts)
        if hits:
            return min(hits, key=lambda p: len(p.parts))
    raise VendorError(f"{inner} not found in npm package {package}")


def copy_with_assets(src: Path, modules: Path, vendor: Path) -> Path:
    """Copy ``src`` under ``vendor`` (keeping its package path) with the files its CSS refers to."""
    dest = vendor / src.relative_to(modules)
    dest.parent.mkdir(parents=True, exist_ok=True)
    shutil.copy2(src, dest)
    if src.suffix == ".css":
        for ref in set(CSS_URL.findall(src.read_text(errors="replace"))):
            if ref.startswith(("data:", "http:", "https:", "//")):
                continue
            asset = (src.parent / ref).resolve()
            if asset.is_file():
                target = vendor / asset.relative_to(modules.resolve())
                target.parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(asset, target)
    return dest


def vendor_page(page: Path, modules: Path, vendor: Path) -> list[str]:
    """Rewrite the external tags of one page; return the URLs replaced."""
    replaced = []

    def local(match):
        tag, attr, url = match.group(0), match.group(2), match.group(3)
        if match.group(1).lower() == "link" and "stylesheet" not in tag.lower():
            return tag  # not a resource the page loads
        dest = copy_with_assets(find_file(modules, *locate(url)), modules, vendor)
        replaced.append(url)
        rel = dest.relative_to(page.parent).as_posix()
        return DROP_ATTRS.sub("", tag.replace(f'{attr}="{url}"', f'{attr}="{rel}"'))

    text = TAG.sub(local, page.read_text())
    page.write_text(text)
    return replaced


def external_loads(page: Path) -> list[str]:
    """External scripts and stylesheets a page still loads."""
    return [m.group(3) for m in TAG.finditer(page.read_text())
            if m.group(1).lower() == "script" or "stylesheet" in m.group(0).lower()]


def html_dir_of_config() -> Path:
    text = (REPO / "asv.conf.json").read_text()
    conf = json.loads("\n".join(line for line in text.splitlines()
                                if not line.strip().startswith("//")))
    return REPO / conf.get("html_dir", "html")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--no-publish", action="store_true",
                        help="vendor an already published dashboard")
    parser.add_argument("--html-dir", type=Path, default=None)
    parser.add_argument("--cache", type=Path, default=REPO / ".asv" / "npm")
    args = parser.parse_args(argv)
    if not args.no_publish:
        subprocess.run([sys.executable, "-m", "asv", "publish"], cwd=REPO, check=True)
    html = args.html_dir or html_dir_of_config()
    pages = sorted(html.glob("*.html"))
    if not pages:
        print(f"publish_offline: no published pages in {html}", file=sys.stderr)
        return 2
    modules = npm_install(args.cache)
    try:
        for page in pages:
            for url in vendor_page(page, modules, html / "vendor"):
                print(f"{page.name}: {url} -> local copy")
    except VendorError as exc:
        print(f"publish_offline: {exc}", file=sys.stderr)
        return 1
    left = {page.name: external_loads(page) for page in pages}
    left = {k: v for k, v in left.items() if v}
    if left:
        print(f"publish_offline: pages still load external files: {left}", file=sys.stderr)
        return 1
    print(f"dashboard published to {html}/index.html; it loads no external file")
    return 0


if __name__ == "__main__":
    sys.exit(main())
