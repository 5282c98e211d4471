"""The Digital Calibration Certificate (DCC): ``reports/<campaign>/certificate.xml``.

PTB's DCC is the machine-readable calibration certificate labs exchange: an XML document
of schema ``https://ptb.de/dcc`` (version :data:`SCHEMA_VERSION`) whose quantities are D-SI
elements (``https://ptb.de/si``, version 2.1.0). calflow writes

* ``administrativeData``: calflow as the software, the certificate's number
  (:func:`calflow.certificate.document.number`) and dates, the item (manufacturer, model,
  serial number), the laboratory, the approver as the responsible person, the customer,
  and statements — the decision rule, each labelled decision (as found, as left) and the
  traceability;
* ``measurementResults``: one ``measurementResult`` per state (as found, as left, other
  results), each with the standards used, the temperature the runs recorded
  (``influenceConditions``), and per figure a ``quantity`` whose ``si:real`` carries the value,
  its unit, and ``si:expandedUnc`` (U, k, coverage probability); ``si:label`` is the figure's
  key in ``summary.json`` (``models.III.accuracy_um``), and the conformity statement with its
  limit and rule is the quantity's ``measurementMetaData``.

Values are written with Python's shortest round-trip representation, so a reader gets back
the summary's floats exactly (``calflow verify-certificate`` compares them).
"""

from __future__ import annotations

import math

SCHEMA_VERSION = "3.1.2"
DCC = "https://ptb.de/dcc"
SI = "https://ptb.de/si"
NSMAP = {"dcc": DCC, "si": SI}
#: D-SI unit strings of the summary's unit suffixes.
UNITS = {"um": r"\micro\metre", "nm": r"\nano\metre", "deg": r"\degree", "degC": r"\degreeCelsius"}
#: DCC conformity statements of calflow's decisions (ILAC-G8 wording).
CONFORMITY = {
    "pass": "pass",
    "conditional pass": "conditionalPass",
    "conditional fail": "conditionalFail",
    "fail": "fail",
}
STATES = (
    ("as_found", "As found (before adjustment)"),
    ("as_left", "As left (after adjustment)"),
    ("", "Results"),
)


def number_text(v: float) -> str:
    """A float as D-SI's decimal: Python's shortest round-trip form (``repr``)."""
    return repr(float(v))


def _el(parent, tag: str, text=None, **attrib):
    from lxml import etree

    ns, name = tag.split(":")
    e = etree.SubElement(parent, f"{{{NSMAP[ns]}}}{name}", {k: str(v) for k, v in attrib.items()})
    if text is not None:
        e.text = str(text)
    return e


def _text(parent, tag: str, text: str):
    """A ``dcc:textType`` element: one English ``dcc:content``."""
    e = _el(parent, tag)
    _el(e, "dcc:content", text, lang="en")
    return e


def _contact(parent, tag: str, name: str, email: str, address: str):
    """A ``dcc:contactType``: name, e-mail (may be empty) and the address as free text."""
    e = _el(parent, tag)
    _text(e, "dcc:name", name)
    _el(e, "dcc:eMail", email)
    loc = _el(e, "dcc:location")
    _text(loc, "dcc:further", address)
    return e


def _real(parent, label: str, value: float, unit: str, unc: dict | None = None):
    """An ``si:real`` with its expanded uncertainty when given (``{U, k, coverage}``)."""
    real = _el(parent, "si:real")
    _el(real, "si:label", label)
    _el(real, "si:value", number_text(value))
    _el(real, "si:unit", unit)
    if unc is not None:
        exp = _el(real, "si:expandedUnc")
        _el(exp, "si:uncertainty", number_text(unc["U"]))
        _el(exp, "si:coverageFactor", number_text(unc["k"]))
        _el(exp, "si:coverageProbability", f"{float(unc.get('coverage', 0.95)):.6f}".rstrip("0"))
    return real


