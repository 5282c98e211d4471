"""The DCC (valid against PTB's schema, read back by an independent reader), the PAdES and
XAdES signatures, and ``calflow verify-certificate`` refusing any changed digit."""

from __future__ import annotations

import json
import shutil
import time
from pathlib import Path

import numpy as np
import pytest
import throwaway_pki
from dcc_check import read_back, results_read_back, schema_errors

from calflow.certificate import Measurement
from calflow.certificate.annotate import annotate
from calflow.certificate.dcc import build
from calflow.certificate.document import record
from calflow.cli import main

ROOT = Path(__file__).resolve().parents[2]
CAMPAIGN = "demo-sn0042-2026-01"  # a calibration of no other campaign: its file loads alone
LAB = {"name": "Test lab", "address": "1 Test street", "approver": {"name": "T. Approver", "role": "head"}}
ITEM = {"customer": "Customer AG", "manufacturer": "Maker", "model": "XY-200", "serial_number": "SN-0042"}
SPEC = {"specification": {"accuracy_um": 3.5}, "decision_rule": "non-binary"}


def _summary(monkeypatch) -> dict:
    """An XYΘ calibration's summary with its certificate keys (as found, as left, U, decisions)."""
    from calflow.metrics.iso9283 import iso9283

    rng = np.random.default_rng(11)

    def targets(offset):
        cmd = rng.uniform(-1000, 1000, (6, 2))
        return cmd, [c + [offset, 0.0] + rng.normal(0, 0.1, (4, 2)) for c in cmd]

    (cf, af), (cl, al) = targets(4.5), targets(1.0)
    ap = {
        k: max(iso9283(c, a).ap for c, a in zip(*d, strict=True))
        for k, d in (("f", (cf, af)), ("l", (cl, al)))
    }
    keys = {"accuracy": "accuracy_um", "repeatability": "repeatability_um"}
    ms = [
        Measurement(
            ("models", "III", "as_found"),
            keys,
            data={"command": cf, "attained": af},
            label="found",
            state="as_found",
        ),
        Measurement(
            ("models", "III"), keys, data={"command": cl, "attained": al}, label="left", state="as_left"
        ),
    ]
    s = {
        "campaign": CAMPAIGN,
        "robot": "xytheta",
        "description": "d",
        "models": {
            "III": {
                "accuracy_um": ap["l"],
                "repeatability_um": 0.3,
                "as_left": {"accuracy_um": ap["l"], "date": "2026-01-05T10:00:00+00:00"},
                "as_found": {
                    "accuracy_um": ap["f"],
                    "repeatability_um": 0.3,
                    "date": "2026-01-05T08:00:00+00:00",
                },
            }
        },
    }
    monkeypatch.setattr("calflow.certificate.annotate.resolve", lambda target: lambda c, f: ms)
    campaign = {
        "name": CAMPAIGN,
        "robot": "xytheta",
        "stage": "SN-0042",
        "start": "2026-01-05T08:00:00+00:00",
    }
    return json.loads(json.dumps(annotate(s, campaign, [], SPEC)))


@pytest.fixture
def project(tmp_path, monkeypatch):
    """A project folder with one campaign's summary on disk, and a throw-away CA and lab key
    outside it."""
    work = tmp_path / "project"
    (work / "config" / "campaigns").mkdir(parents=True)
    shutil.copy(ROOT / "config" / "campaigns" / f"{CAMPAIGN}.yaml", work / "config" / "campaigns")
    (work / "results" / CAMPAIGN).mkdir(parents=True)
    (work / "reports" / CAMPAIGN).mkdir(parents=True)
    summary = _summary(monkeypatch)
    (work / "results" / CAMPAIGN / "summary.json").write_text(json.dumps(summary, indent=1))
    (tmp_path / "pki").mkdir()
    pki = throwaway_pki.make(tmp_path / "pki")
    monkeypatch.chdir(work)
    monkeypatch.delenv("CALFLOW_SIGNING_KEY", raising=False)
    monkeypatch.setenv("CALFLOW_SIGNING_PASSWORD", pki["password"])
    return {"work": work, "pki": pki, "summary": summary}


def certificate(signed: bool, monkeypatch, pki) -> int:
    if signed:
        monkeypatch.setenv("CALFLOW_SIGNING_KEY", str(pki["p12"]))
    out = f"reports/{CAMPAIGN}/certificate"
    return main(
        [
            "certificate",
            "--campaign",
            f"config/campaigns/{CAMPAIGN}.yaml",
            "--summary",
            f"results/{CAMPAIGN}/summary.json",
            "--laboratory",
            json.dumps(LAB),
            "--item",
            json.dumps(ITEM),
            "--html",
            f"{out}.html",
            "--pdf",
            f"{out}.pdf",
            "--xml",
            f"{out}.xml",
        ]
    )


