"""End to end: the default campaigns through Snakemake, rerun semantics, replay, config errors.

The read-only tests share the session's one run of the default configuration
(``thesis_run`` in conftest); replay replays the session's reduced XYΘ run.
"""

import json

import pytest
from conftest import make_workdir, snakemake

CAMPAIGN = "xytheta-thesis"


def test_plugin_rig_campaign_runs_end_to_end(tmp_path):
    """A rig defined in the tests, named by rig.factory, runs through the whole workflow."""
    from conftest import SMALL_XYTHETA

    campaign = json.loads(json.dumps(SMALL_XYTHETA))
    campaign["rig"] = {
        "factory": "toyrigs:open_toy",
        "options": {"x_R": 5000.0, "y_R": 3000.0, "alpha": 178.0, "beta": 0.2},
    }
    campaign["identification"]["initial"] = {"x_R": 5500.0, "y_R": 2500.0}
    campaign["models"] = {k: v for k, v in campaign["models"].items() if k in ("I", "II")}
    campaign["xy_tests"] = {"compensation": []}
    work = make_workdir(tmp_path, {"toy": campaign}, rig_plugins=["toyrigs"])  # plugins are code: allowed
    proc = snakemake(work, "results/toy/summary.json")  # the reports are tested on the default run
    assert proc.returncode == 0, proc.stderr[-3000:]
    summary = json.loads((work / "results/toy/summary.json").read_text())
    p = summary["models"]["II"]["parameters"]
    assert p["x_R_um"]["value"] == pytest.approx(5000.0, rel=1e-6)  # noise-free: exact recovery
    assert p["alpha_deg"]["value"] == pytest.approx(178.0, rel=1e-6)
    assert summary["models"]["II"]["accuracy_um"] < 1e-3
    assert "truth" not in summary


@pytest.mark.parametrize(
    "edit,key",
    [
        (lambda c: c["validation"].update(cyclez=3), "validation.cyclez"),
        (lambda c: c["identification"].update(poses="many"), "identification.poses"),
    ],
)
def test_bad_campaign_stops_before_any_job(tmp_path, edit, key):
    from conftest import SMALL_XYTHETA

    campaign = json.loads(json.dumps(SMALL_XYTHETA))
    edit(campaign)
    work = make_workdir(tmp_path, {"broken": campaign})
    proc = snakemake(work)
    assert proc.returncode != 0
    lines = [line for line in proc.stderr.splitlines() if "calflow: error" in line]
    assert len(lines) == 1
    assert "config/campaigns/broken.yaml" in lines[0] and key in lines[0]
    assert not (work / "results").exists()
