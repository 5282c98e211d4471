"""Rig options that silence the simulated hexapod's random errors: the legs' repeatability and
the tracker's noise terms (for the tests that need an exact chain)."""

NOISE_OFF = {
    "leg_repeatability_um": 0.0,
    "tracker_adm_um": 0.0,
    "tracker_adm_um_per_m": 0.0,
    "tracker_transverse_um": 0.0,
    "tracker_transverse_um_per_m": 0.0,
    "tracker_angle_mdeg": 0.0,
    "tracker_resolution_um": 0.0,
}
