"""Check a built documentation site as a reader without internet sees it.

Two checks, on the folder `mkdocs build` wrote:
- in the HTML: no script, style sheet, font or image is loaded from another host
  (`external_resources`);
- in a real browser (headless Chromium, with every host name unresolvable): after the
  scripts ran, how many equation blocks are still raw TeX on each page (`unrendered`).

    python scripts/check_site.py SITE_DIR [--browser chromium] [--pages envs/...]

prints one line per page with equations (`rendered/blocks`) and exits 1 when any block is
left raw or anything is loaded from outside.
"""

from __future__ import annotations

import argparse
import re
import shutil
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
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


def rendered_dom(browser: str, page: Path, budget_ms: int = 20000) -> str:
    """The page's DOM after its scripts ran, in headless Chromium with no network: every
    host name resolves to nothing, so a script that tried to fetch would fail."""
    command = [
        browser,
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--host-resolver-rules=MAP * ~NOTFOUND",
        "--allow-file-access-from-files",
        f"--virtual-time-budget={budget_ms}",
        "--dump-dom",
        page.resolve().as_uri(),
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
    pages = equation_pages(args.site)
    if args.pages:
        pages = [args.site / p for p in args.pages]
    with ThreadPoolExecutor(args.jobs) as pool:
        counts = list(pool.map(lambda p: unrendered(rendered_dom(browser, p)), pages))
    total = raw_total = 0
    for page, (n, raw) in zip(pages, counts):
        total, raw_total = total + n, raw_total + raw
        print(f"{page.relative_to(args.site).parent}: {n - raw}/{n} rendered")
    print(f"{len(pages)} pages, {total} equation blocks, {raw_total} left as raw TeX")
    return 1 if (bad or raw_total) else 0


if __name__ == "__main__":
    sys.exit(main())
