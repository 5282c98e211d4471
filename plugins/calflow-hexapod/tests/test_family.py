"""The hexapod as a registered calflow family: found through the entry point, its campaign
validated by its own schema, its ISO 9283 metrics per target for position and orientation."""

from pathlib import Path

import numpy as np
import xarray as xr

from calflow.configuration.campaign import load as load_campaign
from calflow.family import family_of, joints
from calflow_hexapod.steps import pose_metrics
from calflow_hexapod.workflow import WORKFLOW

ROOT = Path(__file__).resolve().parents[3]
DEMO = ROOT / "config" / "campaigns" / "hexapod-demo.yaml"


def test_the_family_is_found_through_its_entry_point():
    fam = family_of("hexapod")
    assert fam.name == "hexapod" and joints("hexapod") == ("x", "y", "z", "u", "v", "w")
    assert all(Path(p).is_file() for p in fam.rules_files())
    assert fam.hooks() is WORKFLOW


def test_the_demo_campaign_validates_and_lists_its_results():
    c = load_campaign(DEMO)
    files = WORKFLOW.results_of(c)
    for model in c["models"]:
        assert f"results/hexapod-demo/metrics/validation_heldout_{model}.nc" in files
        assert f"results/hexapod-demo/metrics/iso9283_{model}.nc" in files
    without = {k: v for k, v in c.items() if k != "iso9283"}  # a campaign is immutable: a variant
    assert not any("iso9283" in f for f in WORKFLOW.results_of(without))


def _run(target, attained) -> xr.Dataset:
    """A validation run: home (pose 0) then the attained readings of one target (pose 1)."""
    rows = np.vstack([np.zeros(6), attained])
    pose = np.r_[0, np.ones(len(attained), int)]
    data = {f"meas_{a}": ("sample", rows[:, i]) for i, a in enumerate("xyzuvw")}
    data |= {
        f"target_{a}": ("sample", np.r_[np.nan, np.full(len(attained), target[i])])
        for i, a in enumerate("xyzuvw")
    }
    return xr.Dataset({**data, "pose": ("sample", pose)})


def test_pose_metrics_follow_iso9283_for_position_and_orientation():
    rng = np.random.default_rng(3)
    target = np.array([100.0, -50.0, 20.0, 0.1, -0.2, 0.3])
    attained = (
        target
        + np.array([3.0, 4.0, 0.0, 0.01, -0.02, 0.0])
        + rng.normal(0, [1, 1, 1, 1e-3, 1e-3, 1e-3], (30, 6))
    )
    m = pose_metrics(_run(target, attained))
    mean = attained.mean(axis=0)
    assert np.isclose(m["ap"][0], np.linalg.norm(mean[:3] - target[:3]))  # AP_p: barycentre to command
    l = np.linalg.norm(attained[:, :3] - mean[:3], axis=1)
    assert np.isclose(m["rp"][0], l.mean() + 3 * l.std(ddof=1))  # RP_l = l̄ + 3 S_l
    assert np.allclose(m["ap_orient"][0], np.abs(mean[3:] - target[3:]))
    assert np.allclose(m["rp_orient"][0], 3 * attained[:, 3:].std(axis=0, ddof=1))
    assert m["n"][0] == 30


def test_the_summary_says_in_words_what_a_model_cannot_do():
    from calflow_hexapod.report.summary import _statement

    held = {"n_targets": 10, "accuracy_um": 50.0, "repeatability_um": 20.0}
    words = _statement("nominal", {"heldout": held}, best=10.0)
    assert "does not model every error" in words and "2.5 × RP" in words and "10.00 µm" in words
    fits = _statement("geometric", {"heldout": {**held, "accuracy_um": 21.0}}, best=21.0)
    assert "only what the rig cannot repeat" in fits
    assert "not validated" in _statement("scale", {}, best=None)


def test_the_bound_before_beside_the_result_after():
    from calflow_hexapod.report.summary import _bound

    ds = xr.Dataset({"a": ((), 0.0, {"std": 2.0}), "b": ((), 0.0, {"std": 3.0})})
    b = _bound(ds, {"a": 1.0, "b": 6.0, "absent": 1.0})
    assert b["parameters"] == 2 and b["worst"] == "a"
    assert b["sigma_ratio_max"] == 2.0 and b["sigma_ratio_median"] == 1.25
    assert _bound(ds, None) is None


def test_the_gcs_variant_is_the_demo_through_a_local_controller():
    """hexapod-demo-gcs: the same campaign with rig: gcs on the loopback address, so its runs
    compare with the demo's (plugins/calflow-hexapod/benchmarks/bench_gcs_campaign.py)."""
    demo, gcs = load_campaign(DEMO), load_campaign(DEMO.with_name("hexapod-demo-gcs.yaml"))
    assert gcs["rig"]["factory"] == "gcs" and gcs["rig"]["options"]["host"] == "127.0.0.1"
    assert gcs["rig"]["options"]["sensor"]["factory"] == "simulated_tracker"
    for key in ("seed", "identification", "models", "iso9283"):
        assert gcs[key] == demo[key], key

    def heldout(c):
        return {k: v for k, v in c["validation"]["heldout"].items() if k != "error_budget"}

    assert heldout(gcs) == heldout(demo)
    assert WORKFLOW.budget_files(gcs) == []
