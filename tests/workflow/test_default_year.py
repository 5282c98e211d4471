"""Stage SN-0042's year of the default run, then one campaign at a time as a lab runs them: nothing
earlier lost, the history never shrinks (the run: tests/conftest.py, ``thesis_run``)."""

import json
import re

import pytest
from conftest import SOURCE_DATE_EPOCH, snakemake

# The lab's way (docs/lifecycle.md): after the default run, campaigns of the stage are run one
# at a time. A copy of the year's folders (not of the whole run) keeps this cheap: one small
# calibration and one interim check are run, plus two runs that stop before their history.
YEAR = [
    "demo-sn0042-2026-01",
    "demo-sn0042-2026-04-check",
    "demo-sn0042-2026-07-check",
    "demo-sn0042-2026-07",
    "demo-sn0042-2026-10-check",
]
HISTORY = "results/stages/SN-0042/history.json"


@pytest.fixture(scope="module")
def year(thesis_run, tmp_path_factory):
    """The default run's project with only SN-0042's campaigns on disk (times kept)."""
    import shutil

    work = tmp_path_factory.mktemp("year") / "project"
    work.mkdir()
    shutil.copy(thesis_run / "Snakefile", work / "Snakefile")
    for sub in ["workflow", "config", "results/stages/SN-0042", "reports/stages/SN-0042"] + [
        f"{top}/{name}" for name in YEAR for top in ("results", "reports")
    ]:
        shutil.copytree(thesis_run / sub, work / sub)
    return work


def _digests(work, *tops):
    import hashlib

    return {
        str(p.relative_to(work)): hashlib.sha256(p.read_bytes()).hexdigest()
        for top in tops
        for p in sorted((work / top).rglob("*"))
        if p.is_file() and "/logs/" not in str(p) and "/benchmarks/" not in str(p)
    }


def test_a_bad_campaign_of_the_stage_leaves_every_earlier_result_and_the_history(year):
    """Nothing lost: a check whose reference is itself (refused at load) and a calibration
    whose rig fails (in a job) leave the year's results, history and reports byte for byte."""
    import yaml

    before = _digests(year, "results", "reports")
    assert len([k for k in before if k.startswith("results/stages/")]) == 1
    check = yaml.safe_load((year / f"config/campaigns/{YEAR[1]}.yaml").read_text())
    check["interim_check"]["reference"] = "bad-check"
    (year / "config/campaigns/bad-check.yaml").write_text(yaml.safe_dump(check))
    proc = snakemake(year, "--config", 'campaigns=["bad-check"]')
    assert proc.returncode != 0
    assert "bad-check.yaml: key 'interim_check.reference': expected another campaign" in proc.stderr
    assert _digests(year, "results", "reports") == before
    bad = yaml.safe_load((year / f"config/campaigns/{YEAR[0]}.yaml").read_text())
    bad["start"] = "2026-12-01T08:00:00+00:00"
    bad["rig"] = {"factory": "toyrigs:open_toy", "options": {"camera": [1000.0]}}  # fails on its first read
    (year / "config/campaigns/bad-rig.yaml").write_text(yaml.safe_dump(bad))
    proc = snakemake(year, "--config", 'campaigns=["bad-rig"]', 'rig_plugins=["toyrigs"]')
    assert proc.returncode != 0
    after = _digests(year, "results", "reports")
    assert {k: v for k, v in after.items() if "/bad-rig/" not in k} == before


def test_one_campaign_at_a_time_never_shrinks_the_history(year):
    """One more calibration of SN-0042 run alone: the history lists the year and it (six). The
    April check run alone after its results were deleted comes back byte for byte, and the
    history is still six. A campaign deleted from disk leaves it, with the reason."""
    import shutil

    import yaml

    c = yaml.safe_load((year / f"config/campaigns/{YEAR[0]}.yaml").read_text())
    c.update(seed=44, start="2027-01-05T08:00:00+00:00", description="Stage SN-0042, calibration of 2027-01")
    (year / "config/campaigns/demo-sn0042-2027-01.yaml").write_text(yaml.safe_dump(c))
    # the campaign, the history and its page (not every PDF: CI time); the copy has no
    # Snakemake metadata, so the campaign's summary is asked for (its report would do too)
    page = "reports/stages/SN-0042/history.html"
    targets = ["results/demo-sn0042-2027-01/summary.json", HISTORY, page]
    proc = snakemake(
        year, *targets, "--config", 'campaigns=["demo-sn0042-2027-01"]', env_extra=SOURCE_DATE_EPOCH
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    h = json.loads((year / HISTORY).read_text())
    assert [e["campaign"] for e in h["campaigns"]] == YEAR + ["demo-sn0042-2027-01"]
    assert [(e["from"], e["to"]) for e in h["changes"]] == [
        (YEAR[0], YEAR[3]),
        (YEAR[3], "demo-sn0042-2027-01"),
    ]
    assert h["departed"] == [] and "demo-sn0042-2027-01" in (year / page).read_text()
    six = (year / HISTORY).read_bytes()

    check = year / "results" / YEAR[1]
    kept = {p: (check / p).read_bytes() for p in ("summary.json", "runs/interim_check.nc")}
    shutil.rmtree(check)
    targets = [f"results/{YEAR[1]}/summary.json", HISTORY]
    proc = snakemake(year, *targets, "--config", f'campaigns=["{YEAR[1]}"]', env_extra=SOURCE_DATE_EPOCH)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert not re.search(rf"wildcards: campaign={YEAR[0]}\b", proc.stdout + proc.stderr)  # read, not remade
    for p, data in kept.items():
        assert (check / p).read_bytes() == data, p
    assert (year / HISTORY).read_bytes() == six

    shutil.rmtree(year / "results/demo-sn0042-2027-01")
    proc = snakemake(year, HISTORY, "--config", f'campaigns=["{YEAR[1]}"]')
    assert proc.returncode == 0, proc.stderr[-3000:]
    h = json.loads((year / HISTORY).read_text())
    assert [e["campaign"] for e in h["campaigns"]] == YEAR
    assert h["departed"] == [
        {
            "campaign": "demo-sn0042-2027-01",
            "start": "2027-01-05T08:00:00+00:00",
            "kind": "calibration",
            "reason": "results/demo-sn0042-2027-01/summary.json is no longer on disk (its results were deleted)",
        }
    ]
