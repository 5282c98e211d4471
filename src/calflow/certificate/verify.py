"""``calflow verify-certificate FILE``: is this certificate what the results on disk say, and who signed it?

FILE is a campaign's ``certificate.xml`` (the DCC) or ``certificate.pdf`` (which carries its
DCC as an embedded file, ``certificate.xml``). The command checks, and refuses in one line
naming what differs (exit 1) at the first failure:

1. the signature, when the document has one: a DCC's XAdES signature (signxml) or a PDF's
   PAdES signature (pyHanko: intact, covering the whole file, nothing changed after it), and
   the signer's certificate chain up to ``--trust CA.pem`` when given (without it only the
   signature's integrity is checked, and the command says so);
2. the values: every result of the DCC (value, U, k) equals the summary's figure of the same
   key (``si:label``), every figure of the summary with a U is in the DCC, each decision
   equals the summary's, and the certificate's number is the one the summary gives
   (:func:`calflow.certificate.document.number`: a changed result changes it).

3. for a PDF, its visible text (:mod:`calflow.certificate.visible`): the number, "page i of
   n" and "UNSIGNED" on every page, and every value, U, k, decision and budget of the page
   as the template renders them from the summary; a signature covers the text, an unsigned
   file is checked on it all the same.

An unsigned document passes on its values, and the command says it is unsigned: anyone
could have written it.
The summary is ``results/<campaign>/summary.json`` beside the ``reports/<campaign>/`` the
file is in, or ``--summary``.
"""

from __future__ import annotations

import math
from pathlib import Path

from calflow.configuration import layout
from calflow.errors import CalflowError


class Refused(CalflowError):
    """The certificate does not hold: one line naming what differs."""


def _same(a, b) -> bool:
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        return float(a) == float(b) or (math.isnan(a) and math.isnan(b))
    return a == b


def _dig(summary: dict, dotted: str):
    node = summary
    for key in dotted.split("."):
        if not isinstance(node, dict) or key not in node:
            return None
        node = node[key]
    return node


def read_dcc(xml: bytes) -> dict:
    """``{number, serial, results: {key: {value, U, k, decision}}}`` of a DCC calflow wrote."""
    from lxml import etree

    from calflow.certificate.dcc import CONFORMITY, DCC, SI

    ns = {"dcc": DCC, "si": SI}
    root = etree.fromstring(xml, parser=etree.XMLParser(resolve_entities=False, no_network=True))
    number = root.findtext("dcc:administrativeData/dcc:coreData/dcc:uniqueIdentifier", namespaces=ns)
    serial = root.findtext(
        "dcc:administrativeData/dcc:items/dcc:item/dcc:identifications/dcc:identification/dcc:value",
        namespaces=ns,
    )
    back = {v: k for k, v in CONFORMITY.items()}
    results = {}
    for q in root.iterfind(".//dcc:results/dcc:result/dcc:data/dcc:quantity", namespaces=ns):
        real = q.find("si:real", ns)
        key = real.findtext("si:label", namespaces=ns)
        entry = {"value": float(real.findtext("si:value", namespaces=ns))}
        unc = real.find("si:expandedUnc", ns)
        if unc is not None:
            entry["U"] = float(unc.findtext("si:uncertainty", namespaces=ns))
            entry["k"] = float(unc.findtext("si:coverageFactor", namespaces=ns))
        conformity = q.findtext("dcc:measurementMetaData/dcc:metaData/dcc:conformity", namespaces=ns)
        entry["decision"] = back.get(conformity) if conformity else None
        results[key] = entry
    return {"number": number, "serial": serial, "quantities": results}


def compare(dcc: dict, summary: dict, name: str) -> int:
    """Refuse (:class:`Refused`) the first value of ``dcc`` that differs from ``summary``;
    the number of results compared."""
    from calflow.certificate.document import digest, rows

    for key, got in dcc["quantities"].items():
        parent_key, _, leaf = key.rpartition(".")
        parent = _dig(summary, parent_key) if parent_key else summary
        if not isinstance(parent, dict) or leaf not in parent:
            raise Refused(f"{name}: result {key}: not in the results on disk")
        if not _same(got["value"], parent[leaf]):
            raise Refused(
                f"{name}: result {key}: the certificate says {got['value']!r}, the results {parent[leaf]!r}"
            )
        unc = (parent.get("uncertainty") or {}).get(leaf)
        for field in ("U", "k"):
            if field in got and (unc is None or not _same(got[field], unc.get(field))):
                mine = unc.get(field) if unc else None
                raise Refused(f"{name}: result {key}: {field} is {got[field]!r}, the results give {mine!r}")
        cf = (parent.get("conformity") or {}).get(leaf)
        if got["decision"] != (cf or {}).get("decision"):
            raise Refused(
                f"{name}: result {key}: decision {got['decision']!r}, the results give {(cf or {}).get('decision')!r}"
            )
    for r in rows(summary):
        if r["uncertainty"] and isinstance(r["value"], (int, float)) and r["dotted"] not in dcc["quantities"]:
            raise Refused(
                f"{name}: result {r['dotted']} of the results on disk is missing from the certificate"
            )
    expected = digest(summary)
    if not str(dcc["number"]).endswith(f"-{expected}"):
        raise Refused(
            f"{name}: certificate number {dcc['number']}, the results on disk give one ending {expected}: they differ"
        )
    return len(dcc["quantities"])


