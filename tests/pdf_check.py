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


def _glyphs(font) -> dict[str, bytes]:
    """A Type0 font's character → its 2-byte glyph code, from the font's /ToUnicode CMap."""
    import re

    cmap = font["/ToUnicode"].get_object().data.decode("latin-1")
    out = {}
    for block in re.findall(r"beginbfchar(.*?)endbfchar", cmap, re.S):
        for code, uni in re.findall(r"<([0-9a-fA-F]{4})>\s*<([0-9a-fA-F]{4})>", block):
            out[chr(int(uni, 16))] = bytes.fromhex(code)
    return out


def change_text(pdf: bytes, old: str, new: str) -> bytes:
    """The PDF with the first drawing of ``old`` (a run of characters of one font, as a
    WeasyPrint TJ array draws it) redrawn as ``new`` (as long, its glyphs in the same font),
    saved as an incremental update (as a PDF editor saves): the embedded files, and the
    other pages, untouched. The content stream is rewritten with pyHanko's writer."""
    import re
    from io import BytesIO

    from pyhanko.pdf_utils.generic import NameObject, StreamObject
    from pyhanko.pdf_utils.incremental_writer import IncrementalPdfFileWriter

    assert len(old) == len(new)
    writer = IncrementalPdfFileWriter(BytesIO(pdf), strict=False)
    pages = writer.root["/Pages"]["/Kids"]
    for i in range(len(pages)):
        page = pages[i].get_object()
        data = page["/Contents"].get_object().data
        for font in page["/Resources"]["/Font"].values():
            glyphs = _glyphs(font.get_object())
            if not all(ch in glyphs for ch in old + new):
                continue
            # the glyphs of `old` in a TJ array: <code> with kerning numbers between them
            pattern = rb"[-\d.]*".join(re.escape(b"<" + glyphs[ch].hex().encode() + b">") for ch in old)
            m = re.search(pattern, data)
            if not m:
                continue
            codes = [b"<" + glyphs[ch].hex().encode() + b">" for ch in new]
            kerns = re.split(rb"<[0-9a-fA-F]{4}>", m.group())[1:-1]  # between the glyphs
            redrawn = codes[0] + b"".join(k + c for k, c in zip(kerns, codes[1:], strict=True))
            stream = StreamObject(stream_data=data[: m.start()] + redrawn + data[m.end() :])
            page[NameObject("/Contents")] = writer.add_object(stream)
            writer.update_container(page)
            out = BytesIO()
            writer.write(out)
            return out.getvalue()
    raise AssertionError(f"{old!r} is not drawn in one run of one font of this PDF")
