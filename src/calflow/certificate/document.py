"""What a calibration certificate states besides its results (ISO/IEC 17025:2017 §7.8).

§7.8.2.1 asks every report for a title, the laboratory's name and address, a unique
identification on every page and a clear end, the customer, the method, the item's
description and identification, the dates of calibration and of issue, the results with
their units, and who authorised the report; §7.8.4.1 adds, for a calibration certificate,
the measurement uncertainty, the environmental conditions that influence the results and
the metrological traceability; §7.8.6 the statement of conformity with its decision rule.
This module gathers them from the campaign, the configuration (``laboratory``,
``stages.<id>.item``) and the summary's certificate keys (:mod:`calflow.certificate.annotate`)
into one record that the PDF, the DCC (:mod:`calflow.certificate.dcc`) and
``calflow verify-certificate`` share.

The certificate's number is ``CF-<item>-<digest>``: the first 12 hex digits of the SHA-256
of the summary's canonical JSON (sorted keys, no spaces). The same results give the same
number on every rerun; a changed result gives a new one. Its issue date is the day the
document is made (``SOURCE_DATE_EPOCH`` when set, for reproducible builds).
"""

from __future__ import annotations

import datetime as dt
import hashlib
import json
import os
import re

from calflow.configuration.campaign import dig

#: The standard each kind of measurement follows (:data:`calflow.certificate.KINDS`).
STANDARDS = {
    "iso9283": "ISO 9283:1998, 7.2.1 and 7.2.2: pose accuracy AP and pose repeatability RP",
    "iso230_2": "ISO 230-2:2014: accuracy and repeatability of positioning of numerically controlled axes",
}
#: The standards' short designations (a DCC's ``dcc:norm``).
NORMS = {"iso9283": "ISO 9283:1998", "iso230_2": "ISO 230-2:2014"}
UNSIGNED = "unsigned"
STATE_LABELS = {"as_found": "as found", "as_left": "as left", "": "result"}


def canonical(summary: dict) -> bytes:
    """The summary's canonical JSON (sorted keys, compact, UTF-8): what the number digests."""
    return json.dumps(summary, sort_keys=True, separators=(",", ":"), ensure_ascii=False).encode()


def digest(summary: dict) -> str:
    """The part of the number the results give: 12 hex digits of their canonical SHA-256."""
    return hashlib.sha256(canonical(summary)).hexdigest()[:12].upper()


def number(summary: dict, item: str) -> str:
    """The certificate's unique number (module notes)."""
    safe = re.sub(r"[^A-Za-z0-9-]", "-", item or "item")[:32]
    return f"CF-{safe}-{digest(summary)}"


def issue_date() -> str:
    """Today (UTC), or the day of ``SOURCE_DATE_EPOCH`` when set."""
    epoch = os.environ.get("SOURCE_DATE_EPOCH")
    when = (
        dt.datetime.fromtimestamp(int(epoch), dt.UTC)
        if epoch and epoch.isdigit()
        else dt.datetime.now(dt.UTC)
    )
    return when.date().isoformat()


def _dates(summary: dict, campaign: dict) -> list[str]:
    """Every dated measurement of the summary (as found, as left) and the campaign's start."""
    out = [str(campaign["start"])] if campaign.get("start") else []
    for m in (summary.get("models") or {}).values() if isinstance(summary.get("models"), dict) else ():
        for key in ("as_found", "as_left"):
            d = (m.get(key) or {}).get("date") if isinstance(m, dict) else None
            out += [str(d)] if d else []
    return out


def calibration_dates(summary: dict, campaign: dict) -> dict:
    """``{start, end}``: the first and last dated measurement of the calibration (ISO 8601)."""
    dates = _dates(summary, campaign)
    if not dates:
        return {"start": None, "end": None}

    def key(d):
        return dt.datetime.fromisoformat(d.replace("Z", "+00:00"))

    return {"start": min(dates, key=key), "end": max(dates, key=key)}


