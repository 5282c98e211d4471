"""Each rule hands its job the campaign sections it reads and digests the same: the job
cannot read another (calflow.campaign.Campaign.only)."""

from __future__ import annotations

import re

import pytest
from conftest import ROOT

from calflow.campaign import SectionNotHanded, load

FOLDER = ROOT / "config" / "campaigns"


def test_a_step_reads_only_the_sections_its_rule_hands_it():
    c = load(FOLDER / "demo-sn0042-2026-01.yaml")
    seen = c.only(["stage", "start"], "calflow certificate")
    assert seen["stage"] == c["stage"] and seen.get("start") == c["start"] and seen["name"] == c.name
    for read in (lambda: seen["models"], lambda: seen.get("rig"), lambda: "description" in seen):
        with pytest.raises(
            SectionNotHanded, match=r"calflow certificate read section '(models|rig|description)'"
        ):
            read()
    assert set(seen) == {"stage", "start", "name"}
    assert c.digest(["stage", "start"]) == load(FOLDER / "demo-sn0042-2026-01.yaml").digest(
        ["stage", "start"]
    )


def test_the_certificate_rule_hands_what_it_digests():
    rule = (ROOT / "workflow" / "rules" / "certificate.smk").read_text()
    assert re.search(r'\*\*reads\("certificate", "stage", "start"\)', rule)
    assert "--sections {params.sections" in rule
