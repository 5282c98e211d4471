"""The nano rigs' closed-loop step response, the recorded step-response plan and the ISO 9283
stabilisation time (7.5) and overshoot (7.6) it gives the summary (issue 16, item 4)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from calflow.acquisition.recorded_moves import acquire_recorded_moves
from calflow.data.runs import RunMetadata
from calflow.errors import OptionError, RigError
from calflow.nano.plans import sequences as plans
from calflow.nano.report.stabilisation import stabilisation_entries
from calflow.nano.stage.options import without
from calflow.nano.stage.piezo import closed_loop_step
from calflow.nano.stage.rig import nano1d, nano2d

QUIET = dict(
    interferometer_noise_nm=0.0,
    repeatability_nm=0.0,
    wavelength_stability_ppm=0.0,
    settle_fraction=0.0,
    creep_pct_per_decade=0.0,
    move_settling_ppm_per_decade=0.0,  # the mechanics' log-time relaxation after the move
    turbulence_mk=0.0,  # the beam's air fluctuates within the 50 ms record
    interferometer_resolution_nm=1e-6,
    profile="constant",
)
META = RunMetadata(campaign="t", robot="stage1d", source="simulated", plan="step_response", config_sha256="0")


def _record(rig, step=10.0, seconds=0.05, rate=1000.0):
    rig.move({"x": 100.0})
    before = rig.read()["meas_x"]
    chunk = next(rig.record_move({"x": 100.0 + step}, seconds, rate))
    return chunk["time"] - chunk["time"][0], chunk["meas_x"] - before


@settings(max_examples=30, deadline=None)
@given(st.floats(20.0, 500.0), st.floats(0.2, 0.9))
def test_closed_loop_step_has_the_second_order_overshoot_and_envelope(fn, zeta):
    w = 2 * math.pi * fn
    wd = w * math.sqrt(1 - zeta * zeta)
    t = np.linspace(0.0, 12.0 / (zeta * w), 20001)
    y = closed_loop_step(t, fn, zeta)
    assert y[0] == 0.0 and closed_loop_step(-1e-3, fn, zeta) == 0.0
    # peak overshoot exp(-pi zeta / sqrt(1 - zeta^2)) at t = pi / w_d
    assert y.max() - 1 == pytest.approx(
        math.exp(-math.pi * zeta / math.sqrt(1 - zeta * zeta)), rel=1e-4, abs=1e-9
    )
    assert t[np.argmax(y)] == pytest.approx(math.pi / wd, abs=2 * (t[1] - t[0]))
    # never outside the envelope exp(-zeta w t) / sqrt(1 - zeta^2)
    assert np.all(np.abs(y - 1) <= np.exp(-zeta * w * t) / math.sqrt(1 - zeta * zeta) + 1e-12)
    assert closed_loop_step(float(t[-1]), fn, zeta) == pytest.approx(
        float(y[-1]), abs=1e-12
    )  # scalar path agrees


def test_rig_records_the_configured_step_response_from_the_start_of_the_move():
    fn, zeta, step = 100.0, 0.7, 10.0
    t, x = _record(nano1d(**QUIET, step_natural_hz=fn, step_damping=zeta), step, seconds=0.05, rate=20000.0)
    # the static errors follow the command at once (tens of nm over the step), the stage the loop
    g = x[-1] - step
    assert t[0] == 0.0 and x[0] - g == pytest.approx(0.0, abs=0.03)  # the record starts with the move
    overshoot = (x.max() - x[-1]) / step
    assert overshoot == pytest.approx(math.exp(-math.pi * zeta / math.sqrt(1 - zeta * zeta)), rel=2e-3)
    np.testing.assert_allclose(x - g, step * closed_loop_step(t, fn, zeta), atol=1e-6)


def test_step_response_switches_off_and_leaves_dwell_readings_unchanged():
    t, x = _record(nano1d(**without(QUIET | {"step_natural_hz": 100.0}, "step_response")))
    assert np.ptp(x) < 1e-6 and abs(x[0] - 10.0) < 0.05  # an ideal step: there from the first point
    with pytest.raises(OptionError, match="step_damping"):
        nano1d(step_damping=1.5)

    def readings(**o):  # the existing plans: move, dwell, read (4 s rise, ms transient)
        rig = nano1d(seed=3, **o)
        out = []
        for x in (0.0, 80.0, 160.0, 80.0):
            rig.move({"x": x})
            rig.wait(19.0)
            out.append(rig.read())
        return out

    assert readings() == readings(step_natural_hz=0.0)  # bit for bit


def test_step_response_plan_shape():
    p = plans.step_response([1.0, 10.0], cycles=3, base_um=(20.0, 20.0), record_s=0.05, rate_hz=1000.0)
    assert len(p) == 2 * 2 * 3 and set(p.commands) == {"x", "y"}
    np.testing.assert_array_equal(p.commands["x"][:4], [21.0, 20.0, 30.0, 20.0])
    np.testing.assert_array_equal(p.commands["y"], 20.0)
    np.testing.assert_array_equal(p.direction[:4], [1, -1, 1, -1])
    np.testing.assert_array_equal(p.pose, np.tile(np.arange(4), 3))
    assert p.average_last_s == 0.01 and p.extra["record_rate_hz"][0] == 1000.0


def _run(rig, steps=(1.0, 10.0, 40.0), cycles=3, base=20.0):
    plan = plans.step_response(list(steps), cycles, (base,) * len(rig.joints), 0.05, 1000.0, 0.01)
    return acquire_recorded_moves(plan, rig, META)


def test_recorded_run_and_its_iso9283_entries():
    run = _run(nano1d(seed=1, profile="constant"))
    assert run.sizes["record"] == 50 and run["record_time"].attrs["units"] == "s"
    np.testing.assert_allclose(run["record_time"].values[:, 1], 1e-3)
    np.testing.assert_allclose(run["step_x"].values, np.tile([1, -1, 10, -10, 40, -40], 3))  # first step too
    stab, over = stabilisation_entries(run)
    assert (stab["clause"], stab["unit"], over["clause"], over["unit"]) == ("7.5", "s", "7.6", "nm")
    assert 0 < stab["value"] < 0.05 and stab["band_nm"] > 0
    # the worst overshoot is the largest step's: ~4.6 % of 40 um for zeta = 0.7
    zeta = 0.7
    assert over["value"] == pytest.approx(
        40e3 * math.exp(-math.pi * zeta / math.sqrt(1 - zeta * zeta)), rel=0.05
    )
    small = [e for e in stab["per_step"] if abs(e["step_um"]) == 1.0]
    big = [e for e in stab["per_step"] if abs(e["step_um"]) == 40.0]
    assert max(e["stabilisation_time_s"] for e in small) < min(e["stabilisation_time_s"] for e in big)


def test_stated_band_and_a_record_too_short_to_settle():
    run = _run(nano1d(seed=2, profile="constant"), steps=(10.0,))
    run.attrs["band_nm"] = 1000.0  # wider than the 10 um step's ~460 nm overshoot
    stab, over = stabilisation_entries(run)
    assert stab["band_nm"] == 1000.0 and over["value"] == 0.0
    slow = _run(nano1d(seed=2, profile="constant", step_natural_hz=5.0), steps=(10.0,))
    stab, over = stabilisation_entries(slow)
    assert stab["value"] is None and stab["reason"].startswith("not supported by this data")


def test_two_dof_run_and_a_rig_without_a_recorder():
    run = _run(nano2d(seed=1, profile="constant"), steps=(1.0, 10.0))
    assert "record_meas_y" in run and np.all(run["step_y"].values == 0.0)
    assert stabilisation_entries(run)[1]["value"] > 0

    class Plain:
        joints, sensors, thermometers = ("x",), ("meas_x",), ()

    with pytest.raises(RigError, match="record_move"):
        acquire_recorded_moves(plans.step_response([1.0]), Plain(), META)


def _synthetic_run(band_nm=None):
    """Two cycles of one step of 1 um out (pose 0) and back (pose 1), by hand: the record
    crosses the attained position between points 1 and 2 (at 1.5 ms), peaks 0.1 um beyond it
    at 3 ms and is inside a 20 nm band from 5 ms on."""
    import xarray as xr

    t = np.arange(10) * 1e-3
    out = np.array([0.0, 0.5, 1.5, 1.1, 1.05, 1.01, 1.0, 1.0, 1.0, 1.0])
    rec = np.stack([out, 1.0 - out, out, 1.0 - out])
    meas = np.array([1.0, 0.0, 1.0, 0.0])
    data = {
        "record_time": (("sample", "record"), np.tile(t, (4, 1))),
        "record_meas_x": (("sample", "record"), rec),
        "meas_x": ("sample", meas),
        "cmd_x": ("sample", meas),
        "step_x": ("sample", [1.0, -1.0, 1.0, -1.0]),
        "pose": ("sample", [0, 1, 0, 1]),
    }
    attrs = {"record_s": 0.01, "record_rate_hz": 1000.0, **({"band_nm": band_nm} if band_nm else {})}
    return xr.Dataset(data, attrs=attrs)


def test_summary_block_from_a_small_synthetic_run():
    from test_evaluation_nano import run_1d
    from test_nano_iso9283_summary import DEV, DIRS, POSITIONS

    from calflow.nano.report.iso9283 import iso9283_block

    step = _synthetic_run(band_nm=20.0)
    validation = run_1d(DEV, modes=[0, 0], positions=POSITIONS, dirs=DIRS)
    block = iso9283_block(validation, step)
    b = block["modes"]["no_calibration"]
    # first entry at the crossing (1.5 ms, between points 1 and 2); inside from 5 ms (|1.01 - 1| <= 0.02)
    assert b["stabilisation_time_s"]["value"] == pytest.approx(0.005 - 0.0015)
    assert b["overshoot"]["value"] == pytest.approx(500.0)  # 1.5 um - 1 um after the entry, in nm
    assert (b["stabilisation_time_s"]["clause"], b["overshoot"]["clause"]) == ("7.5", "7.6")
    assert [e["step_um"] for e in b["overshoot"]["per_step"]] == [1.0, -1.0]
    # without a stated band the band is RP, which needs two cycles of a pose
    with pytest.raises(ValueError, match="band_nm"):
        stabilisation_entries(_synthetic_run().assign(pose=("sample", [0, 1, 2, 3])))
    with pytest.raises(ValueError, match="band_nm"):  # identical attained positions: RP = 0, no band
        stabilisation_entries(_synthetic_run())