def method(summary: dict, campaign: dict, version: str) -> dict:
    """The method: the standards the figures follow, the campaign's plan and calflow's procedure."""
    kinds = {f.get("kind") for f in (summary.get("certificate") or {}).get("figures", [])}
    plan = hashlib.sha256(json.dumps(campaign, sort_keys=True, default=str).encode()).hexdigest()
    return {
        "standards": [STANDARDS[k] for k in ("iso9283", "iso230_2") if k in kinds],
        "procedure": (
            f"calflow {version}: characterisation, identification and held-out validation of the "
            "calibration models (Tan, Calibration of micro and nanorobotic systems, chapters 3 to 5), "
            f"as planned by campaign {campaign['name']}"
        ),
        "plan": {"campaign": campaign["name"], "description": campaign.get("description"), "sha256": plan},
    }


def traceability(chain: list[str]) -> str:
    """The traceability statement from the sensor's declared chain (or that none is declared)."""
    if not chain:
        return (
            "The measuring system declares no chain to the SI: calflow cannot state the metrological "
            "traceability of these results."
        )
    return (
        "The results are traceable to the SI metre through: "
        + "; ".join(chain)
        + ". Where a link's calibration is not recorded, calflow cannot confirm the traceability of that link."
    )


def decisions(summary: dict) -> list[dict]:
    """The labelled decisions a lab states: as found and as left (or the result's), each with
    whether it is what the item leaves the laboratory with."""
    cert = summary.get("certificate") or {}
    given = cert.get("decisions") or {}
    out = []
    for state in ("as_found", "as_left"):
        if given.get(state):
            out.append({"state": state, "label": STATE_LABELS[state], "decision": given[state]})
    final = cert.get("decision")
    for d in out:
        d["final"] = d["state"] == "as_left" or (len(out) == 1 and d["decision"] == final)
    return out


def record(summary: dict, campaign: dict, laboratory: dict, item: dict, signed_by: str | None) -> dict:
    """Everything the certificate states besides its results (module notes)."""
    from calflow import __version__

    cert = summary.get("certificate") or {}
    item = dict(item or {})
    stage = campaign.get("stage")
    item.setdefault("serial_number", stage or None)
    lab = {k: v for k, v in (laboratory or {}).items() if k != "signing_key"}
    return {
        "title": "Calibration certificate",
        "number": number(summary, item.get("serial_number") or campaign["name"]),
        "issued": issue_date(),
        "calibrated": calibration_dates(summary, campaign),
        "laboratory": lab,
        "item": item,
        "stage": stage,
        "campaign": campaign["name"],
        "method": method(summary, campaign, __version__),
        "environment": cert.get("environment")
        or {"statement": "the environmental conditions were not recorded by this calflow version"},
        "traceability": traceability(cert.get("traceability") or []),
        "decisions": decisions(summary),
        "approver": lab.get("approver"),
        "signature": signed_by or UNSIGNED,
    }


UNITS = {"um": "µm", "nm": "nm", "deg": "°"}


def unit_of(key: str) -> str:
    """The unit of a summary key from its suffix (``accuracy_um`` → µm)."""
    return UNITS.get(key.rsplit("_", 1)[-1], "")


def rows(summary: dict) -> list[dict]:
    """One row per figure with a U or a decision: label, key, value, unit, uncertainty, conformity."""
    out = []
    for f in (summary.get("certificate") or {}).get("figures", []):
        parent = dig(summary, ".".join(f["path"])) if f["path"] else summary
        if not isinstance(parent, dict):
            continue
        key = f["key"]
        out.append(
            {
                "label": f["label"],
                "state": f.get("state", ""),
                "state_label": STATE_LABELS.get(f.get("state", ""), ""),
                "key": key,
                "dotted": ".".join([*f["path"], key]),
                "value": parent.get(key),
                "unit": unit_of(key),
                "uncertainty": (parent.get("uncertainty") or {}).get(key),
                "conformity": (parent.get("conformity") or {}).get(key),
            }
        )
    return out
