"""The laser tracker's declared terms for the hexapod's certificate."""

from __future__ import annotations

import pytest

from calflow_hexapod.certificate import tracker_terms
from calflow_hexapod.stage import tracker
from calflow_hexapod.stage.physics import HexapodTruth


def test_tracker_terms_are_the_specifications_mpe_over_four():
    truth = HexapodTruth()
    terms = {t.name: t for t in tracker_terms(2.0)}
    assert terms["tracker ADM, random"].u == pytest.approx((10 + 0.3 * 2.0) / 4)
    assert terms["tracker transverse, random"].u == pytest.approx((15 + 6 * 2.0) / 4)
    systematic = terms["tracker angle encoders, systematic (transverse MPE/4)"]
    assert systematic.scope == "target" and systematic.u == pytest.approx((15 + 6 * 2.0) / 4)
    # the same MPE/4 the simulated tracker draws its random errors from, at its station distance
    import numpy as np

    _, s_t, _ = tracker.sigmas(truth, np.zeros((1, 3)))
    assert tracker_terms(truth.tracker_distance_m)[1].u == pytest.approx(s_t[0], rel=0.02)


def test_heldout_runs_give_each_models_position_figures(monkeypatch):
    import numpy as np
    import xarray as xr

    from calflow.certificate.annotate import annotate
    from calflow_hexapod.certificate import measurements

    rng = np.random.default_rng(0)
    pose = np.repeat(np.arange(0, 4), 3)
    cols = {f"target_{a}": ("sample", np.repeat(rng.uniform(-5000, 5000, 4), 3)) for a in "xyzuvw"}
    run = xr.Dataset(
        {
            **cols,
            **{f"meas_{a}": ("sample", cols[f"target_{a}"][1] + rng.normal(0, 3, 12)) for a in "xyzuvw"},
        },
    )
    run["pose"] = ("sample", pose)
    run.attrs.update(model="geometric", plan="validation_heldout")
    monkeypatch.setattr(
        "calflow.summary_routing.route", lambda files, sections, family="": {"heldout_runs": [("r.nc", run)]}
    )
    (m,) = measurements(
        {"name": "h", "robot": "hexapod", "rig": {"options": {"tracker_distance_m": 2.0}}}, []
    )
    assert m.path == ("models", "geometric", "heldout") and len(m.data["attained"]) == 3  # pose 0 is home
    summary = {
        "robot": "hexapod",
        "models": {"geometric": {"heldout": {"accuracy_um": 1.0, "repeatability_um": 2.0}}},
    }
    monkeypatch.setattr("calflow.certificate.annotate.resolve", lambda target: lambda c, f: [m])
    out = annotate(
        summary,
        {"name": "h", "robot": "hexapod"},
        [],
        {"specification": {"accuracy_um": 50}, "decision_rule": "guarded"},
    )
    held = out["models"]["geometric"]["heldout"]
    assert (
        held["uncertainty"]["accuracy_um"]["U"] > 0 and held["conformity"]["accuracy_um"]["rule"] == "guarded"
    )
    assert "mismatch" in held["uncertainty"]["accuracy_um"]  # 1.0 is not what these readings give
