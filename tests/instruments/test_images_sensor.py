"""The simulated XYΘ rig's vision sensor through rendered frames and the decoder
(``rig.options.sensor: images``): readings in the pattern frame (Eq. 4.26), their
uncertainties and decode status in the run dataset, its options checked, the budget's
replays and the summary's comparison with the noise-model sensor.

Small and fast: a pattern for a 1.5 mm square, the camera looking at its middle, 352 × 272
frames at 5× (enough field of view for that pattern), a handful of frames per test.
"""

from __future__ import annotations

import numpy as np
import pytest

from calflow.acquisition.runner import acquire
from calflow.data.runs import RunMetadata
from calflow.data.validate import validate_dataset
from calflow.errors import OptionError
from calflow.plan import Plan
from calflow.xytheta.stage.physics import check_options
from calflow.xytheta.stage.rig import simulated_xytheta

CAMERA = {"width": 352, "height": 272, "magnification": 5.0}
SMALL = {
    "sensor": "images",
    "camera": CAMERA,
    "pattern_range_um": [1500.0, 1500.0],
    "camera_x_um": 750.0,
    "camera_y_um": 750.0,
}
META = RunMetadata(
    campaign="t", robot="xytheta", source="simulated", plan="identification", config_sha256="0" * 64
)


def _plan(x, y, theta) -> Plan:
    n = len(x)
    return Plan(
        name="identification",
        commands={"x": np.asarray(x, float), "y": np.asarray(y, float), "theta": np.asarray(theta, float)},
        targets={},
        pose=np.arange(n),
        cycle=np.zeros(n, int),
        direction=np.zeros(n, int),
        dwell_s=0.5,
    )


def test_readings_are_the_camera_point_in_the_pattern_frame():
    """Each reading decodes the frame rendered where the camera looks (Eq. 4.26): within
    nanometres of the noise-free camera point, Θ the stage's attained angle (sign included)."""
    rig = simulated_xytheta(seed=3, stream="s", **SMALL)
    t = rig.truth_model
    for cmd in (
        {"x": 0.0, "y": 0.0, "theta": 0.0},
        {"x": 60.0, "y": -40.0, "theta": 1.5},
        {"x": -50, "y": 30, "theta": -1},
    ):
        rig.move(cmd)
        r = rig.read()
        x_P, y_P, theta_a = rig._pose
        x_m, y_m = t.camera_point(x_P, y_P, theta_a, t.room_temperature(r["time"]))
        assert r["decode_status"] == 0
        assert abs(r["meas_x"] - x_m) < 0.01 and abs(r["meas_y"] - y_m) < 0.01
        assert abs(r["meas_theta"] - theta_a) < 1e-3
        assert 0 < r["u_meas_x"] < 0.01 and 0 < r["u_meas_theta"] < 1e-3


def test_same_stage_draws_as_the_noise_model_sensor():
    """Only the sensor differs: with the noise model's own terms off, the two sensors read
    the same stage (repeatability draws included) within the decoder's nanometres."""
    quiet = {
        "sensor_noise_um": 0.0,
        "decode_error_um": 0.0,
        "gross_error_rate": 0.0,
        "sensor_resolution_um": 1e-6,
    }
    plan = _plan([0, 40, 80, -30], [0, 20, -20, 50], [0, 0.5, 1.0, -1.0])
    model = {k: v for k, v in SMALL.items() if k not in ("sensor", "camera")}
    a = acquire(plan, simulated_xytheta(seed=5, stream="i", **SMALL, **quiet), META)
    b = acquire(plan, simulated_xytheta(seed=5, stream="i", **model, **quiet), META)
    assert np.max(np.abs(a["meas_x"].values - b["meas_x"].values)) < 0.01
    assert np.max(np.abs(a["meas_y"].values - b["meas_y"].values)) < 0.01
    assert np.array_equal(a["time"].values, b["time"].values)


