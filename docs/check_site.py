"""Check the built book in a real headless browser.

    python -m paper_repro book && python docs/check_site.py [--site build/book/html]

Installs what it needs when it is missing (Debian's ``chromium``, with apt-get; the
``playwright`` Python package, which drives it), serves the site on localhost, and loads
every page of ``docs/`` and every notebook page. On each page it asserts that every image
has loaded (``complete`` with a non-zero natural width), that the browser logged no console
error, no failed request and no exception, that MathJax typeset the formulas of a page that
has some, and that every internal link resolves (the file
answers 200, and a ``#fragment`` names an element of it). A notebook page must show at least
one figure: an image in a cell's output that loaded. It saves a full-page screenshot of
each page into ``build/book/screenshots/`` and prints one line per page, then what failed;
the exit status is 1 when anything did.
"""

from __future__ import annotations

import argparse
import functools
import http.server
import shutil
import subprocess
import sys
import threading
from pathlib import Path
from urllib.parse import urldefrag, urljoin, urlparse

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"


def pages_of_docs() -> list[str]:
    """The page the book makes of every Markdown page of ``docs/`` (``method.html``,
    ``theory/distance.html``, …), the index first."""
    return sorted((p.relative_to(DOCS).with_suffix(".html").as_posix()
                   for p in DOCS.rglob("*.md")), key=lambda p: (p != "index.html", p))
CHROMIUM = "/usr/bin/chromium"
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync"]
"""Chromium's flags on a machine without a network: no background connections."""


def install() -> None:
    """Debian's Chromium and the Playwright package, each only when missing."""
    if not Path(CHROMIUM).exists():
        print("installing Debian's chromium (apt-get)", flush=True)
        subprocess.run(["apt-get", "update", "-qq"], check=True)
        env = {"DEBIAN_FRONTEND": "noninteractive", "PATH": "/usr/bin:/bin:/usr/sbin:/sbin"}
        subprocess.run(["apt-get", "install", "-y", "-qq", "chromium"], check=True, env=env)
    try:
        import playwright  # noqa: F401
    except ImportError:
        print("installing playwright (pip)", flush=True)
        subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "playwright"],
                       check=True)


def serve(site: Path) -> tuple[http.server.ThreadingHTTPServer, str]:
    handler = functools.partial(_QuietHandler, directory=str(site))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    return server, f"http://127.0.0.1:{server.server_address[1]}/"


class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args) -> None:  # one line per page is ours to print
        pass


def check_page(page, context, base: str, path: str, shots: Path) -> list[str]:
    """Load ``path`` and return what is wrong with it."""
    problems: list[str] = []
    console = []
    page.on("console", lambda m: console.append(m.text) if m.type == "error" else None)
    page.on("pageerror", lambda e: console.append(f"exception: {e}"))
    page.on("requestfailed", lambda r: console.append(f"request failed: {r.url}"))
    page.on("response", lambda r: console.append(f"HTTP {r.status}: {r.url}")
            if r.status >= 400 else None)
    url = urljoin(base, path)
    response = page.goto(url, wait_until="load")
    if response is None or response.status != 200:
        return [f"{path}: HTTP {response.status if response else 'no response'}"]
    page.wait_for_load_state("networkidle")
    images = page.eval_on_selector_all(
        "img", "els => els.map(e => [e.getAttribute('src'), e.complete && e.naturalWidth > 0])")
    problems += [f"{path}: image {src} did not load" for src, ok in images if not ok]
    figures = page.eval_on_selector_all(
        ".cell_output img", "els => els.filter(e => e.complete && e.naturalWidth > 0).length")
    if path.startswith("notebooks/") and not figures:
        problems.append(f"{path}: the page shows no figure (no image in a cell's output)")
    problems += [f"{path}: console: {text}" for text in console]
    formulas, typeset = page.evaluate(
        "[document.querySelectorAll('span.math, div.math').length,"
        " document.querySelectorAll('.MathJax, .MathJax_Display').length]")
    if formulas and not typeset:
        problems.append(f"{path}: {formulas} formulas and MathJax typeset none")
    hrefs = page.eval_on_selector_all("a[href]", "els => els.map(e => e.href)")
    checked: dict[str, str | None] = {}
    for href in sorted(set(hrefs)):
        if urlparse(href).netloc != urlparse(base).netloc:
            continue  # an external link: this machine has no network to follow it
        target, fragment = urldefrag(href)
        if target not in checked:
            answer = context.request.get(target)
            checked[target] = answer.text() if answer.status == 200 else None
            if answer.status != 200:
                problems.append(f"{path}: link {href} answers {answer.status}")
        body = checked[target]
        if fragment and body is not None and f'id="{fragment}"' not in body:
            problems.append(f"{path}: link {href} names no element #{fragment}")
    name = path.replace("/", "_").removesuffix(".html") + ".png"
    page.screenshot(path=str(shots / name), full_page=True)
    print(f"{path}: {len(images)} images ({figures} figures in outputs), {len(set(hrefs))} "
          f"links, {formulas} formulas ({typeset} typeset), {len(console)} console errors -> "
          f"{shots / name}", flush=True)
    return problems


def check_site(site: Path, shots: Path, pages=None) -> list[str]:
    """Load ``pages`` of the built ``site`` (default every page of ``docs/`` and every notebook
    page) in
    headless Chromium; returns what is wrong, one line per problem, and leaves a screenshot of
    each page in ``shots`` (emptied first). Chromium and Playwright must be installed."""
    from playwright.sync_api import sync_playwright

    if pages is None:
        pages = [*pages_of_docs(), *(f"notebooks/{p.name}"
                           for p in sorted((site / "notebooks").glob("*.html")))]
    if shots.exists():
        shutil.rmtree(shots)
    shots.mkdir(parents=True)
    server, base = serve(site)
    problems: list[str] = []
    try:
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=CHROMIUM, args=FLAGS)
            context = browser.new_context(viewport={"width": 1280, "height": 900})
            for path in pages:
                page = context.new_page()
                problems += check_page(page, context, base, path, shots)
                page.close()
            browser.close()
    finally:
        server.shutdown()
    return problems


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--site", type=Path, default=ROOT / "build" / "book" / "html")
    args = parser.parse_args()
    if not (args.site / "index.html").is_file():
        print(f"no site at {args.site}: build it first (python -m paper_repro book)")
        return 2
    install()
    problems = check_site(args.site, args.site.parent / "screenshots")
    print("\n".join(problems) if problems else "every page: images loaded, a figure on every "
          "notebook page, no console error, every internal link resolves")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
