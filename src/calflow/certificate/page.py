"""The certificate page of a campaign: ``reports/<campaign>/certificate.html`` and ``.pdf``.

Everything on it is a key of the campaign's ``summary.json`` (:mod:`calflow.certificate.annotate`):
as-found and as-left values of each model when the summary has them, each result with its
U, k and effective dof, the decision rule and specification, the decision and its specific
probability of a false accept (or reject), and each figure's uncertainty budget. Rendered
with the reports' Jinja2 environment (autoescaped) and WeasyPrint, as the reports are.
"""

from __future__ import annotations

from pathlib import Path

from calflow.certificate.annotate import json_object
from calflow.certificate.document import rows


def as_found_left(summary: dict) -> list[dict]:
    """Per model with ``as_found`` or ``as_left`` values: both, and the as-found decisions."""
    out = []
    for name, m in (summary.get("models") or {}).items():
        if not isinstance(m, dict) or not (m.get("as_found") or m.get("as_left")):
            continue
        out.append(
            {"model": name, "as_found": m.get("as_found") or {}, "as_left": m.get("as_left") or {}, "m": m}
        )
    return out


def render(summary: dict, campaign: dict, command: str, doc: dict | None = None) -> str:
    """The certificate's HTML; ``doc``: its record (:func:`calflow.certificate.document.record`;
    default: no laboratory, no item settings, unsigned)."""
    from calflow.certificate.document import record
    from calflow.report.render import TEMPLATES, _machine, _versions, environment

    template = environment().get_template("certificate.html.j2")
    return template.render(
        s=summary,
        c=campaign,
        doc=doc or record(summary, campaign, {}, {}, None),
        cert=summary.get("certificate") or {},
        rows=rows(summary),
        models=as_found_left(summary),
        command=command,
        versions=_versions(),
        machine=_machine(),
        css=(TEMPLATES / "style.css").read_text(),
    )


def run(args) -> None:
    """``calflow certificate``: the page (and the DCC) from the campaign's summary."""
    from calflow.certificate.document import record
    from calflow.configuration import layout
    from calflow.configuration.handed import campaign_of
    from calflow.data.io import load_summary, write_bytes, write_text
    from calflow.report.render import write_pdf

    campaign = campaign_of(args)
    summary = load_summary(args.summary)
    laboratory = json_object(getattr(args, "laboratory", None), "calflow certificate: --laboratory")
    item = json_object(getattr(args, "item", None), "calflow certificate: --item")
    command = f"snakemake --cores 2 {layout.certificate(campaign['name'])}"
    from calflow.certificate import signing
    from calflow.certificate.dcc import build

    path = signing.key_path(laboratory)
    key = signing.load(path) if path else None
    doc = record(summary, campaign, laboratory, item, key.signer_name if key else None)
    html = render(summary, campaign, command, doc)
    xml = build(summary, doc)
    if key:
        xml = signing.sign_xml(xml, key)
    outputs = [(xml, args.xml)] if getattr(args, "xml", None) else []
    if args.pdf:
        pdf = write_pdf(html, Path(args.html).parent, {"certificate.xml": xml})
        outputs.append((signing.sign_pdf(pdf, key) if key else pdf, args.pdf))
    write_text(html, args.html)
    for data, out in outputs:
        write_bytes(data, out)
