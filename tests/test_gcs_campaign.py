"""A campaign run with `rig: gcs` against the controller emulator gives the simulated rig's results."""

import json

import numpy as np
import pytest

from conftest import SMALL_XYTHETA, make_workdir, snakemake


def test_campaign_through_the_emulator_matches_the_simulated_rig(tmp_path):
    from calflow.xytheta.emulate import emulated_rig_options

    sim = json.loads(json.dumps(SMALL_XYTHETA))
    sim["models"] = {k: v for k, v in sim["models"].items() if k in ("I", "II")}
    sim["xy_tests"] = {"compensation": []}
    sim["identification"]["poses"] = 120
    emu, options = emulated_rig_options(sim, time_scale=2000.0, timeout=2.0)
    try:
        via_gcs = json.loads(json.dumps(sim))
        via_gcs["rig"] = {"factory": "gcs", "options": options}
        work = make_workdir(tmp_path, {"sim": sim, "viagcs": via_gcs})
        proc = snakemake(work, "results/sim/summary.json", "results/viagcs/summary.json")
        assert proc.returncode == 0, proc.stderr[-3000:]
    finally:
        emu.stop()
    a = json.loads((work / "results/sim/summary.json").read_text())["models"]
    b = json.loads((work / "results/viagcs/summary.json").read_text())["models"]
    for name in ("I", "II"):
        assert b[name]["accuracy_um"] == pytest.approx(a[name]["accuracy_um"], rel=0.3, abs=2.0), name
    for key in ("x_R_um", "y_R_um", "alpha_deg", "beta_deg"):
        pa, pb = a["II"]["parameters"][key], b["II"]["parameters"][key]
        assert abs(pa["value"] - pb["value"]) < 4 * np.hypot(pa["std"], pb["std"]), key