def test_the_dcc_is_valid_and_an_independent_reader_gets_every_value_back(tmp_path, monkeypatch):
    s = _summary(monkeypatch)
    campaign = {
        "name": CAMPAIGN,
        "robot": "xytheta",
        "stage": "SN-0042",
        "start": "2026-01-05T08:00:00+00:00",
    }
    doc = record(s, campaign, LAB, ITEM, None)
    xml = build(s, doc)
    assert schema_errors(xml, tmp_path) == []
    dcc = read_back(xml, tmp_path)
    adm = dcc["dcc:administrativeData"]
    assert adm["dcc:coreData"]["dcc:uniqueIdentifier"] == doc["number"]
    item = adm["dcc:items"]["dcc:item"][0]
    assert item["dcc:identifications"]["dcc:identification"][0]["dcc:value"] == "SN-0042"
    assert adm["dcc:customer"]["dcc:name"]["dcc:content"][0]["$"] == "Customer AG"
    assert adm["dcc:calibrationLaboratory"]["dcc:contact"]["dcc:name"]["dcc:content"][0]["$"] == "Test lab"
    got = results_read_back(dcc)
    conformity = {
        "pass": "pass",
        "conditional pass": "conditionalPass",
        "conditional fail": "conditionalFail",
    }
    conformity["fail"] = "fail"
    expected = {}
    for path in ("models.III", "models.III.as_found"):
        parent = s["models"]["III"] if path == "models.III" else s["models"]["III"]["as_found"]
        for key in ("accuracy_um", "repeatability_um"):
            u = parent["uncertainty"][key]
            cf = (parent.get("conformity") or {}).get(key)
            expected[f"{path}.{key}"] = (
                parent[key],
                u["U"],
                u["k"],
                conformity[cf["decision"]] if cf else None,
            )
    assert got == expected  # float for float: the DCC holds the summary's values exactly
    decisions = {st.get("@id"): st.get("dcc:conformity") for st in adm["dcc:statements"]["dcc:statement"]}
    assert decisions["decision-as_found"] == conformity[s["certificate"]["decisions"]["as_found"]]
    assert decisions["decision-as_left"] == conformity[s["certificate"]["decisions"]["as_left"]]


def test_a_campaign_without_a_figure_with_u_still_gives_a_valid_dcc_that_says_so(tmp_path):
    s = {"campaign": "c", "robot": "stage2d", "certificate": {"figures": [], "decisions": {}}}
    xml = build(s, record(s, {"name": "c", "robot": "stage2d"}, {}, {}, None))
    assert schema_errors(xml, tmp_path) == []
    assert results_read_back(read_back(xml, tmp_path)) == {}
    assert b"computes no uncertainty" in xml


def test_unsigned_certificates_say_so_and_verify_on_their_values(project, monkeypatch, capsys):
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1767225600")
    assert certificate(False, monkeypatch, project["pki"]) == 0
    first = (project["work"] / "reports" / CAMPAIGN / "certificate.pdf").read_bytes()
    time.sleep(1.1)  # the embedded DCC's dates are the epoch's, not the clock's: the same bytes again
    assert certificate(False, monkeypatch, project["pki"]) == 0
    assert (project["work"] / "reports" / CAMPAIGN / "certificate.pdf").read_bytes() == first
    from pdf_check import page_texts

    pages = page_texts(project["work"] / "reports" / CAMPAIGN / "certificate.pdf")
    number = record(project["summary"], {"name": CAMPAIGN, "robot": "xytheta"}, LAB, ITEM, None)["number"]
    assert len(pages) > 1
    for i, text in enumerate(pages, 1):  # the number, "unsigned" and "page x of y" on every page
        assert "UNSIGNED" in text and number in text and f"page {i} of {len(pages)}" in text
    for suffix in ("pdf", "xml"):
        assert main(["verify-certificate", f"reports/{CAMPAIGN}/certificate.{suffix}"]) == 0
        out = capsys.readouterr().out
        assert out.rstrip().endswith("unsigned") and "4 results equal" in out