def _finite(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _ident(dotted: str) -> str:
    """An xs:ID of a summary key (letters, digits, ``_``, ``-``, ``.``)."""
    return "q-" + "".join(c if c.isalnum() or c in "_-." else "_" for c in dotted)


def _administrative(root, doc: dict, summary: dict) -> None:
    from calflow import __version__

    adm = _el(root, "dcc:administrativeData")
    sw = _el(_el(adm, "dcc:dccSoftware"), "dcc:software")
    _text(sw, "dcc:name", "calflow")
    _el(sw, "dcc:release", __version__)
    core = _el(adm, "dcc:coreData")
    lab = doc["laboratory"]
    _el(core, "dcc:countryCodeISO3166_1", lab.get("country") or "ZZ")
    _el(core, "dcc:usedLangCodeISO639_1", "en")
    _el(core, "dcc:mandatoryLangCodeISO639_1", "en")
    _el(core, "dcc:uniqueIdentifier", doc["number"])
    cal = doc["calibrated"]
    _el(core, "dcc:beginPerformanceDate", (cal["start"] or doc["issued"])[:10])
    _el(core, "dcc:endPerformanceDate", (cal["end"] or cal["start"] or doc["issued"])[:10])
    _el(core, "dcc:performanceLocation", "laboratory")
    item = doc["item"]
    it = _el(_el(adm, "dcc:items"), "dcc:item")
    _text(it, "dcc:name", item.get("model") or summary.get("robot") or "positioning stage")
    _text(it, "dcc:description", item.get("description") or summary.get("description") or doc["campaign"])
    _text(_el(it, "dcc:manufacturer"), "dcc:name", item.get("manufacturer") or "not given")
    if item.get("model"):
        _el(it, "dcc:model", item["model"])
    ident = _el(_el(it, "dcc:identifications"), "dcc:identification")
    _el(ident, "dcc:issuer", "manufacturer")
    _el(ident, "dcc:value", item.get("serial_number") or "not given")
    _text(ident, "dcc:name", "serial number")
    cl = _el(adm, "dcc:calibrationLaboratory")
    if lab.get("accreditation"):
        _el(cl, "dcc:calibrationLaboratoryCode", lab["accreditation"])
    _contact(
        cl,
        "dcc:contact",
        lab.get("name") or "not named",
        lab.get("email") or "",
        lab.get("address") or "not given",
    )
    person = _el(_el(adm, "dcc:respPersons"), "dcc:respPerson")
    approver = doc.get("approver") or {}
    _text(_el(person, "dcc:person"), "dcc:name", approver.get("name") or "no approver named")
    _el(person, "dcc:role", approver.get("role") or "not given")
    _el(person, "dcc:mainSigner", "true")
    _el(person, "dcc:cryptElectronicSignature", "false" if doc["signature"] == "unsigned" else "true")
    _contact(adm, "dcc:customer", item.get("customer") or "not given", item.get("customer_email") or "", "—")
    statements = _el(adm, "dcc:statements")
    cert = summary.get("certificate") or {}
    if cert.get("decision_rule"):
        st = _el(statements, "dcc:statement", refType="basic_conformity")
        _el(st, "dcc:norm", "ILAC-G8:09/2019")
        _el(st, "dcc:norm", "JCGM 106:2012")
        _text(st, "dcc:declaration", f"Decision rule {cert['decision_rule']}: {cert.get('rule_text')}")
        for d in doc["decisions"]:
            st = _el(
                statements, "dcc:statement", id=f"decision-{d['state']}", refType=f"calflow_{d['state']}"
            )
            final = " (the state the item leaves the laboratory in)" if d["final"] else ""
            _text(st, "dcc:declaration", f"{d['label'].capitalize()}: {d['decision']}{final}")
            _el(st, "dcc:conformity", CONFORMITY[d["decision"]])
    st = _el(statements, "dcc:statement", refType="basic_traceability")
    _el(st, "dcc:traceable", "true" if cert.get("traceability") else "false")
    _text(st, "dcc:declaration", doc["traceability"])
    st = _el(statements, "dcc:statement", refType="calflow_signature")
    _text(
        st,
        "dcc:declaration",
        "unsigned" if doc["signature"] == "unsigned" else f"signed by {doc['signature']}",
    )


def _environment(parent, env: dict) -> None:
    t = env.get("temperature_degC")
    conds = _el(parent, "dcc:influenceConditions")
    cond = _el(conds, "dcc:influenceCondition", refType="basic_temperature")
    _text(cond, "dcc:name", "temperature during the runs")
    _text(cond, "dcc:description", env.get("statement") or "not recorded")
    data = _el(cond, "dcc:data")
    if not t:
        _text(data, "dcc:text", "not recorded")
        return
    for key in ("min", "max", "mean"):
        if _finite(t.get(key)):
            q = _el(data, "dcc:quantity", refType=f"basic_temperature{key.capitalize()}")
            _real(q, f"certificate.environment.temperature_degC.{key}", t[key], UNITS["degC"])


def _results(root, doc: dict, rows: list[dict], summary: dict) -> None:
    from calflow.certificate.document import NORMS, STANDARDS

    results = _el(root, "dcc:measurementResults")
    cert = summary.get("certificate") or {}
    kinds = {f.get("kind") for f in cert.get("figures", [])}
    if not any(_finite(r["value"]) for r in rows):  # the schema asks for one result at least
        mr = _el(results, "dcc:measurementResult", refType="calflow_result")
        _text(mr, "dcc:name", "Results")
        result = _el(_el(mr, "dcc:results"), "dcc:result")
        _text(result, "dcc:name", "no result with an uncertainty")
        _text(
            _el(result, "dcc:data"),
            "dcc:text",
            "calflow computes no uncertainty for this campaign's figures: the certificate states none",
        )
        return
    for state, title in STATES:
        mine = [r for r in rows if r["state"] == state and _finite(r["value"])]
        if not mine:
            continue
        mr = _el(results, "dcc:measurementResult", refType=f"calflow_{state or 'result'}")
        _text(mr, "dcc:name", title)
        methods = _el(mr, "dcc:usedMethods")
        for k in ("iso9283", "iso230_2"):
            if k in kinds:
                m = _el(methods, "dcc:usedMethod")
                _text(m, "dcc:name", STANDARDS[k])
                _el(m, "dcc:norm", NORMS[k])
        _environment(mr, doc["environment"])
        res = _el(mr, "dcc:results")
        for r in mine:
            unit = UNITS.get(r["key"].rsplit("_", 1)[-1], "\\one")
            result = _el(res, "dcc:result", id=_ident(r["dotted"]))
            _text(result, "dcc:name", f"{r['label']}: {r['key']}")
            q = _el(_el(result, "dcc:data"), "dcc:quantity")
            u = r["uncertainty"] if r["uncertainty"] and _finite(r["uncertainty"].get("U")) else None
            _real(q, r["dotted"], r["value"], unit, u)
            cf = r["conformity"]
            if cf and cf.get("decision"):
                meta = _el(_el(q, "dcc:measurementMetaData"), "dcc:metaData", refType="basic_conformity")
                _el(meta, "dcc:norm", "ILAC-G8:09/2019")
                _text(meta, "dcc:declaration", f"{cf['rule']}: {cf['decision']}, upper limit {cf['spec']!r}")
                _el(meta, "dcc:conformity", CONFORMITY[cf["decision"]])
                lim = _el(_el(meta, "dcc:data"), "dcc:quantity", refType="basic_toleranceLimitUpper")
                _real(lim, f"{r['dotted']}:limit", cf["spec"], unit)


def build(summary: dict, doc: dict) -> bytes:
    """The DCC of a campaign (module notes), as UTF-8 XML bytes."""
    from lxml import etree

    from calflow.certificate.document import rows

    root = etree.Element(f"{{{DCC}}}digitalCalibrationCertificate", nsmap=NSMAP)
    root.set("schemaVersion", SCHEMA_VERSION)
    _administrative(root, doc, summary)
    _results(root, doc, rows(summary), summary)
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)
