"""The as-found step of a recalibration: refused before anything runs when it cannot run,
one line naming the file and the key; the summary's as_found / as_left blocks."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from calflow.configuration.campaign import load as load_campaign
from calflow.errors import ConfigError
from calflow.lifecycle.stages import check_needs

ROOT = Path(__file__).resolve().parents[2]
DEMO = ROOT / "config/campaigns"


def _folder(tmp_path, **changes):
    """The stage demo's January calibration, its April check and its July recalibration (with
    its as_found section) in a scratch folder; ``changes`` edit the July file."""
    for name in ("demo-sn0042-2026-01", "demo-sn0042-2026-04-check"):
        (tmp_path / f"{name}.yaml").write_text((DEMO / f"{name}.yaml").read_text())
    july = yaml.safe_load((DEMO / "demo-sn0042-2026-07.yaml").read_text())
    for k, v in changes.items():
        if v is None:
            july.pop(k, None)
        else:
            july[k] = v
    path = tmp_path / "demo-sn0042-2026-07.yaml"
    path.write_text(yaml.safe_dump(july))
    return path


def test_demo_recalibration_measures_as_found_through_january():
    c = load_campaign(DEMO / "demo-sn0042-2026-07.yaml")
    assert c["as_found"] == {"reference": "demo-sn0042-2026-01", "model": "III"}
    from calflow.xytheta.plans.workflow import WORKFLOW

    files = WORKFLOW.results_of(c)
    assert "results/demo-sn0042-2026-07/metrics/as_found.nc" in files
    # the open-loop runs do not read the as-found run (it goes first by its rule's priority)
    assert WORKFLOW.acquire_inputs(c, "characterisation_x") == {}
    assert not any("as_found" in f for f in WORKFLOW.acquire_inputs(c, "identification").values())
    first = load_campaign(DEMO / "demo-sn0042-2026-01.yaml")
    assert not any("as_found" in f for f in WORKFLOW.results_of(first))


@pytest.mark.parametrize(
    "section,key,match",
    [
        ({"reference": "demo-sn0042-2026-01", "model": "V"}, "as_found.model", r"no exported bundle"),
        ({"reference": "gone", "model": "III"}, "as_found.reference", r"no gone\.yaml"),
        (
            {"reference": "demo-sn0042-2026-04-check", "model": "III"},
            "as_found.reference",
            "an interim check",
        ),
        ({"reference": "demo-sn0042-2026-01"}, "as_found", "model"),
        ({"reference": "../demo-sn0042-2026-01", "model": "III"}, "as_found.reference", "expected"),
        ({"reference": "demo-sn0042-2026-01", "model": "../III"}, "as_found.model", "expected"),
    ],
)
def test_refuses_an_as_found_step_that_cannot_run(tmp_path, section, key, match):
    path = _folder(tmp_path, as_found=section)
    with pytest.raises(ConfigError, match=rf"demo-sn0042-2026-07\.yaml: key '{key}.*{match}"):
        load_campaign(path)


def test_refuses_a_reference_of_another_stage_or_a_later_one(tmp_path):
    path = _folder(tmp_path, stage="SN-0043")
    with pytest.raises(
        ConfigError, match=r"key 'as_found.reference': expected a calibration of stage 'SN-0043'"
    ):
        load_campaign(path)
    path = _folder(tmp_path, start="2025-12-01T08:00:00+00:00")
    with pytest.raises(
        ConfigError, match=r"key 'start': expected a start after that of its reference 'demo-sn0042-2026-01'"
    ):
        load_campaign(path)


def test_refuses_a_reference_neither_in_the_run_nor_on_disk(tmp_path):
    from calflow.xytheta.plans.workflow import WORKFLOW

    cs = {
        "b": {
            "name": "b",
            "robot": "xytheta",
            "stage": "S",
            "start": "2026-07-05T08:00:00Z",
            "as_found": {"reference": "a", "model": "III"},
        },
    }
    results = tmp_path / "results"
    with pytest.raises(
        ConfigError,
        match=r"b\.yaml: key 'as_found.reference': expected the results of 'a' on disk .* "
        r"results/a/export/manifest\.json is missing: run it first",
    ):
        check_needs(cs, tmp_path, WORKFLOW.needs, results)
    (results / "a" / "export").mkdir(parents=True)
    (results / "a" / "export" / "manifest.json").write_text("{}")
    check_needs(cs, tmp_path, WORKFLOW.needs, results)  # on disk: runs alone


def test_summary_blocks_as_left_for_every_model_as_found_for_the_model_in_use():
    """add() on a summary: as_left from the held-out protocol, as_found from the as-found
    metrics, and the top-level block for a model the campaign did not identify again."""
    import numpy as np
    import xarray as xr

    from calflow.xytheta.report.as_found import add

    campaign = {"start": "2026-07-05T08:00:00+00:00", "as_found": {"reference": "jan", "model": "III"}}
    run = xr.Dataset({"time": ("sample", np.array([0.0, 30.0, 60.0]))}, attrs={"model": "III"})
    metrics = xr.Dataset({"ap": ("target", [1.0, 5.9])}, attrs={"accuracy_um": 5.9, "repeatability_um": 0.9})
    afrun = xr.Dataset({"time": ("sample", np.array([5.0, 20.0]))})
    found = {"heldout_runs": [("r", run)], "as_found": [("m", metrics)], "as_found_runs": [("a", afrun)]}
    summary = {"models": {"III": {"accuracy_um": 2.4, "repeatability_um": 1.0, "protocol": "heldout"}}}
    add(summary, campaign, found)
    m = summary["models"]["III"]
    assert m["as_left"] == {"accuracy_um": 2.4, "repeatability_um": 1.0, "date": "2026-07-05T08:01:00+00:00"}
    assert m["as_found"] == {
        "accuracy_um": 5.9,
        "repeatability_um": 0.9,
        "date": "2026-07-05T08:00:05+00:00",
        "reference": "jan",
    }
    other = {"models": {"V": {"accuracy_um": 2.0, "repeatability_um": 0.5, "protocol": "heldout"}}}
    add(other, campaign, found)
    assert "as_found" not in other["models"]["V"] and other["as_found"]["model"] == "III"
    from calflow.lifecycle.decisions.as_found import carry_as_found

    models = {"V": {"accuracy_um": 2.0}}
    carry_as_found(models, other)
    assert models["III"]["as_found"]["reference"] == "jan" and "as_left" in models["V"]


def test_acquisition_refuses_a_missing_bundle(tmp_path):
    """Run outside the workflow without the reference's export: one line naming the folder."""
    from types import SimpleNamespace

    from calflow.errors import CalflowError
    from calflow.xytheta.plans.as_found import as_found, heldout_target_rows

    c = load_campaign(DEMO / "demo-sn0042-2026-07.yaml")
    with pytest.raises(
        CalflowError, match=r"nowhere/III: no exported bundle of model III of demo-sn0042-2026-01"
    ):
        as_found(c, SimpleNamespace(export=str(tmp_path / "nowhere/III")))
    with pytest.raises(CalflowError, match="--export DIR"):
        as_found(c, SimpleNamespace(export=None))
    rows = heldout_target_rows(c)
    assert rows.shape == (c["validation"]["heldout"]["targets"], 3)
