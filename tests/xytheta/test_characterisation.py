"""Characterisation of the XY-stage errors (Sec. 4.4.1) against the simulated rig's truth."""

import numpy as np
import pytest

from calflow.acquisition.runner import acquire
from calflow.data.runs import RunMetadata
from calflow.data.validate import validate_dataset
from calflow.errors import DataError
from calflow.xytheta.plans import sweeps
from calflow.xytheta.stage.rig import simulated_xytheta
from calflow.xytheta.tables.characterisation import (
    characterise,
    characterise_axis,
    dominant_period,
    stage_positions,
)

STOP, CYCLES = 2000.0, 2


def meta(plan):
    return RunMetadata(campaign="t", robot="xytheta", source="simulated", plan=plan, config_sha256="0" * 64)


def sweep(axis, stop=STOP, cycles=CYCLES, step=5.0, seed=11, **physics):
    rig = simulated_xytheta(seed=seed, stream=f"char-{axis}", **physics)
    run = acquire(
        sweeps.characterisation(axis, stop_um=stop, step_um=step, cycles=cycles),
        rig,
        meta(f"characterisation_{axis}"),
    )
    return run, rig.truth_model


# the carriages' yaw along the travel is a rotation that grows with the stroke: over a sweep
# it cannot be told from α, β (the perpendicularity test below needs it off); gross decoding
# errors are the robust fit's business, not the tables'
PHYSICS = {"yaw_urad": [0.0, 0.0], "straightness_um": [0.0, 0.0], "gross_error_rate": 0.0}


@pytest.fixture(scope="module")
def runs():
    (rx, truth), (ry, _) = sweep("x", **PHYSICS), sweep("y", **PHYSICS)
    return rx, ry, truth, characterise(rx, ry, meta("characterisation_x"))


def true_tables(truth, axis, q, d):
    """Noise-free errors (target − measured, stage frame) from the truth's tool point at Θ = 0.

    Stage frame u = -(x_P - x_P0), v = -(y_P - y_P0), Eq. (4.18) with Θ = 0. Home: both
    joints at 0 approached forward (the rig's initial state); long approaches in ``d``.
    """
    x0, y0, _ = truth.tool_point(0.0, 0.0, 0.0, 1, 1)
    zero = np.zeros_like(q)
    X, Y = (q, zero) if axis == "x" else (zero, q)
    dx, dy = (d, 1) if axis == "x" else (1, d)
    x_P, y_P, _ = truth.tool_point(X, Y, zero, dx, dy)
    u, v = -(x_P - x0), -(y_P - y0)
    return (q - u, 0 - v) if axis == "x" else (q - v, 0 - u)  # (driving, coupling)


def test_sign_convention_on_the_rig(runs):
    """+X makes x_m grow by ≈ X, +Y makes y_m grow by ≈ Y (α ≈ 180°, β ≈ 0)."""
    rx, ry, _, _ = runs
    u, v = stage_positions(rx)
    fwd = rx["direction"].values == 1
    slope = np.polyfit(rx["cmd_x"].values[fwd], u[fwd], 1)[0]
    assert slope == pytest.approx(1.0, abs=2e-3)
    u, v = stage_positions(ry)
    fwd = ry["direction"].values == 1
    assert np.polyfit(ry["cmd_y"].values[fwd], v[fwd], 1)[0] == pytest.approx(1.0, abs=2e-3)


def test_tables_match_rig_truth(runs):
    _, _, truth, ds = runs
    sigma = np.hypot(truth.sensor_noise_um, truth.stage_repeatability_um)
    for axis, other in (("x", "y"), ("y", "x")):
        q = ds[f"{axis}_position"].values
        for j, d in enumerate((1, -1)):
            drive, couple = true_tables(truth, axis, q, d)
            got_drive = ds[f"err_{axis}{axis}"].values[:, j]
            got_couple = ds[f"err_{axis}{other}"].values[:, j] + ds[f"delta_{other}"].values
            for got, want in ((got_drive, drive), (got_couple, couple)):
                diff = got - want
                # every table point is relative to the single home reading: its noise is a
                # common offset (a few sigma at most); around it, the mean of the cycles
                offset = np.mean(diff)
                assert abs(offset) < 4 * sigma, (axis, d, offset)
                assert np.max(np.abs(diff - offset)) < 5 * sigma, (axis, d, np.max(np.abs(diff - offset)))
                assert np.sqrt(np.mean((diff - offset) ** 2)) < 1.5 * sigma


def test_fft_finds_the_thread_pitch(runs):
    _, _, truth, ds = runs
    for name in ("period_xx", "period_xy", "period_yx", "period_yy"):
        print(name, float(ds[name]))
        assert float(ds[name]) == pytest.approx(truth.thread_pitch_um, rel=0.02)


