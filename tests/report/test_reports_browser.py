"""The HTML reports of the default run, opened in a real browser (headless Chromium from
the operating system's packages, driven by Playwright): every image loads, every internal
link and anchor resolves, no console error, every figure has a text alternative, every
table has header cells, and printing to PDF from the browser works.

The pages are those of the session's default run (``thesis_run``); with
``CALFLOW_REPORTS_DIR`` set to a ``reports/`` folder, that folder's pages are checked
instead (for working on the templates without running the campaigns).
"""

from __future__ import annotations

import os
import re
import shutil
from pathlib import Path
from urllib.parse import unquote, urlsplit

import pytest

CHROMIUM_FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]

# What one page says about itself, read in the page after it has loaded.
PAGE_FACTS = """() => {
  const name = (el) => {
    if (el.getAttribute('aria-label')) return el.getAttribute('aria-label').trim();
    const by = el.getAttribute('aria-labelledby');
    if (by) return by.split(/\\s+/).map(id => (document.getElementById(id) || {}).textContent || '')
                  .join(' ').trim();
    if (el.tagName.toLowerCase() === 'img') return (el.getAttribute('alt') || '').trim();
    const t = el.querySelector(':scope > title');
    return t ? t.textContent.trim() : '';
  };
  const graphics = [...document.querySelectorAll('img, svg[role="img"], figure > svg')];
  return {
    broken_images: [...document.images].filter(i => !i.complete || i.naturalWidth === 0)
                     .map(i => i.getAttribute('src').slice(0, 80)),
    empty_graphics: graphics.filter(g => { const r = g.getBoundingClientRect();
                                           return r.width === 0 || r.height === 0; })
                            .map(g => g.closest('figure') ? g.closest('figure').id : g.tagName),
    unnamed_graphics: graphics.filter(g => !name(g))
                              .map(g => (g.closest('figure') && g.closest('figure').id) || g.tagName),
    figures: document.querySelectorAll('figure').length,
    tables_without_th: [...document.querySelectorAll('table')].filter(t => !t.querySelector('th'))
                         .map(t => (t.caption ? t.caption.textContent : t.outerHTML).slice(0, 80)),
    tables: document.querySelectorAll('table').length,
    links: [...document.querySelectorAll('a[href]')].map(a => a.getAttribute('href')),
    refs: [...document.querySelectorAll('use')]
            .map(u => u.getAttribute('href') || u.getAttribute('xlink:href')).filter(h => h),
    ids: [...document.querySelectorAll('[id]')].map(e => e.id)
           .concat([...document.querySelectorAll('a[name]')].map(a => a.getAttribute('name'))),
  };
}"""


def _chromium() -> str:
    path = os.environ.get("CALFLOW_CHROMIUM") or shutil.which("chromium") or shutil.which("chromium-browser")
    assert path, "no Chromium: `make test` installs Debian's chromium package (apt-get install chromium)"
    return path


@pytest.fixture(scope="module")
def reports(request) -> Path:
    given = os.environ.get("CALFLOW_REPORTS_DIR")
    if given:
        return Path(given).resolve()
    return request.getfixturevalue("thesis_run") / "reports"


@pytest.fixture(scope="module")
def browser():
    from playwright.sync_api import sync_playwright

    with sync_playwright() as pw:
        b = pw.chromium.launch(executable_path=_chromium(), args=CHROMIUM_FLAGS)
        yield b
        b.close()


def load(browser, file: Path) -> dict:
    """Open ``file`` in the browser: the page's facts and what the browser reported while
    loading it (console errors, uncaught exceptions, failed requests). The page stays open."""
    page = browser.new_page()
    said: list[str] = []
    page.on("console", lambda m: said.append(f"console {m.type}: {m.text}") if m.type == "error" else None)
    page.on("pageerror", lambda e: said.append(f"exception: {e}"))
    page.on("requestfailed", lambda r: said.append(f"request failed: {r.url[:100]} {r.failure}"))
    page.goto(file.as_uri(), wait_until="load")
    facts = page.evaluate(PAGE_FACTS)
    facts["said"] = said
    facts["page"] = page
    return facts


