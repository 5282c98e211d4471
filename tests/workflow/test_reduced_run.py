"""The same analysis through other paths: a cluster executor, a replay of the recordings and
the GCS controller emulator all give the session's reduced local run's results
(``reduced_run`` in conftest, made once per session and only read here)."""

import json
import shutil

import numpy as np
import pytest
from conftest import REDUCED_XYTHETA, ROOT, SOURCE_DATE_EPOCH, make_workdir, snakemake


def test_cluster_generic_run_gives_the_local_summary(reduced_run, tmp_path):
    """Each job its own process through a submit script: the same summary.json, byte for byte."""
    cluster = make_workdir(tmp_path, {"c": REDUCED_XYTHETA})
    shutil.copytree(ROOT / "workflow" / "profiles", cluster / "workflow" / "profiles", dirs_exist_ok=True)
    b = snakemake(
        cluster,
        "results/c/summary.json",
        "--workflow-profile",
        "workflow/profiles/local-cluster",
        env_extra=SOURCE_DATE_EPOCH,
    )
    assert b.returncode == 0, b.stderr[-3000:]
    assert "cluster-generic" in b.stdout + b.stderr or (cluster / ".snakemake/local-cluster").exists()
    assert (reduced_run / "results/c/summary.json").read_bytes() == (
        cluster / "results/c/summary.json"
    ).read_bytes()


def test_replay_campaign_reproduces_the_recorded_analysis(reduced_run, tmp_path):
    """A campaign replaying another's recordings gets the same models and metrics (run in a
    project of its own, so the session's reduced run stays as it was made)."""
    recorded = reduced_run / "results/c/runs"
    campaign = json.loads(json.dumps(REDUCED_XYTHETA))
    campaign["rig"] = {"factory": "replay", "options": {"recordings": str(recorded)}}
    work = make_workdir(tmp_path, {"again": campaign})
    proc = snakemake(work)  # all of it: its report and certificate too
    assert proc.returncode == 0, proc.stderr[-3000:]
    a = json.loads((reduced_run / "results/c/summary.json").read_text())
    b = json.loads((work / "results/again/summary.json").read_text())
    assert list(a["models"]) == ["I", "II"]
    # the design's bound needs the rig's noise model, which a replay rig does not declare:
    # the replayed summary gives none rather than inventing one; everything else is equal
    bound = ("crlb_sigma", "rig_time_h", "rig_time_h_achieved")
    for name in ("I", "II"):
        assert a["models"][name]["identification"]["crlb_sigma"]
        assert all(b["models"][name]["identification"].get(k) is None for k in bound)
        for s in (a, b):
            for k in bound:
                s["models"][name]["identification"].pop(k, None)
    assert a["models"] == b["models"]
    assert a["truth"] == b["truth"]


def test_campaign_through_the_emulator_matches_the_simulated_rig(reduced_run, tmp_path):
    """The session's reduced XYΘ campaign on the simulated rig, and the same campaign through
    the GCS emulator of that rig."""
    from calflow.xytheta.stage.emulate import emulated_rig_options

    sim = json.loads(json.dumps(REDUCED_XYTHETA))
    emu, options = emulated_rig_options(sim, time_scale=2000.0, timeout=2.0)
    try:
        via_gcs = json.loads(json.dumps(sim))
        via_gcs["rig"] = {"factory": "gcs", "options": options}
        work = make_workdir(tmp_path, {"viagcs": via_gcs})
        proc = snakemake(work, "results/viagcs/summary.json")
        assert proc.returncode == 0, proc.stderr[-3000:]
    finally:
        emu.stop()
    a = json.loads((reduced_run / "results/c/summary.json").read_text())["models"]
    b = json.loads((work / "results/viagcs/summary.json").read_text())["models"]
    for name in ("I", "II"):
        assert b[name]["accuracy_um"] == pytest.approx(a[name]["accuracy_um"], rel=0.3, abs=2.0), name
    for key in ("x_R_um", "y_R_um", "alpha_deg", "beta_deg"):
        pa, pb = a["II"]["parameters"][key], b["II"]["parameters"][key]
        assert abs(pa["value"] - pb["value"]) < 4 * np.hypot(pa["std"], pb["std"]), key


def test_error_budget_replay_reproduces_the_campaign(reduced_run):
    """The budget's replay with nothing switched off is the campaign's own calibration: the
    same held-out AP at every target, to the bit (same seeds, streams and command functions)."""
    import xarray as xr

    from calflow.xytheta.stage.error_budget import replay

    r = replay(reduced_run / "config/campaigns/c.yaml", "none")
    for name, ap in r["ap_um"].items():
        with xr.open_dataset(reduced_run / f"results/c/metrics/validation_heldout_{name}.nc") as m:
            assert np.array_equal(np.asarray(ap), m["ap"].values), name


def test_bound_before_beside_the_achieved_sigma_in_summary_and_report(reduced_run):
    """Issue 15: the Cramér–Rao σ and rig time the plan promised, beside what identification achieved."""
    s = json.loads((reduced_run / "results/c/summary.json").read_text())
    d = s["identification_design"]
    assert d["plan"] == "random" and d["poses"] == REDUCED_XYTHETA["identification"]["poses"] + 1  # and home
    assert d["rig_time_h"] == pytest.approx(d["rig_time_h_achieved"], rel=1e-9)  # the time model is the rig's
    for name, free in (("I", {"x_R_um", "y_R_um"}), ("II", {"x_R_um", "y_R_um", "alpha_deg", "beta_deg"})):
        idf, params = s["models"][name]["identification"], s["models"][name]["parameters"]
        assert set(idf["crlb_sigma"]) == free
        for key, bound in idf["crlb_sigma"].items():  # no unbiased estimate beats its bound
            assert params[key]["std"] >= 0.8 * bound
    html = (reduced_run / "reports/c/report.html").read_text()
    assert 'id="crlb"' in html