def check_xml_signature(xml: bytes, trust: str | None, name: str) -> str:
    """The XAdES signature of a DCC checked: who signed it, and how far; 'unsigned' without one."""
    from lxml import etree
    from signxml import SignatureConfiguration
    from signxml.exceptions import InvalidInput, InvalidSignature
    from signxml.xades import XAdESVerifier

    from calflow.certificate.signing import DS

    root = etree.fromstring(xml, parser=etree.XMLParser(resolve_entities=False, no_network=True))
    sig = root.find(f".//{{{DS}}}Signature")
    if sig is None:
        return "unsigned"
    config = SignatureConfiguration(expect_references=3)
    try:
        if trust:
            XAdESVerifier().verify(xml, ca_pem_file=trust, expect_config=config)
        else:
            cert = sig.findtext(f".//{{{DS}}}X509Certificate")
            XAdESVerifier().verify(xml, x509_cert=cert, expect_config=config)
    except (InvalidSignature, InvalidInput) as exc:
        against = f" with a chain to {trust}" if trust else ""
        raise Refused(f"{name}: XAdES signature does not hold{against}: {str(exc).splitlines()[0]}") from None
    return "signed (XAdES), chain checked against " + trust if trust else "signed (XAdES), chain not checked"


def pdf_parts(pdf: bytes, trust: str | None, name: str) -> tuple[str, bytes]:
    """A PDF certificate's signature status (checked) and its embedded DCC."""
    import logging
    from io import BytesIO

    from pyhanko.pdf_utils.reader import PdfFileReader
    from pyhanko.sign.validation import validate_pdf_signature
    from pyhanko_certvalidator import ValidationContext

    try:
        reader = PdfFileReader(BytesIO(pdf), strict=False)
        names = reader.root["/Names"]["/EmbeddedFiles"]["/Names"]
    except Exception as exc:  # pyHanko raises its own errors and KeyError for a missing entry
        raise Refused(
            f"{name}: expected a calflow certificate PDF carrying its DCC ({type(exc).__name__})"
        ) from None
    xml = None
    for i in range(0, len(names), 2):
        if str(names[i]) == "certificate.xml":
            xml = names[i + 1].get_object()["/EF"]["/F"].get_object().data
    if xml is None:
        raise Refused(f"{name}: expected an embedded certificate.xml (the DCC); it has none")
    sigs = reader.embedded_signatures
    logging.getLogger("pyhanko").setLevel(logging.CRITICAL)  # its tracebacks: the verdict says it in one line
    logging.getLogger("pyhanko_certvalidator").setLevel(logging.CRITICAL)
    if not sigs:
        return "unsigned", xml
    if trust:
        from pyhanko.keys import load_cert_from_pemder

        context = ValidationContext(trust_roots=[load_cert_from_pemder(trust)])
    else:
        context = ValidationContext(trust_roots=[], allow_fetching=False)
    for sig in sigs:
        status = validate_pdf_signature(sig, context)
        if not (status.intact and status.valid):
            raise Refused(f"{name}: PAdES signature does not hold: the signed bytes were changed")
        if status.coverage.name != "ENTIRE_FILE" or status.modification_level.name != "NONE":
            raise Refused(
                f"{name}: PAdES signature does not cover the whole file: it was changed after signing"
            )
        if trust and not status.trusted:
            raise Refused(f"{name}: the signer's certificate does not chain to {trust}")
    how = f"chain checked against {trust}" if trust else "chain not checked"
    return f"signed (PAdES), {how}", xml


def verify(path: str, summary_path: str | None = None, trust: str | None = None) -> str:
    """The one-line verdict of a certificate file (module notes); :class:`Refused` otherwise."""
    from calflow.data.io import load_summary

    file = Path(path)
    if not file.is_file():
        raise Refused(f"{path}: file not found")
    data = file.read_bytes()
    if file.suffix == ".pdf":
        status, xml = pdf_parts(data, trust, path)
        inner = check_xml_signature(xml, trust, f"{path} (embedded DCC)")
        if status == "unsigned" and inner != "unsigned":
            status = inner
    elif file.suffix == ".xml":
        xml, status = data, check_xml_signature(data, trust, path)
    else:
        raise Refused(f"{path}: expected a certificate.pdf or certificate.xml")
    summary_file = (
        Path(summary_path) if summary_path else file.resolve().parents[2] / layout.summary(file.parent.name)
    )
    if not summary_file.is_file():
        raise Refused(
            f"{path}: the results it certifies are not on disk (expected {summary_file}; give --summary)"
        )
    try:
        dcc = read_dcc(xml)
    except Exception as exc:  # lxml and float() errors on a damaged document
        raise Refused(f"{path}: not a readable calflow DCC ({type(exc).__name__}: {exc})") from None
    summary = load_summary(summary_file)
    n = compare(dcc, summary, path)
    shown = ""
    if file.suffix == ".pdf":
        from calflow.certificate import visible

        try:
            items = visible.compare(data, summary, dcc["number"], status != "unsigned", path)
        except visible.Differs as exc:
            raise Refused(str(exc)) from None
        shown = f", and its pages show them ({items} rows and statements)"
    return f"{path}: certificate {dcc['number']}: {n} results equal {summary_file}{shown}; {status}"


def run(args) -> None:
    """``calflow verify-certificate``."""
    print(verify(args.file, args.summary, args.trust))
