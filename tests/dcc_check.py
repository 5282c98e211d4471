"""Checks of a Digital Calibration Certificate that do not use calflow's own code: PTB's
schema (vendored in tests/certificate/dcc_schema, LGPL-3.0) through xmlschema, and the
dcc-json-toolkit reader."""

from __future__ import annotations

import shutil
from pathlib import Path

SCHEMA = Path(__file__).parent / "certificate" / "dcc_schema"


def local_schema(folder: Path) -> Path:
    """The vendored dcc.xsd with its D-SI import pointed at the vendored copy (no network)."""
    shutil.copy(SCHEMA / "SI_Format.xsd", folder / "SI_Format.xsd")
    text = (SCHEMA / "dcc.xsd").read_text()
    text = text.replace("https://ptb.de/si/v2.1.0/SI_Format.xsd", "SI_Format.xsd")
    (folder / "dcc.xsd").write_text(text)
    return folder / "dcc.xsd"


def schema_errors(xml: bytes, folder: Path) -> list[str]:
    import xmlschema

    schema = xmlschema.XMLSchema(str(local_schema(folder)))
    return [str(e).splitlines()[0] for e in schema.iter_errors(xml.decode())]


def read_back(xml: bytes, folder: Path) -> dict:
    """The DCC as dcc-json-toolkit reads it (schema-aware, another code base than calflow's)."""
    from dcc_json_toolkit import DccSchema

    reader = DccSchema("3.1.2", no_cache=True, schema_url=str(local_schema(folder)))
    return reader.to_dict(xml.decode())


def results_read_back(dcc: dict) -> dict:
    """label → (value, U, k, conformity) of every result quantity the reader returns."""
    out = {}
    for mr in dcc["dcc:measurementResults"]["dcc:measurementResult"]:
        for r in mr["dcc:results"]["dcc:result"]:
            if "dcc:quantity" not in r["dcc:data"]:  # a statement in words (no result with a U)
                continue
            q = r["dcc:data"]["dcc:quantity"][0]
            real = q["si:real"]
            unc = real.get("si:expandedUnc") or {}
            meta = (q.get("dcc:measurementMetaData") or {}).get("dcc:metaData") or [{}]
            out[real["si:label"]] = (
                real["si:value"],
                unc.get("si:uncertainty"),
                unc.get("si:coverageFactor"),
                meta[0].get("dcc:conformity"),
            )
    return out