def link_problems(root: Path, pages: dict[str, dict]) -> list[str]:
    """Links (``a href``) and SVG references (``use href``) of ``pages`` (keyed by their path
    under ``root``) that lead to no file, or to no element of the linked page."""
    problems = []
    for rel, facts in pages.items():
        here = root / rel
        for href in facts["links"] + facts["refs"]:
            parts = urlsplit(href)
            if parts.scheme or parts.netloc:  # http:, https:, mailto:, data: — not ours
                continue
            target = (here.parent / unquote(parts.path)).resolve() if parts.path else here
            if not target.is_file():
                problems.append(f"{rel}: {href}: no file {target}")
                continue
            if parts.fragment:
                trel = target.relative_to(root).as_posix() if target.is_relative_to(root) else None
                if trel not in pages or unquote(parts.fragment) not in pages[trel]["ids"]:
                    problems.append(f"{rel}: {href}: no element with id {parts.fragment!r}")
    return problems


@pytest.fixture(scope="module")
def pages(reports, browser) -> dict[str, dict]:
    """Every HTML page under ``reports/``, loaded once."""
    out = {f.relative_to(reports).as_posix(): load(browser, f) for f in sorted(reports.rglob("*.html"))}
    yield out
    for facts in out.values():
        facts["page"].close()


BAD_PAGE = """<!doctype html><html><head><meta charset="utf-8"><title>bad</title></head><body>
<script>console.error("boom")</script>
<figure id="f1"><img src="missing.png"><figcaption>no alt</figcaption></figure>
<figure id="f2"><svg role="img" viewBox="0 0 10 10" style="width:100px"><rect width="10" height="10"/></svg></figure>
<table><tr><td>no header</td></tr></table>
<a href="#nowhere">dangling</a> <a href="gone.html">gone</a> <a href="#f1">fine</a>
<a href="https://example.org/">outside</a>
</body></html>"""


def test_the_checks_find_what_is_wrong_in_a_bad_page(tmp_path, browser):
    """Each check below fails on a page made to break it (so a green run means something)."""
    (tmp_path / "bad.html").write_text(BAD_PAGE)
    facts = load(browser, tmp_path / "bad.html")
    try:
        assert any("boom" in s for s in facts["said"])
        assert any("missing.png" in s for s in facts["said"])  # the failed request
        assert facts["broken_images"] == ["missing.png"]
        assert sorted(facts["unnamed_graphics"]) == ["f1", "f2"]
        assert len(facts["tables_without_th"]) == 1
        problems = link_problems(tmp_path, {"bad.html": facts})
        assert len(problems) == 2 and "#nowhere" in problems[0] and "gone.html" in problems[1]
    finally:
        facts["page"].close()


def test_the_default_run_has_its_pages(pages):
    assert "index.html" in pages
    reports = [p for p in pages if p.endswith("/report.html")]
    assert len(reports) >= 3, sorted(pages)
    assert all(pages[p]["figures"] > 0 and pages[p]["tables"] > 0 for p in reports)


def test_no_console_error(pages):
    assert {p: f["said"] for p, f in pages.items() if f["said"]} == {}


def test_every_image_loads_and_shows(pages):
    assert {p: f["broken_images"] for p, f in pages.items() if f["broken_images"]} == {}
    assert {p: f["empty_graphics"] for p, f in pages.items() if f["empty_graphics"]} == {}


def test_every_figure_has_a_text_alternative(pages):
    assert {p: f["unnamed_graphics"] for p, f in pages.items() if f["unnamed_graphics"]} == {}


def test_every_table_has_header_cells(pages):
    assert {p: f["tables_without_th"] for p, f in pages.items() if f["tables_without_th"]} == {}


def test_every_internal_link_and_anchor_resolves(reports, pages):
    problems = link_problems(reports, pages)
    assert problems == [], "\n".join(problems[:40])


def test_printing_to_pdf_works(pages, tmp_path):
    """The browser's own print (the print style sheet, A4): a whole PDF, a campaign report
    over several pages, and no text past the page's edge (pdfminer.six reads it back) — the
    pages calflow writes no PDF of (the index, a study's page) included."""
    from pdf_check import outside

    past = {}
    for rel, facts in pages.items():
        pdf = facts["page"].pdf(format="A4", print_background=True)
        assert pdf.startswith(b"%PDF-") and b"%%EOF" in pdf[-1024:], rel
        n_pages = len(re.findall(rb"/Type\s*/Page\b", pdf))
        assert n_pages >= (2 if rel.endswith("report.html") else 1), (rel, n_pages)
        (tmp_path / "printed.pdf").write_bytes(pdf)
        if found := outside(tmp_path / "printed.pdf"):
            past[rel] = found[:3]
    assert past == {}
