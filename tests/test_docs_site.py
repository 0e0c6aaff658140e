"""The documentation site builds with warnings as errors, and its generated pages cover the
registry: every Lagrange id (every version) has a page with its animation and its spaces'
tables, every model a page with its derived equations."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from html import unescape
from pathlib import Path

import gymnasium as gym
import pytest

import dynamics
import envs  # noqa: F401  (registers the Lagrange namespace)

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    pytest.importorskip("mkdocs")
    pytest.importorskip("material")
    out = tmp_path_factory.mktemp("site")
    env = {**os.environ, "OMP_NUM_THREADS": "1", "NO_MKDOCS_2_WARNING": "1"}
    done = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(out)],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert done.returncode == 0, done.stderr[-4000:]
    return out


def _page(site: Path, path: str) -> str:
    page = site / path / "index.html"
    assert page.exists(), f"no page {path}"
    return page.read_text(encoding="utf-8")


@pytest.mark.slow  # builds the site: tens of seconds
def test_every_registered_id_has_a_page_with_its_animation_and_spaces(site):
    ids = [k for k in gym.registry if k.startswith("Lagrange/")]
    assert set(envs.ENV_IDS) <= set(ids) and "Lagrange/Acrobot-v1" in ids  # older versions too
    for env_id in ids:
        slug = env_id.replace("/", "-")
        html = _page(site, f"envs/{slug}")
        assert re.search(rf'<img[^>]+src="[./]*assets/envs/{slug}\.gif"', html), env_id
        assert (site / "assets" / "envs" / f"{slug}.gif").stat().st_size > 1000
        assert "<th>Input</th>" in html and "<th>Observation</th>" in html, env_id
        obs = gym.spec(env_id).make().observation_space.shape[0]
        assert f"<td>{obs - 1}</td>" in html  # the observation table's last row
        text = unescape(re.sub(r"<[^>]+>", "", html))
        assert f'env = gym.make("{env_id}"' in text, env_id  # how to make it
        assert f"{slug}/" in _page(site, "envs")  # listed on the index


@pytest.mark.slow  # builds the site: tens of seconds
def test_every_model_has_a_page_with_its_equations(site):
    for name in dynamics.list_models():
        html = _page(site, f"models/{name}")
        found = re.findall(r'<div class="arithmatex">\\\[(.*?)\\\]</div>', html, re.S)
        blocks = [re.sub(r"\\(begin|end)\{aligned\}|&", "", unescape(b)).strip() for b in found]
        coordinates = dynamics.get_model(name).coordinates
        equations = [b for b in blocks if b.endswith("= 0")]
        if name in _generator_models_doc().EQUATIONS_NOT_PRINTED:  # too large to read: says so
            assert "are not printed" in html, name
        else:
            assert len(equations) >= len(coordinates), name  # one equation of motion each
        assert any(b.startswith("T =") for b in blocks), name
        assert any(b.startswith("V =") for b in blocks), name


def _generator_models_doc():
    """scripts/gen_models_doc.py as a module."""
    return _generator().models_doc()


def _generator():
    """scripts/docs_site.py, the site's page generator (mkdocs runs it as its hooks)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("docs_site", ROOT / "scripts" / "docs_site.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_docstring_prose_keeps_asterisks_literal_outside_code_and_list_markers():
    text = "3 N*m, phi*.\n* v2: `make(x,\n**kw)` 2 N*m\n```\na*b\n```\n"
    assert _generator().escape_text(text) == (
        "3 N\\*m, phi\\*.\n* v2: `make(x,\n**kw)` 2 N\\*m\n```\na*b\n```\n"
    )


def test_a_models_errata_are_the_rows_whose_tests_derive_it():
    rows = _generator().errata_of("two_link_arm")
    numbers = [r.split("|")[1].strip() for r in rows if r.startswith("| ") and "| #" not in r]
    # 6: (7.25)'s Q1 (its test reaches the arm through a fixture); 14: the notation clash
    assert numbers == ["6", "14"]
    assert rows[0].startswith("| # | Where | Printed |")  # each table keeps its header


