"""The noise model of a hexapod reading that the designed plan weighs poses by (its own
module, free of the identification's imports: the campaign check reads it at load)."""

from __future__ import annotations

import numpy as np


def noise_model(campaign: dict) -> dict | None:
    """σ of a reading: ``position_um`` and ``angle_deg`` per axis of the instrument, ``leg_um`` of
    the legs. ``identification.design.noise`` when given, else the simulated rig's tracker
    (MPE/4 at the station's distance, :mod:`calflow_hexapod.stage.tracker`) and leg repeatability,
    also when the simulated hexapod is served by the C-887 emulator (``rig: gcs`` with the
    tracker sensor); None for another rig that declares none."""
    given = (campaign["identification"].get("design") or {}).get("noise") or {}
    if {"position_um", "angle_deg", "leg_um"} <= set(given):
        return {k: float(given[k]) for k in ("position_um", "angle_deg", "leg_um")}
    from calflow_hexapod.stage.run_options import simulated_physics

    physics = simulated_physics(campaign)
    if physics is None:
        return None
    from calflow_hexapod.stage import tracker
    from calflow_hexapod.stage.physics import truth_from_options

    t = truth_from_options(physics)
    p = tracker.probe_pose(t, np.zeros((1, 6)))[0]
    s_r, s_t, s_a = tracker.sigmas(t, p)
    return {
        "position_um": float(np.sqrt((s_r[0] ** 2 + 2 * s_t[0] ** 2) / 3)),
        "angle_deg": float(s_a),
        "leg_um": float(t.leg_repeatability_um),
    }
