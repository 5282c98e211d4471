"""Each rule hands its job the campaign sections it reads and digests the same: the job
cannot read another (calflow.configuration.campaign.Campaign.only), and Snakemake reruns it when a section
it reads changes, not when another does."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest
import yaml
from conftest import ROOT, snakemake

from calflow.configuration.campaign import SectionNotHanded, load
from calflow.configuration.config import digest

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
    # the certificate states the campaign's plan by its digest: its step reads (and its rule
    # digests) every section
    from calflow.step import ALL
    from calflow.steps import step

    assert ALL in step("certificate").sections()
    assert re.search(r'\*\*reads\("certificate"\)', rule)
    assert "--sections {params.sections" in rule


def _params_changed(work: Path) -> set[str]:
    """The rules of the jobs Snakemake would rerun because their params changed (a dry run's
    reasons; Snakemake's --list-changes params lists every file whatever changed)."""
    proc = snakemake(work, "-n")
    assert proc.returncode == 0, proc.stderr[-3000:]
    out, rules, rule = proc.stdout + proc.stderr, set(), None
    for line in out.splitlines():
        m = re.match(r"^\s*(?:local)?rule (\w+):", line)  # grouped jobs are indented
        if m:
            rule = m.group(1)
        elif rule and line.strip().startswith("reason:") and "Params have changed" in line:
            rules.add(rule)
    return rules


def _edit(work: Path, **sections) -> None:
    path = work / "config" / "campaigns" / "c.yaml"
    data = yaml.safe_load(path.read_text())
    path.write_text(yaml.safe_dump({**data, **sections}, sort_keys=False))


def test_a_section_a_step_reads_reruns_it_and_another_does_not(reduced_run, tmp_path):
    work = tmp_path / "project"
    shutil.copytree(reduced_run, work, symlinks=True)
    assert _params_changed(work) == set()
    _edit(work, description="another description")  # the summary reads it (and the certificate,
    # which is rerun for its new input already, as the report is)
    changed = _params_changed(work)
    assert "summarise" in changed
    assert "acquire" not in changed and "identify" not in changed
    _edit(work, start="2026-03-02T09:00:00+01:00")  # the acquisitions read it
    assert "acquire" in _params_changed(work)


def test_a_step_handed_one_key_of_a_section_reads_no_other_key_of_it():
    import copy
    import pickle

    c = load(FOLDER / "demo-sn0042-2026-01.yaml")
    seen = c.only(["robot", "validation.heldout", "validation.dwell_s"], "calflow acquire")
    assert seen["validation"]["heldout"] == c["validation"]["heldout"]
    assert seen["validation"].get("dwell_s") == c["validation"]["dwell_s"]
    with pytest.raises(SectionNotHanded, match=r"calflow acquire read section 'validation.cycles'"):
        seen["validation"]["cycles"]
    assert set(seen["validation"]) == {"heldout", "dwell_s"}
    # the digest covers the keys handed: another key of the section leaves it alone
    assert c.digest(["validation.heldout"]) == digest([c["validation"]["heldout"]])
    assert c.digest(["validation.heldout"]) != c.digest(["validation.dwell_s"])
    # a job's worker processes get the same view; a copy is a plain dict of what was handed
    again = pickle.loads(pickle.dumps(seen))
    assert set(again["validation"]) == {"heldout", "dwell_s"}
    with pytest.raises(SectionNotHanded):
        again["models"]
    assert copy.deepcopy(seen)["validation"] == {k: c["validation"][k] for k in ("heldout", "dwell_s")}


def test_the_digest_of_a_nested_key_is_what_the_step_is_handed():
    c = load(FOLDER / "demo-sn0042-2026-01.yaml")
    key = "validation.heldout.targets"
    seen = c.only([key], "calflow acquire")
    assert c.part(key) == seen["validation"]["heldout"]["targets"] == c["validation"]["heldout"]["targets"]
    with pytest.raises(SectionNotHanded, match=r"read section 'validation.heldout.cycles'"):
        seen["validation"]["heldout"]["cycles"]
    assert c.digest([key]) != c.digest(["validation.heldout.cycles"])
    assert c.part("validation.nothing.here") is None and c.part("start.year") is None