def test_run_dataset_keeps_uncertainties_and_status_and_meets_the_contract():
    """u_meas_* and decode_status (CF flags) beside meas_*; a frame off the pattern is NaN with
    its reason's flag, never a wrong position."""
    plan = _plan([0, 30, 3000], [0, 10, 0], [0, 0.5, 0])  # the last looks 2 mm off the pattern
    ds = acquire(plan, simulated_xytheta(seed=1, stream="i", **SMALL), META)
    assert validate_dataset(ds) == []
    for v in ("u_meas_x", "u_meas_y", "u_meas_theta"):
        assert ds[v].attrs["units"] == ds[f"meas_{v[7:]}"].attrs["units"]
    status = ds["decode_status"]
    assert status.dtype == np.int8 and status.attrs["flag_meanings"].split()[0] == "ok"
    assert list(status.values[:2]) == [0, 0]
    assert status.values[2] != 0 and np.isnan(ds["meas_x"].values[2]) and np.isnan(ds["u_meas_x"].values[2])


def test_truth_names_the_sensor_so_the_oracle_reads_the_same_camera():
    rig = simulated_xytheta(seed=1, **SMALL)
    assert rig.truth()["sensor"] == {"sensor": "images", "camera": CAMERA}
    assert "sensor" not in simulated_xytheta(seed=1).truth()


@pytest.mark.parametrize(
    "options, key",
    [
        ({"sensor": "camera"}, "sensor"),
        ({"sensor": "images", "camera": {"pixels": 3}}, "camera"),
        ({"sensor": "images", "camera": {"width": -5}}, "camera"),
        ({"sensor": "images", "camera": [512, 384]}, "camera"),
        ({"camera": {"width": 512}}, "camera"),  # a camera for the noise-model sensor
        ({"sensor": "images", "pattern": "no/such/pattern.json"}, "pattern"),
    ],
)
def test_bad_sensor_options_name_the_option(options, key):
    with pytest.raises(OptionError) as err:
        check_options(**options)
    assert err.value.option.startswith(key)


def test_budget_of_an_images_rig_replays_the_sensor_and_the_noise_model():
    from calflow.xytheta.stage.error_budget import REPLAYS, active_effects, budget_replays, replay_options
    from calflow.xytheta.stage.physics import XYThetaTruth

    c = {"rig": {"options": {"sensor": "images"}}, "validation": {"heldout": {"error_budget": False}}}
    assert budget_replays(c) == ("noise_model",)
    c["validation"]["heldout"]["error_budget"] = True
    assert budget_replays(c) == (*REPLAYS, "sensor", "noise_model")
    effects = active_effects(XYThetaTruth(), images=True)
    assert "sensor" in effects and "decode" not in effects and "gross_errors" not in effects
    assert replay_options("noise_model")["sensor"] == "model"
    assert check_options(**{**SMALL, **replay_options("sensor")})["sensor"] == {"sensor": "model"}


def test_summary_puts_the_noise_model_replay_beside_the_images():
    from calflow.xytheta.report.summary import _add_error_budget

    summary = {"models": {"V": {"accuracy_um": 2.0}}, "validation": {"heldout": {}}}
    budget = {"replays": [{"replay": "noise_model", "active": True, "ap_um": {"V": [1.0, 3.0, 2.0]}}]}
    _add_error_budget(summary, {}, budget)
    assert summary["models"]["V"]["noise_model_sensor"]["accuracy_um"] == 3.0
    assert summary["models"]["V"]["noise_model_sensor"]["rms_ap_um"] == pytest.approx(np.sqrt(14 / 3))
    assert "noise-model sensor" in summary["validation"]["heldout"]["sensor_comparison"]


def test_validate_checks_the_decoder_variables():
    """calflow validate: u_meas_* beside their meas_*, decode_status as CF flags, NaN readings
    where a frame did not decode."""
    plan = _plan([0, 30, 3000], [0, 10, 0], [0, 0.5, 0])
    ds = acquire(plan, simulated_xytheta(seed=1, stream="i", **SMALL), META)
    bad = ds.copy(deep=True)
    bad["meas_x"].values[2] = 1.0  # a reading where the frame did not decode
    bad["u_meas_y"].values[0] = -1.0
    bad["decode_status"].values[1] = 42
    problems = validate_dataset(bad)
    assert any("'meas_x': expected NaN where decode_status" in p for p in problems)
    assert any("'u_meas_y': expected standard uncertainties >= 0" in p for p in problems)
    assert any("'decode_status': expected values in flag_values" in p for p in problems)
    assert any(
        "'u_meas_theta': expected beside 'meas_theta'" in p
        for p in validate_dataset(ds.drop_vars("meas_theta"))
    )
