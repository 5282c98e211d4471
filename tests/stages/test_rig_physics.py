"""Every effect of the simulated XYΘ rig is present by default and gone when switched off."""

import numpy as np
import pytest

from calflow.xytheta.models.kinematics import forward
from calflow.xytheta.stage.physics import EFFECTS, XYThetaTruth, options_off, truth_from_options
from calflow.xytheta.stage.rig import simulated_xytheta

RNG = np.random.default_rng(5)
X, Y, T = RNG.uniform(0, 4000, 300), RNG.uniform(800, 2800, 300), RNG.uniform(0, 5, 300)
GEOMETRIC = (
    "lead_screw",
    "backlash",
    "coupling",
    "scale",
    "straightness",
    "yaw",
    "expansion",
    "theta_scale",
    "theta_periodic",
    "theta_backlash",
    "axis_runout",
)


def _tool(truth, temperature=None):
    x, y, _ = truth.tool_point(X, Y, T, temperature_degC=temperature)
    return np.array([x, y])


@pytest.mark.parametrize("effect", GEOMETRIC)
def test_each_stage_effect_is_present_and_switches_off(effect):
    alone = truth_from_options({k: v for k, v in options_off().items() if k not in EFFECTS[effect]})
    nothing = truth_from_options(options_off())
    ideal = np.array(forward(X, Y, T, nothing.parameters))
    temperature = nothing.room_temperature_degC + 0.3  # the expansion needs a temperature change
    assert np.allclose(_tool(nothing, temperature), ideal, atol=1e-9)
    shift = np.hypot(*(_tool(alone, temperature) - ideal))
    assert shift.max() > 0.01, effect  # present: at least 10 nm somewhere in the workspace
    assert np.allclose(_tool(alone.without(*EFFECTS[effect]), temperature), ideal, atol=1e-9)


def test_sensor_effects_are_present_and_switch_off():
    t = XYThetaTruth()
    x_m, y_m = 1234.5, 2345.6
    assert np.hypot(*t.decode_error(x_m, y_m)) > 0.001
    assert t.decode_error(x_m, y_m) == t.decode_error(x_m, y_m)  # the same pose, the same error
    assert t.without("decode_error_um").decode_error(x_m, y_m) == (0.0, 0.0)
    warm = t.room_temperature_degC + 1.0
    x_P, y_P, theta_a = t.tool_point(2000.0, 1500.0, 1.0)  # a pose the camera sees
    a = t.vision(x_P, y_P, theta_a, warm, (0.0, 0.0))
    b = t.without("drift_um_per_degC").vision(x_P, y_P, theta_a, warm, (0.0, 0.0))
    assert np.isfinite(a).all()
    assert a[1] - b[1] == pytest.approx(1.357, abs=0.02)  # Table 3.3's y drift per degC
    assert t.gross_error(0.0, 0.2) == (t.pattern_period_um, 0.0) and t.gross_error(0.5, 0.2) == (0.0, 0.0)
    assert t.without("gross_error_rate").gross_error(0.0, 0.2) == (0.0, 0.0)


def test_gross_errors_come_at_their_rate():
    rig = simulated_xytheta(
        seed=3,
        gross_error_rate=0.02,
        sensor_noise_um=0.0,
        stage_repeatability_um=0.0,
        decode_error_um=0.0,
        room_swing_degC=0.0,
    )
    rig.move({"x": 2000.0, "y": 1500.0, "theta": 2.0})
    readings = np.array([[r["meas_x"], r["meas_y"]] for r in (rig.read() for _ in range(3000))])
    jumps = np.hypot(*(readings - np.median(readings, axis=0)).T)
    rate = np.mean(jumps > 1.0)
    assert 0.01 < rate < 0.03
    assert np.allclose(jumps[jumps > 1.0], rig.truth_model.pattern_period_um, atol=0.02)


def test_lost_motion_depends_on_the_approach_distance():
    """After a reversal, the first backlash of travel leaves the carriage behind: a short
    return move ends between the two long-approach positions."""

    def reading(moves, **physics):
        rig = simulated_xytheta(
            seed=0,
            sensor_noise_um=0.0,
            stage_repeatability_um=0.0,
            sensor_resolution_um=1e-9,
            decode_error_um=0.0,
            gross_error_rate=0.0,
            room_swing_degC=0.0,
            lead_fwd_um=[0, 0],
            lead_bwd_um=[0, 0],
            **physics,
        )
        for x in moves:
            rig.move({"x": x, "y": 1000.0, "theta": 0.0})
        return rig.read()["meas_x"]

    long_fwd, long_bwd = reading([1000.0, 2000.0]), reading([3000.0, 2000.0])
    short_bwd = reading([1000.0, 2000.5, 2000.0])  # forward, then 0.5 µm back: half the play taken up
    assert abs(long_fwd - long_bwd) == pytest.approx(2.0, abs=0.2)  # Table 4.1 backlash
    assert min(long_fwd, long_bwd) + 0.2 < short_bwd < max(long_fwd, long_bwd) - 0.2
    ideal = reading([1000.0, 2000.5, 2000.0], lost_motion=False)
    assert ideal == pytest.approx(long_bwd, abs=1e-6)  # without lost motion any reversal takes the full lash


def test_one_key_switches_off_every_unmodelled_effect():
    t = XYThetaTruth(unmodelled=False)
    for name in EFFECTS.unmodelled_fields:
        value = getattr(t, name)
        assert (not value) if isinstance(value, bool) else np.all(np.asarray(value) == 0), name
    assert t.lead_fwd_um == XYThetaTruth().lead_fwd_um  # modelled effects stay
    rig = simulated_xytheta(unmodelled=False)
    assert rig.truth()["unmodelled"] is False and rig.truth()["yaw_urad"] == (0.0, 0.0)


def test_the_theta_stage_does_not_reach_its_angle_exactly():
    t = XYThetaTruth()
    err_fwd, err_bwd = t.theta_error(3.0, 1), t.theta_error(3.0, -1)
    assert err_fwd - err_bwd == pytest.approx(1e-3)  # one m° between the two approach sides
    assert abs(err_fwd) > 1e-3  # scale and periodic errors
    period = t.theta_period_deg
    for step in (0.05, 0.1, 0.2, 0.25, 0.5, 1.0):  # not a multiple of any plan's step
        assert abs(period / step - round(period / step)) > 0.05
