r"""Check a built documentation site as a reader without internet sees it.

Checks, on the folder `mkdocs build` wrote:
- in the HTML: no script, style sheet, font or image is loaded from another host
  (`external_resources`);
- in a real browser (headless Chromium, with every host name unresolvable), after the
  scripts ran (`measure`): equation blocks still raw TeX (`unrendered`), TeX left as source
  anywhere else in the text (`$...$`, `\(...\)`), formulas drawn smaller than their natural
  size, code blocks cut at the right edge (wider than their box and not scrolling), names in
  a table's first column broken across lines, console errors and uncaught exceptions, and
  requests to anything but local files.

    python scripts/check_site.py SITE_DIR [--browser chromium] [--pages envs/...]

prints one line per page with a finding and a total, and exits 1 on any finding.
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import threading
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from functools import partial
from html import unescape
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

# what makes a browser fetch: <script src>, <link href> (style sheets, fonts, icons,
# preloads; not rel="canonical", "alternate", "prev" or "next", which only name a page),
# <img src>, CSS url() and @import
FETCHES = re.compile(
    r"<script[^>]*\ssrc=[\"']([^\"']+)"
    r"|<link(?![^>]*\srel=[\"']?(?:canonical|alternate|prev|next)\b)[^>]*\shref=[\"']([^\"']+)"
    r"|<img[^>]*\ssrc=[\"']([^\"']+)|url\(\s*[\"']?([^\"')]+)|@import\s+[\"']([^\"']+)",
    re.I,
)
EQUATION = re.compile(r'class="arithmatex"')


def external_resources(html: str) -> list[str]:
    """The addresses on another host that the page would fetch (links a reader may click,
    <a href>, are not fetched and are not counted)."""
    found = (next(g for g in m.groups() if g) for m in FETCHES.finditer(html))
    return [u for u in found if re.match(r"(https?:)?//", u.strip())]


def equation_pages(site: Path) -> list[Path]:
    """The built pages that hold at least one equation block."""
    pages = sorted(site.rglob("*.html"))
    return [p for p in pages if EQUATION.search(p.read_text(encoding="utf-8"))]


def rendered_dom(browser: str, page: Path | str, budget_ms: int = 20000) -> str:
    """The page's DOM after its scripts ran, in headless Chromium with no network: every
    host name resolves to nothing, so a script that tried to fetch would fail."""
    command = [
        browser,
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--host-resolver-rules=MAP * ~NOTFOUND, EXCLUDE 127.0.0.1",
        "--allow-file-access-from-files",
        f"--virtual-time-budget={budget_ms}",
        "--dump-dom",
        page if isinstance(page, str) else page.resolve().as_uri(),
    ]
    done = subprocess.run(command, capture_output=True, text=True, timeout=180)
    if done.returncode != 0:
        raise RuntimeError(f"{browser} failed on {page}: {done.stderr[-500:]}")
    return done.stdout


def unrendered(dom: str) -> tuple[int, int]:
    """(equation blocks, blocks still raw TeX) in a rendered DOM: MathJax replaces the TeX
    of each `arithmatex` element with an <mjx-container>."""
    blocks = re.findall(r'<(div|span) class="arithmatex">(.*?)</\1>', dom, re.S)
    raw = [b for _, b in blocks if "<mjx-container" not in b]
    return len(blocks), len(raw)


# Injected into a copy of each page: the first script records console errors, uncaught
# exceptions and rejected promises; the last, once MathJax has typeset the page, measures it
# and writes the findings as JSON into the DOM that --dump-dom prints.
PROBE_HEAD = """<script>
window.__siteCheck = {errors: []};
(function () {
  const error = console.error.bind(console);
  console.error = function () {
    window.__siteCheck.errors.push(Array.from(arguments).map(String).join(" "));
    error.apply(console, arguments);
  };
  window.addEventListener("error", e => window.__siteCheck.errors.push(String(e.message)));
  window.addEventListener("unhandledrejection",
                          e => window.__siteCheck.errors.push(String(e.reason)));
})();
</script>"""
PROBE_TAIL = r"""<script>
window.addEventListener("load", () => {
  const mathjax = window.MathJax && MathJax.startup && MathJax.startup.promise;
  const ready = mathjax || Promise.resolve();
  ready.then(() => new Promise(r => setTimeout(r, 50))).then(() => {
    const found = {errors: window.__siteCheck.errors, source: [], shrunk: [], cut: [], broken: [],
                   requests: []};
    const skip = ["CODE", "PRE", "SCRIPT", "STYLE", "MJX-CONTAINER", "MJX-ASSISTIVE-MML",
                  "TEXTAREA"];
    const tex = /\$[^$\n]*\\[A-Za-z]+[^$\n]*\$|\\\(|\\\[/;
    const text = document.querySelector("article") || document.body;
    const walker = document.createTreeWalker(text, NodeFilter.SHOW_TEXT);
    for (let n = walker.nextNode(); n; n = walker.nextNode()) {
      let up = n.parentElement, skipped = false;
      for (; up; up = up.parentElement) if (skip.includes(up.tagName)) { skipped = true; break; }
      if (!skipped && tex.test(n.textContent)) found.source.push(n.textContent.trim().slice(0, 80));
    }
    for (const svg of document.querySelectorAll("mjx-container > svg")) {
      const drawn = svg.getBoundingClientRect().width;
      const keep = svg.style.maxWidth;
      svg.style.maxWidth = "none";
      const natural = svg.getBoundingClientRect().width;
      svg.style.maxWidth = keep;
      if (natural > drawn + 1) found.shrunk.push(Math.round(100 * drawn / natural) + "%");
    }
    for (const code of document.querySelectorAll("pre > code")) {
      const overflow = getComputedStyle(code).overflowX;
      if (code.scrollWidth > code.clientWidth + 1 && !["auto", "scroll"].includes(overflow))
        found.cut.push(code.textContent.slice(0, 40));
    }
    for (const name of document.querySelectorAll("td:first-child > code"))
      if (name.getClientRects().length > 1) found.broken.push(name.textContent);
    for (const r of performance.getEntriesByType("resource"))
      if (!r.name.startsWith(location.origin) && !r.name.startsWith("data:"))
        found.requests.push(r.name);
    const out = document.createElement("pre");
    out.id = "site-check";
    out.textContent = JSON.stringify(found);
    document.body.appendChild(out);
  });
});
</script>"""


def measure(browser: str, page: Path, base: str, site: Path, budget_ms: int = 20000) -> dict:
    """What a reader's browser shows of one built page (see the module's docstring), the
    site served at `base` (over HTTP, as a reader gets it: the search worker cannot start
    from file://): the page is copied beside itself with the probes added, so its relative
    links still hold."""
    html = page.read_text(encoding="utf-8")
    html = re.sub(r"<head[^>]*>", lambda m: m.group(0) + PROBE_HEAD, html, count=1)
    html = html.replace("</body>", PROBE_TAIL + "</body>", 1)
    probe = page.with_name(f".site-check-{page.stem}.html")
    probe.write_text(html, encoding="utf-8")
    try:
        dom = rendered_dom(browser, base + probe.relative_to(site).as_posix(), budget_ms)
    finally:
        probe.unlink()
    blocks, raw = unrendered(dom)
    found = re.search(r'<pre id="site-check">(.*?)</pre>', dom, re.S)
    if found is None:
        return {"blocks": blocks, "raw": raw, "errors": ["the probe did not finish"],
                "source": [], "shrunk": [], "cut": [], "broken": [], "requests": []}  # fmt: skip
    return {"blocks": blocks, "raw": raw, **json.loads(unescape(found.group(1)))}


FINDINGS = ("raw", "source", "shrunk", "cut", "broken", "errors", "requests")


def count(result: dict, key: str) -> int:
    value = result[key]
    return value if isinstance(value, int) else len(value)


@contextmanager
def serve(site: Path):
    """The site over HTTP on a free local port, quietly, for the length of the block."""
    handler = partial(QuietHandler, directory=str(site))
    server = ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}/"
    finally:
        server.shutdown()
        server.server_close()


class QuietHandler(SimpleHTTPRequestHandler):
    def log_message(self, *args):
        pass


def find_browser() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome", "chrome"):
        if shutil.which(name):
            return shutil.which(name)
    return None


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("site", type=Path, help="the folder `mkdocs build` wrote")
    parser.add_argument("--browser", default=None, help="Chromium's command (default: found)")
    parser.add_argument("--pages", nargs="*", help="only these pages (paths under the site)")
    parser.add_argument("--jobs", type=int, default=2, help="browsers at once")
    args = parser.parse_args(argv)
    bad = 0
    for page in sorted(args.site.rglob("*.html")):
        outside = external_resources(page.read_text(encoding="utf-8"))
        if outside:
            bad += 1
            print(f"{page.relative_to(args.site)}: loads from outside: {outside}")
    browser = args.browser or find_browser()
    if browser is None:
        print("no Chromium found: the rendered equations were not checked")
        return 1 if bad else 0
    pages = sorted(p for p in args.site.rglob("*.html") if p.name != "404.html")
    if args.pages:
        pages = [args.site / p for p in args.pages]
    with serve(args.site) as base, ThreadPoolExecutor(args.jobs) as pool:
        results = list(pool.map(lambda p: measure(browser, p, base, args.site), pages))
    totals = dict.fromkeys(FINDINGS, 0)
    for page, result in zip(pages, results):
        found = {k: count(result, k) for k in FINDINGS}
        totals = {k: totals[k] + found[k] for k in FINDINGS}
        if any(found.values()):
            details = {k: result[k] for k in FINDINGS if found[k] and k != "raw"}
            print(f"{page.relative_to(args.site)}: {found} {json.dumps(details)[:400]}")
    blocks = sum(r["blocks"] for r in results)
    print(
        f"{len(pages)} pages, {blocks} equation blocks: {totals['raw']} left as raw TeX, "
        f"{totals['source']} formulas as source elsewhere, {totals['shrunk']} shrunk, "
        f"{totals['cut']} code blocks cut, {totals['broken']} names broken across lines, "
        f"{totals['errors']} console errors, "
        f"{totals['requests']} outside requests"
    )
    return 1 if (bad or any(totals.values())) else 0


if __name__ == "__main__":
    sys.exit(main())
