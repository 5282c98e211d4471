"""Bad inputs across campaigns (a stage's campaigns, an interim check's reference): each is
refused before any job, in one line naming the file, the key and what was expected. The
catalogue's cross-campaign part, apart from tests/bad_input/test_bad_input.py; the load-time cases
call the loader in-process, three cases go through a dry run of the workflow."""

from __future__ import annotations

import copy
import json

import pytest
import yaml
from conftest import SMALL_NANO1D, SMALL_XYTHETA, make_workdir, snakemake

from calflow.configuration.campaign import load as load_campaign
from calflow.errors import ConfigError

STAGE = "SN-9"
JAN, FEB, MAR, APR = (f"2026-{m:02d}-05T08:00:00+00:00" for m in (1, 2, 3, 4))


def calibration(**extra) -> dict:
    c = copy.deepcopy(SMALL_XYTHETA)
    c["models"] = {"II": c["models"]["II"]}
    c["xy_tests"]["compensation"] = []
    c.update({"stage": STAGE, "start": JAN, **extra})
    return c


def check(ref="ref", start=APR, **extra) -> dict:
    return {
        "robot": "xytheta",
        "stage": STAGE,
        "seed": 5,
        "start": start,
        "rig": {"factory": "simulated", "options": {"aging": False}},
        "interim_check": {"reference": ref, "model": "II", "tolerance_um": 20.0},
        **extra,
    }


# the campaign files beside the one checked (check.yaml)
FOLDER = {
    "ref": calibration(),
    "nano": {**SMALL_NANO1D, "stage": STAGE, "start": FEB},
    "other-stage": calibration(stage="SN-8", start=FEB),
    "check2": check(start=MAR),
    "loop-a": check(ref="loop-b", start=MAR),
    "loop-b": check(ref="loop-a", start=FEB),
}

# case → (check.yaml, substrings of its one line after "<file>: ")
CASES = {
    "reference is itself": (
        check(ref="check"),
        ["key 'interim_check.reference'", "expected another campaign", "'check', this campaign itself"],
    ),
    "reference is a nano campaign of the same stage": (
        check(ref="nano"),
        [
            "key 'interim_check.reference'",
            "expected a calibration of robot 'xytheta'",
            "'nano' of robot 'stage1d'",
        ],
    ),
    "reference is an interim check": (
        check(ref="check2"),
        ["key 'interim_check.reference'", "expected a calibration campaign", "itself an interim check"],
    ),
    "references in a cycle": (
        check(ref="loop-a"),
        ["key 'interim_check.reference'", "'loop-a', itself an interim check"],
    ),
    "reference of another stage": (
        check(ref="other-stage"),
        ["key 'interim_check.reference'", "expected a calibration of stage 'SN-9'", "of stage 'SN-8'"],
    ),
    "reference missing from the folder": (
        check(ref="nowhere"),
        ["key 'interim_check.reference'", "expected a campaign of", "(no nowhere.yaml)"],
    ),
    "reference name that leaves the folder": (
        check(ref="../ref"),
        ["key 'interim_check.reference'", "(letters, digits, '-' or '_'), got '../ref'"],
    ),
    "check dated before its reference": (
        check(start="2025-12-24T08:00:00+00:00"),
        ["key 'start'", "expected a start after that of its reference 'ref'", "2025-12-24"],
    ),
    "check at its reference's very start": (
        check(start="2026-01-05T09:00:00+01:00"),
        ["key 'start'", "expected a start after that of its reference 'ref'"],
    ),
    "reference without the model checked": (
        {**check(), "interim_check": {"reference": "ref", "model": "V", "tolerance_um": 20.0}},
        ["key 'interim_check.model'", "expected one of the reference's models ['II']"],
    ),
}


def _folder(tmp_path, body: dict):
    for name, spec in FOLDER.items():
        (tmp_path / f"{name}.yaml").write_text(yaml.safe_dump(spec))
    path = tmp_path / "check.yaml"
    path.write_text(yaml.safe_dump(body))
    return path


@pytest.mark.parametrize("case", list(CASES))
def test_a_bad_reference_is_refused_at_load_in_one_line(tmp_path, case):
    body, expected = CASES[case]
    path = _folder(tmp_path, body)
    with pytest.raises(ConfigError) as info:
        load_campaign(path)
    message = str(info.value)
    assert "\n" not in message and message.startswith(f"{path}: "), message
    for part in expected:
        assert part in message, message


def test_a_good_check_still_loads(tmp_path):
    c = load_campaign(_folder(tmp_path, check()))
    assert c["interim_check"]["resolved"]["runs"]


def _one_line(proc) -> str:
    lines = [line for line in proc.stderr.splitlines() if line.startswith("calflow: error:")]
    assert proc.returncode != 0 and len(lines) == 1, proc.stderr[-2000:]
    assert "Traceback" not in proc.stderr
    return lines[0]


def test_a_check_whose_reference_is_neither_in_the_run_nor_on_disk_names_what_to_run_first(tmp_path):
    """Refused before any job; then, with only part of the reference's results on disk, the
    line names the first file missing."""
    work = make_workdir(tmp_path, {"check": check()})
    (work / "config" / "campaigns" / "ref.yaml").write_text(yaml.safe_dump(FOLDER["ref"]))
    line = _one_line(snakemake(work, "-n"))
    assert line.startswith("calflow: error: config/campaigns/check.yaml: key 'interim_check.reference': ")
    assert "expected the results of 'ref' on disk or 'ref' among this run's campaigns" in line
    assert "results/ref/export/manifest.json is missing" in line
    assert """run it first (snakemake --cores 2 --config 'campaigns=["ref"]')""" in line
    assert not (work / "results").exists()
    (work / "results" / "ref" / "export").mkdir(parents=True)
    (work / "results" / "ref" / "export" / "manifest.json").write_text("{}")
    assert "results/ref/runs/export_II.nc is missing" in _one_line(snakemake(work, "-n"))
    assert sorted(p.name for p in (work / "results").rglob("*") if p.is_file()) == ["manifest.json"]


def test_a_campaign_of_another_robot_than_the_stages_campaigns_on_disk_is_refused(tmp_path):
    """The stage's robot is that of its campaigns on disk, whichever run made them; so is a
    start already taken."""
    work = make_workdir(tmp_path, {"nano": FOLDER["nano"]})
    (work / "config" / "campaigns" / "old.yaml").write_text(yaml.safe_dump(calibration()))
    (work / "results" / "old").mkdir(parents=True)
    (work / "results" / "old" / "summary.json").write_text(json.dumps({"robot": "xytheta", "models": {}}))
    line = _one_line(snakemake(work, "-n"))
    assert line == (
        "calflow: error: config/campaigns/nano.yaml: key 'robot': expected 'xytheta' as the other "
        f"campaigns of stage '{STAGE}' (old, on disk), got 'stage1d'"
    )
    (work / "config" / "campaigns" / "nano.yaml").write_text(
        yaml.safe_dump(calibration(start="2026-01-05T10:00:00+02:00"))
    )
    line = _one_line(snakemake(work, "-n"))
    assert "nano.yaml: key 'start': expected a start different from every other campaign" in line
    assert line.endswith("as old, on disk")
