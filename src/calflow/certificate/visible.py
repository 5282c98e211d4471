"""What a certificate PDF shows, compared with the results on disk.

A reader trusts the printed page, not the DCC embedded in it: an unsigned PDF's text can be
edited while its attachment is left alone. This module reads the text a PDF draws
(pdfminer.six, in the order of its content streams, which is the HTML's order for a
WeasyPrint document) and compares it with the page calflow renders from the summary now
(:func:`calflow.certificate.page.render`, the template that wrote it):

* every page's header and footer (its margin boxes) carry the certificate's number,
  ``page i of n`` and, for an unsigned file, ``UNSIGNED``, and every certificate number
  the pages show (``CF-…``) is that one; an unsigned file that claims to be signed is
  refused;
* the first heading carries the number;
* each row of the results table (value, U, k, dof, interval, limit, decision, PFA, PFR), of
  the as-found/as-left table, each labelled decision and the overall one, the decision rule
  and each uncertainty budget read exactly as the template renders them from the summary.

White space is not compared (the PDF places words, it does not store the spaces between
them, and a cell may wrap anywhere); every other character is. The first item that differs
is named with what the page shows and what the results give.
"""

from __future__ import annotations

from io import BytesIO

from calflow.errors import CalflowError

#: The page's margins (report/templates/style.css ``@page``: 18 mm top, 20 mm bottom), pt:
#: what lies in them is the header and footer.
TOP_PT, BOTTOM_PT = 18 / 25.4 * 72, 20 / 25.4 * 72


class Differs(CalflowError):
    """What the pages show differs from the results: one line naming it."""


def _squash(text: str) -> str:
    return "".join(text.split())


def pdf_text(pdf: bytes) -> list[dict]:
    """Per page ``{"body", "margins"}``: the characters drawn inside the page's margins and
    in them, white space removed, in content-stream order."""
    from pdfminer.converter import PDFPageAggregator
    from pdfminer.layout import LTChar
    from pdfminer.pdfinterp import PDFPageInterpreter, PDFResourceManager
    from pdfminer.pdfpage import PDFPage

    manager = PDFResourceManager()
    device = PDFPageAggregator(manager, laparams=None)  # no layout analysis: stream order
    interpreter = PDFPageInterpreter(manager, device)
    pages = []
    for page in PDFPage.get_pages(BytesIO(pdf)):
        interpreter.process_page(page)
        layout = device.get_result()
        body, margins = [], []
        for c in layout:
            if isinstance(c, LTChar):
                middle = (c.y0 + c.y1) / 2
                inside = BOTTOM_PT < middle - layout.y0 < layout.height - TOP_PT
                (body if inside else margins).append(c.get_text())
        pages.append({"body": _squash("".join(body)), "margins": _squash("".join(margins))})
    return pages


def expected_items(summary: dict) -> list[tuple[str, str]]:
    """``[(what, text)]``: the summary's figures as the certificate's template renders them,
    in the page's order, white space removed (module notes)."""
    import lxml.html

    from calflow.certificate.page import render

    campaign = {"name": summary.get("campaign", ""), "robot": summary.get("robot", "")}
    root = lxml.html.fromstring(render(summary, campaign, ""))
    wanted = (  # an XPath union: the nodes in the page's order
        '//section[@id="as-found-left"]//tr[@data-model] | //p[@id="rule"] | //ul[@id="decisions"]/li'
        ' | //p[.//*[@id="overall"]] | //section[@id="results"]//tr[@data-key]'
        ' | //section[@id="budgets"]/div[@class="keep"]'
    )
    items = []
    for node in root.xpath(wanted):
        if node.get("data-model"):
            what = f"model {node.get('data-model')} {node.get('data-state').replace('_', ' ')}"
        elif node.get("id") == "rule":
            if node.get("data-rule") == "none":  # without a specification the text names the stage
                continue
            what = "the decision rule and specification"
        elif node.tag == "li":
            what = f"the {node.get('data-state').replace('_', '-')} decision"
        elif node.get("data-key"):
            what = f"result {node.get('data-key')}"
        elif node.tag == "div":
            what = f"the budget '{node.xpath('.//caption')[0].text_content().split(':')[0].strip()}'"
        else:
            what = "the decision"
        items.append((what, _squash(node.text_content())))
    return items


def compare(pdf: bytes, summary: dict, number: str, signed: bool, name: str) -> int:
    """Raise :class:`Differs` at the first item of the PDF's text that differs from the
    certificate the summary gives (module notes); the number of items compared."""
    pages = pdf_text(pdf)
    if not pages:
        raise Differs(f"{name}: the PDF has no page")
    for i, page in enumerate(pages, 1):
        need = {"the certificate number": number, "its place": f"page{i}of{len(pages)}"}
        need |= {} if signed else {"that it is": "UNSIGNED"}
        for what, text in need.items():
            if text not in page["margins"]:
                raise Differs(f"{name}: page {i}'s header and footer do not show {what} {text!r}")
        if not signed and "digitallysigned" in page["margins"]:
            raise Differs(f"{name}: page {i} says it is digitally signed; the file carries no signature")
    for i, page in enumerate(pages, 1):  # every number the page shows is this one
        for part in ("margins", "body"):
            text = page[part]
            for at in (j for j in range(len(text)) if text.startswith("CF-", j)):
                if text[at : at + len(number)] != number:
                    shown = text[at : at + len(number)]
                    raise Differs(
                        f"{name}: page {i} shows certificate number {shown!r}, the results give {number!r}"
                    )
    body = "".join(p["body"] for p in pages)
    heading = f"Calibrationcertificate{number}"
    if heading not in body:
        raise Differs(f"{name}: its heading does not show the certificate number {number}")
    at = body.index(heading) + len(heading)
    items = expected_items(summary)
    for what, want in items:
        found = body.find(want, at)
        if found < 0:
            start = _row_start(body, at, want)
            k = next((j for j, (a, b) in enumerate(zip(want, body[start:])) if a != b), len(want))
            lo = max(0, k - 16)
            raise Differs(
                f"{name}: the page's text of {what} is not what the results on disk give: "
                f"it shows {body[start + lo : start + k + 16]!r} where they give {want[lo : k + 16]!r}"
            )
        at = found + len(want)
    return len(items)


def _row_start(body: str, at: int, want: str) -> int:
    """Where the page's version of ``want`` most likely begins: the longest prefix of ``want``
    found after ``at`` (a row's label and key come before its numbers)."""
    best = at
    lo, hi = 1, len(want)
    while lo <= hi:  # the longest prefix present (a prefix of a present prefix is present)
        mid = (lo + hi) // 2
        found = body.find(want[:mid], at)
        if found >= 0:
            best, lo = found, mid + 1
        else:
            hi = mid - 1
    return best
