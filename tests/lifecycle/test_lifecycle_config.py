"""Stages in the configuration: refused before anything runs, one line naming file and key."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from calflow.configuration.campaign import load as load_campaign
from calflow.errors import ConfigError
from calflow.lifecycle.stages import stages_of

ROOT = Path(__file__).resolve().parents[2]


def campaign(name, robot="xytheta", stage="SN1", start="2026-01-05T08:00:00+00:00", **extra):
    return name, {"name": name, "robot": robot, "stage": stage, "start": start, **extra}


def test_groups_sorted_by_start():
    cs = dict(
        [
            campaign("b", start="2026-06-01T00:00:00+00:00"),
            campaign("a", start="2026-02-01T00:00:00Z"),
            campaign("x", stage=None),
        ]
    )
    assert stages_of(cs) == {"SN1": ["a", "b"]}


def test_refuses_duplicated_start():
    cs = dict([campaign("a"), campaign("b", start="2026-01-05T09:00:00+01:00")])  # the same instant
    with pytest.raises(ConfigError, match=r"b\.yaml: key 'start'"):
        stages_of(cs)


def test_refuses_mixed_robots():
    cs = dict([campaign("a"), campaign("b", robot="stage1d", start="2026-03-01T00:00:00Z")])
    with pytest.raises(ConfigError, match=r"b\.yaml: key 'robot': expected 'xytheta'"):
        stages_of(cs)


@pytest.mark.parametrize("ref,stage,match", [("other", "SN1", "of stage 'SN2'")])
def test_refuses_interim_reference(ref, stage, match):
    cs = dict(
        [
            campaign("a"),
            campaign("other", stage="SN2", start="2026-02-01T00:00:00Z"),
            campaign("check", stage=stage, start="2026-03-01T00:00:00Z", interim_check={"reference": ref}),
        ]
    )
    with pytest.raises(ConfigError, match=rf"check\.yaml: key 'interim_check.reference'.*{match}"):
        stages_of(cs)


@pytest.mark.parametrize("stage", ["../x", "a/b", "", ".hidden", "x" * 65])
def test_stage_id_cannot_escape_results(tmp_path, stage):
    data = yaml.safe_load((ROOT / "config/campaigns/xytheta-thesis.yaml").read_text())
    data["stage"] = stage
    path = tmp_path / "c.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match=r"c\.yaml: key 'stage'"):
        load_campaign(path)


def test_stage_and_tolerance_accepted(tmp_path):
    data = yaml.safe_load((ROOT / "config/campaigns/xytheta-thesis.yaml").read_text())
    data.update(stage="SN-0042", tolerance_um=5)
    path = tmp_path / "c.yaml"
    path.write_text(yaml.safe_dump(data))
    c = load_campaign(path)
    assert c["stage"] == "SN-0042" and c["tolerance_um"] == 5


def test_routine_calibration_leaves_out_the_study_and_the_reference_targets():
    """The stage demo's calibrations: observability.study false and validation.targets []
    drop those files from the campaign (and their runs from its rig time); the defaults keep them."""
    from calflow.xytheta.plans.workflow import WORKFLOW

    routine = load_campaign(ROOT / "config/campaigns/demo-sn0042-2026-01.yaml")
    files = WORKFLOW.results_of(routine)
    assert not any(f.endswith("observability.nc") or "validation_III" in f for f in files)
    assert any(f.endswith("validation_heldout_III.nc") for f in files)
    assert not any("/runs/validation_III" in f for f in WORKFLOW.all_runs(routine))
    full = load_campaign(ROOT / "config/campaigns/xytheta-thesis.yaml")
    assert full["observability"]["study"] is True and "targets" not in full["validation"]
    files = WORKFLOW.results_of(full)
    assert any(f.endswith("observability.nc") for f in files)
    assert any(f.endswith("metrics/validation_III.nc") for f in files)