def test_forward_backward_differ_by_backlash_and_amplitude(runs):
    """b_xx − f_xx = -cos α (backlash − (A_bwd − A_fwd) sin φ): mean ≈ backlash, swing ≈ ΔA."""
    _, _, truth, ds = runs
    for axis, k in (("x", 0), ("y", 1)):
        q = ds[f"{axis}_position"].values
        diff = (
            ds[f"err_{axis}{axis}"].sel(direction=-1).values - ds[f"err_{axis}{axis}"].sel(direction=1).values
        )
        assert diff.mean() == pytest.approx(truth.backlash_um, abs=0.15)
        phase = 2 * np.pi * q / truth.thread_pitch_um
        basis = np.column_stack([np.ones_like(q), np.sin(phase), np.cos(phase)])
        c = np.linalg.lstsq(basis, diff, rcond=None)[0]
        assert np.hypot(c[1], c[2]) == pytest.approx(truth.lead_bwd_um[k] - truth.lead_fwd_um[k], abs=0.15)


def test_perpendicularity_and_alignment(runs):
    _, _, truth, ds = runs
    assert float(ds["perpendicularity"]) == pytest.approx(truth.beta_deg, abs=0.02)
    assert float(ds["x_stage_angle"]) == pytest.approx(truth.alpha_deg - 180.0, abs=0.02)
    # δx(y) of Eq. (4.14): x error while Y moves grows like −sin(α+β)·y
    assert float(ds["delta_x_slope"]) == pytest.approx(
        -np.sin(np.radians(truth.alpha_deg + truth.beta_deg)), abs=1e-3
    )


def test_repeatability_is_range_over_cycles(runs):
    _, _, truth, ds = runs
    rep = ds["rep_xx"].values
    assert np.all(rep[np.isfinite(rep)] >= 0) and np.all(ds["cycles_x"].values == CYCLES)
    sigma = np.hypot(truth.sensor_noise_um, truth.stage_repeatability_um)
    assert 0.3 * sigma < np.median(rep) < 2 * sigma  # range of 2 readings: median ≈ 0.95 σ
    quiet, _ = sweep(
        "x",
        stop=400,
        sensor_noise_um=0.0,
        stage_repeatability_um=0.0,
        room_swing_degC=0.0,
        decode_error_um=0.0,
        gross_error_rate=0.0,
    )
    assert np.nanmax(characterise_axis(quiet)["rep_xx"].values) <= 0.011  # sensor resolution only
    assert np.all(np.isnan(characterise_axis(sweep("x", stop=100, cycles=1)[0])["rep_xx"].values))


def test_dataset_is_cf_luts(runs):
    _, _, _, ds = runs
    assert ds.attrs["calflow_kind"] == "luts"
    assert validate_dataset(ds) == []
    assert set(ds["err_xx"].dims) == {"x_position", "direction"} and list(ds["direction"].values) == [1, -1]
    assert ds.attrs["nan_readings_x"] == 0 and ds.attrs["nan_readings_y"] == 0


def test_nan_readings_are_skipped_and_counted():
    """With the camera at y = 1500 µm it leaves the 4.2 mm pattern near Y ≈ 2700 µm: NaN readings."""
    run, _ = sweep("y", stop=3000, cycles=1, step=20, camera_x_um=1000.0, camera_y_um=1500.0)
    ds = characterise_axis(run)
    pos, err = ds["y_position"].values, ds["err_yy"].sel(direction=1).values
    assert ds.attrs["nan_readings_y"] > 0
    measured = run["direction"].values != 0  # approach rows are not table points
    assert ds.attrs["nan_readings_y"] == int(np.isnan(run["meas_y"].values[measured]).sum())
    assert np.all(np.isfinite(err[pos <= 2600])) and np.all(np.isnan(err[pos >= 2800]))
    assert np.all(ds["cycles_y"].values[pos >= 2800] == 0)


def test_dominant_period_on_synthetic_signal():
    q = np.arange(0, 3000, 5.0)
    e = 0.002 * q + 1.5 * np.sin(2 * np.pi * q / 250 + 0.3) + 0.3 * np.sin(2 * np.pi * q / 90)
    assert dominant_period(q, e) == pytest.approx(250, rel=0.01)
    e[100:110] = np.nan  # the longest finite stretch is used
    assert dominant_period(q, e) == pytest.approx(250, rel=0.02)
    assert np.isnan(dominant_period(q[:5], e[:5]))


def test_home_and_axis_errors():
    run, _ = sweep("x", stop=50, cycles=1)
    with pytest.raises(DataError, match="pose 0"):
        stage_positions(run.assign(pose=run["pose"].where(run["pose"] != 0, 99)))
    bad = run.copy()
    bad["meas_x"] = bad["meas_x"].copy()
    bad["meas_x"].values[0] = np.nan
    with pytest.raises(DataError, match="home reading"):
        stage_positions(bad)