def test_every_registered_id_and_model_is_in_the_navigation():
    site = _generator()
    config = site.on_config({})
    listed = str(config["nav"])
    for env_id in gym.registry:
        if env_id.startswith("Lagrange/"):
            assert f"envs/{env_id.replace('/', '-')}.md" in listed
    for name in dynamics.list_models():
        assert f"models/{name}.md" in listed


@pytest.mark.slow  # builds the site: tens of seconds
def test_benchmark_numbers_carry_their_date_and_machine(site):
    import json

    results = json.loads((ROOT / "docs" / "data" / "agents.json").read_text(encoding="utf-8"))
    html = _page(site, "benchmark")
    assert re.search(r"Measured \d{4}-\d\d-\d\d", html) and "cores" in html
    for row in results["rows"]:
        env_id, run = row["env_id"], results["runs"][row["run"]]
        page = unescape(re.sub(r"<[^>]+>", "", _page(site, f"envs/{env_id.replace('/', '-')}")))
        assert f"Measured {run['finished'][:10]}" in page, env_id
        assert f"by {run['command']}" in page, env_id
        assert f"{run['machine']['cores']} cores" in page, env_id


def _checker():
    """scripts/check_site.py (the offline checks of a built site) as a module."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("check_site", ROOT / "scripts" / "check_site.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_checker_finds_outside_loads_and_raw_tex():
    check = _checker()
    html = (
        '<script src="https://cdn.example/m.js"></script><link href="//fonts.example/css" '
        'rel="stylesheet"><script src="../javascripts/mathjax.js"></script>'
        '<a href="https://example.org">a link is not a load</a>'
        '<link rel="canonical" href="https://site.example/page/">'  # names the page only
    )
    assert check.external_resources(html) == ["https://cdn.example/m.js", "//fonts.example/css"]
    dom = (
        '<div class="arithmatex"><mjx-container>x</mjx-container></div>'
        '<div class="arithmatex">\\[x\\]</div>'
    )
    assert check.unrendered(dom) == (2, 1)


@pytest.mark.slow  # builds the site: tens of seconds
def test_the_site_loads_nothing_from_outside_and_has_a_sitemap(site):
    check = _checker()
    outside = {
        str(p.relative_to(site)): found
        for p in site.rglob("*.html")
        if (found := check.external_resources(p.read_text(encoding="utf-8")))
    }
    assert not outside
    assert (site / "javascripts" / "vendor" / "mathjax" / "tex-svg-full.js").stat().st_size > 1e6
    assert "<loc>" in (site / "sitemap.xml").read_text(encoding="utf-8")  # site_url is set


@pytest.mark.slow  # builds the site: tens of seconds
def test_env_pages_have_their_own_versions_units_arguments_and_whole_cells(site):
    v1, v2 = _page(site, "envs/Lagrange-Acrobot-v1"), _page(site, "envs/Lagrange-Acrobot-v2")
    assert "Superseded" in v1 and 'href="../Lagrange-Acrobot-v2/"' in v1
    assert "Superseded" not in v2 and "max_input=3.0" not in v2
    assert "<td>9.81</td>" in v2 and "<td>3</td>" in v1  # each version's own elbow limit
    for env_id in [k for k in gym.registry if k.startswith("Lagrange/")]:
        html = _page(site, f"envs/{env_id.replace('/', '-')}")
        assert "<th>Unit</th>" in html and "<th>argument</th>" in html, env_id
        assert 'id="version-history"' in html and "<th>status</th>" in html, env_id
    arm = unescape(re.sub(r"<[^>]+>", "", _page(site, "envs/Lagrange-TwoLinkArm-v1")))
    assert "-0.001 |action|^2" in arm  # a '|' in a cell no longer ends it
    assert "N*m" in arm


@pytest.mark.slow  # builds the site: tens of seconds
def test_model_pages_cite_the_source_and_print_no_rounding_noise(site):
    for name in dynamics.list_models():
        html = _page(site, f"models/{name}")
        assert "Chapter 7" in html, name
        matrices = re.findall(r"\\begin\{bmatrix\}(.*?)\\end\{bmatrix\}", unescape(html), re.S)
        cells = [c.strip() for m in matrices for c in re.split(r"&|\\\\", m)]
        assert "-0" not in cells and not any("e-3" in c or "10^{-3" in c for c in cells), name
        text = unescape(re.sub(r"<[^>]+>", "", html))
        for printed in re.findall(
            r"(?:x0|u0) = \(([^)]*)\)|Eigenvalues of A \(1/s\): ([^\n]*)", text
        ):
            values = "".join(printed)
            assert not re.search(r"(^|[ (,])-0([,) ]|$)|e-(0[89]|[1-9]\d)", values), (name, values)
    assert "Chapter 7" in _page(site, "") and "robustness" in _page(site, "")


@pytest.mark.slow  # builds the site: tens of seconds
def test_the_robustness_page_is_dated_and_shows_its_figures(site):
    html = _page(site, "robustness")
    assert re.search(r"Measured \d{4}-\d\d-\d\d", html)
    for png in (ROOT / "docs" / "img" / "robustness").glob("*.png"):
        assert f"img/robustness/{png.name}" in html, png.name
    agents = _page(site, "agents")
    for command in ("check", "train", "evaluate", "lqr", "plan"):
        assert f"python -m agents.{command}" in unescape(agents), command


@pytest.mark.slow  # builds the site and starts a browser per page: a minute
def test_equations_render_offline_in_a_real_browser(site):
    """As a reader sees it, offline: every formula typeset (display, inline, in tables, the
    model outputs' inline TeX), none drawn smaller than its natural size, no code block cut
    off, no console error, nothing requested from another host."""
    check = _checker()
    browser = check.find_browser()
    if browser is None:
        pytest.skip("no Chromium here (install `chromium`); the HTML checks above still ran")
    pages = [
        "models/two_link_arm",  # display equations and the outputs' inline TeX
        "models/whipple_bicycle",  # the longest formulas: the kinetic energy
        "envs/Lagrange-Acrobot-v2",  # tables with formulas, the arguments table
        "errata",  # formulas in table cells
        "new-system",  # long code blocks
        "",
    ]
    with check.serve(site) as base:
        for page in pages:
            found = check.measure(browser, site / page / "index.html", base, site)
            assert found["blocks"] > 0 or page in ("new-system", ""), page
            assert not any(check.count(found, k) for k in check.FINDINGS), (page, found)


@pytest.mark.slow
def test_the_browser_probe_catches_source_tex_shrunk_formulas_and_errors(tmp_path):
    """The probe on a page made to fail: TeX left as source in the text, an SVG squeezed to
    a tenth of its width, a name broken across lines, a console error; and a clean page
    passes."""
    check = _checker()
    browser = check.find_browser()
    if browser is None:
        pytest.skip("no Chromium here (install `chromium` to run it)")
    bad = (
        "<html><head></head><body><article><p>an output: $ - \\frac{l m}{2} $</p>"
        '<div style="width:50px"><mjx-container><svg width="500" height="10" '
        'style="max-width:100%"></svg></mjx-container></div>'
        '<table><tr><td style="max-width:30px"><code style="word-break:break-word">'
        "a_very_long_argument_name</code></td><td>x</td></tr></table>"
        "<script>console.error('boom')</script></article></body></html>"
    )
    good = "<html><head></head><body><article><p>a price of $5 and $6</p></article></body></html>"
    (tmp_path / "bad.html").write_text(bad, encoding="utf-8")
    (tmp_path / "good.html").write_text(good, encoding="utf-8")
    with check.serve(tmp_path) as base:
        found = check.measure(browser, tmp_path / "bad.html", base, tmp_path)
        assert len(found["source"]) == 1 and found["shrunk"] == ["10%"], found
        assert found["errors"] == ["boom"] and found["broken"] == ["a_very_long_argument_name"]
        found = check.measure(browser, tmp_path / "good.html", base, tmp_path)
        assert not any(check.count(found, k) for k in check.FINDINGS), found