def test_an_unsigned_pdf_whose_visible_text_differs_by_one_digit_is_refused(project, monkeypatch, capsys):
    """The printed page, not only its embedded DCC: one digit of a value, U, k, a decision,
    the number or "page x of y" redrawn in the PDF's content stream (an incremental update,
    as a PDF editor saves; the DCC left intact) is refused in one line naming what differs."""
    from pdf_check import change_text

    assert certificate(False, monkeypatch, project["pki"]) == 0
    rep = project["work"] / "reports" / CAMPAIGN
    pdf = (rep / "certificate.pdf").read_bytes()
    s = project["summary"]
    u = s["models"]["III"]["uncertainty"]["accuracy_um"]
    number = record(s, {"name": CAMPAIGN, "robot": "xytheta"}, LAB, ITEM, None)["number"]

    def bump(text: str) -> str:  # the last digit one up
        j = max(i for i, ch in enumerate(text) if ch.isdigit())
        return text[:j] + str((int(text[j]) + 1) % 10) + text[j + 1 :]

    value = f"{s['models']['III']['as_found']['accuracy_um']:.4f}"
    cases = [
        (value, "result models.III.as_found.accuracy_um"),  # the results table's value
        (f"{u['U']:.3f} ({u['k']:.2f})", "model III as left"),  # U (k) of the as-left row
        (number, "number"),
        ("fail", "as-found decision"),  # drawn bold, apart from its label
        ("page 2 of", "page 2"),
    ]
    for old, names in cases:
        new = old.replace("fail", "pass") if "fail" in old else bump(old)
        (rep / "t.pdf").write_bytes(change_text(pdf, old, new))
        summary = ["--summary", f"results/{CAMPAIGN}/summary.json"]
        assert main(["verify-certificate", f"reports/{CAMPAIGN}/t.pdf", *summary]) != 0, old
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and names in err, (old, err)
        assert new.replace(" ", "") in err or "do not show" in err or "heading" in err, err
    # the untouched file still verifies, and says what it compared
    assert main(["verify-certificate", f"reports/{CAMPAIGN}/certificate.pdf"]) == 0
    assert "its pages show them" in capsys.readouterr().out


def test_signed_certificates_verify_against_their_ca_and_refuse_any_change(
    project, monkeypatch, capsys, tmp_path
):
    pki = project["pki"]
    assert certificate(True, monkeypatch, pki) == 0
    rep = project["work"] / "reports" / CAMPAIGN
    xml = (rep / "certificate.xml").read_bytes()
    assert schema_errors(xml, tmp_path) == []  # the signature sits where the schema admits it
    for suffix, kind in (("pdf", "PAdES"), ("xml", "XAdES")):
        assert (
            main(
                ["verify-certificate", f"reports/{CAMPAIGN}/certificate.{suffix}", "--trust", str(pki["ca"])]
            )
            == 0
        )
        assert f"signed ({kind}), chain checked" in capsys.readouterr().out
        assert (
            main(
                [
                    "verify-certificate",
                    f"reports/{CAMPAIGN}/certificate.{suffix}",
                    "--trust",
                    str(pki["other_ca"]),
                ]
            )
            != 0
        )
        assert "calflow: error:" in capsys.readouterr().err
    # one digit changed in the DCC's first value
    text = xml.decode()
    i = text.index("<si:value>") + len("<si:value>")
    (rep / "t.xml").write_text(text[:i] + ("1" if text[i] != "1" else "2") + text[i + 1 :])
    assert (
        main(
            [
                "verify-certificate",
                f"reports/{CAMPAIGN}/t.xml",
                "--summary",
                f"results/{CAMPAIGN}/summary.json",
            ]
        )
        != 0
    )
    err = capsys.readouterr().err
    assert "XAdES signature does not hold" in err and len(err.strip().splitlines()) == 1
    # one byte of the signed PDF changed
    pdf = bytearray((rep / "certificate.pdf").read_bytes())
    pdf[len(pdf) // 3] ^= 0x01
    (rep / "t.pdf").write_bytes(bytes(pdf))
    assert (
        main(
            [
                "verify-certificate",
                f"reports/{CAMPAIGN}/t.pdf",
                "--summary",
                f"results/{CAMPAIGN}/summary.json",
            ]
        )
        != 0
    )
    assert "calflow: error:" in capsys.readouterr().err
    # one digit changed in the results on disk
    summary_file = project["work"] / "results" / CAMPAIGN / "summary.json"
    s = summary_file.read_text()
    v = repr(project["summary"]["models"]["III"]["accuracy_um"])
    j = s.index(v) + len(v) - 2
    summary_file.write_text(s[:j] + str((int(s[j]) + 1) % 10) + s[j + 1 :])
    for suffix in ("pdf", "xml"):
        assert (
            main(
                ["verify-certificate", f"reports/{CAMPAIGN}/certificate.{suffix}", "--trust", str(pki["ca"])]
            )
            != 0
        )
        err = capsys.readouterr().err
        assert "models.III.accuracy_um" in err and len(err.strip().splitlines()) == 1


def test_a_key_inside_the_project_or_missing_is_refused_in_one_line(project, monkeypatch, capsys):
    inside = project["work"] / "lab.p12"
    shutil.copy(project["pki"]["p12"], inside)
    monkeypatch.setenv("CALFLOW_SIGNING_KEY", str(inside))
    assert certificate(False, monkeypatch, project["pki"]) != 0
    err = capsys.readouterr().err.strip()
    assert "inside the project folder" in err and len(err.splitlines()) == 1
    monkeypatch.setenv("CALFLOW_SIGNING_KEY", str(project["work"].parent / "nowhere.p12"))
    assert certificate(False, monkeypatch, project["pki"]) != 0
    assert "no such file" in capsys.readouterr().err
    assert not (project["work"] / "reports" / CAMPAIGN / "certificate.pdf").exists()  # nothing half-written
