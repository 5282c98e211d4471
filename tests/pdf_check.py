"""What a PDF shows, read back with pdfminer.six (another code base than the one that wrote
it): each page's text, and every character that lies outside its page."""

from __future__ import annotations

from pathlib import Path


def _pages(path: Path):
    from pdfminer.high_level import extract_pages

    return list(extract_pages(str(path)))


def _chars(layout):
    from pdfminer.layout import LTChar

    stack = [layout]
    while stack:
        node = stack.pop()
        if isinstance(node, LTChar):
            yield node
        elif hasattr(node, "__iter__"):
            stack.extend(node)


def page_texts(path: Path) -> list[str]:
    """The text of each page (pdfminer's layout analysis, boxes in reading order)."""
    from pdfminer.layout import LTTextContainer

    return ["".join(e.get_text() for e in page if isinstance(e, LTTextContainer)) for page in _pages(path)]


def outside(path: Path, tolerance_pt: float = 0.5) -> list[str]:
    """Each character (visible, not blank) whose box leaves its page, as 'page n: "line…" at x0–x1 pt of W'."""
    out = []
    for n, page in enumerate(_pages(path), 1):
        x0, y0, x1, y1 = page.bbox
        for c in _chars(page):
            if not c.get_text().strip():
                continue
            if (
                c.x0 < x0 - tolerance_pt
                or c.x1 > x1 + tolerance_pt
                or c.y0 < y0 - tolerance_pt
                or c.y1 > y1 + tolerance_pt
            ):
                out.append(
                    f"page {n}: {c.get_text()!r} at x {c.x0:.1f}–{c.x1:.1f} pt, y {c.y0:.1f}–{c.y1:.1f} of {x1:.0f} × {y1:.0f}"
                )
    return out
