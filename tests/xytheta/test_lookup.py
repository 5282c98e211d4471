"""Lookup-table compensation: PositionLUT (Eq. 4.14/4.15) and AngleLUT (Fig. 4.26, Eq. 4.19)."""

import functools

import numpy as np
import pytest
import xarray as xr
from conftest import XY_NOISE_UM
from hypothesis import given, settings
from hypothesis import strategies as st

from calflow.acquisition.runner import acquire
from calflow.data.runs import RunMetadata
from calflow.data.validate import validate_dataset
from calflow.xytheta.evaluation import xytheta_validation_metrics
from calflow.xytheta.models.kinematics import Parameters, forward, inverse
from calflow.xytheta.plans import sweeps
from calflow.xytheta.plans.poses import validation
from calflow.xytheta.stage.rig import simulated_xytheta
from calflow.xytheta.tables.angle_residuals import AngleLUT, angle_residuals_from_run, joint_increments
from calflow.xytheta.tables.characterisation import characterise, xy_positioning_metrics
from calflow.xytheta.tables.position import PositionLUT, infer_directions, sequential_commands


def meta(plan):
    return RunMetadata(campaign="t", robot="xytheta", source="simulated", plan=plan, config_sha256="0" * 64)


@pytest.fixture(scope="module")
def lut_ds():
    runs = [
        acquire(
            sweeps.characterisation(a, stop_um=2000, step_um=5, cycles=2),
            simulated_xytheta(seed=21, stream=f"char-{a}"),
            meta(f"characterisation_{a}"),
        )
        for a in "xy"
    ]
    return characterise(*runs, meta=meta("characterisation_x"))


def synthetic(n=41, step=50.0, **kw):
    q = np.arange(n) * step
    s = np.sin(2 * np.pi * q / 400)
    tab = lambda a, b: np.column_stack([a + s, b + 2 * s])  # noqa: E731
    return PositionLUT(
        q, q, tab(1.0, 3.0), tab(0.1, 0.2), tab(-0.1, -0.3), tab(0.5, 1.5), (0.2, -0.01), (0.0, 0.03), **kw
    )


def test_errors_follow_eq_4_14_4_15_and_direction():
    lut = synthetic()
    s = lambda q: np.sin(2 * np.pi * q / 400)  # noqa: E731
    ex, ey = lut.errors(100.0, 300.0, 1, -1)  # on grid points: exact table values
    assert ex == pytest.approx((1 + s(100)) + (0.2 - 0.01 * 300) + (-0.3 + 2 * s(300)))
    assert ey == pytest.approx((0.1 + s(100)) + 0.03 * 100 + (1.5 + 2 * s(300)))
    ex2, _ = lut.errors(100.0, 300.0, -1, -1)
    assert ex2 - ex == pytest.approx(2.0 + s(100))  # backward table b_xx instead of f_xx
    x = np.array([0.0, 100.0, 250.0])
    ex, ey = lut.errors(x, 0.0, infer_directions(x), 1)
    assert ex.shape == (3,)
    with pytest.raises(ValueError, match="dir_x"):
        lut.errors(1.0, 1.0, 0, 1)


def test_tables_inside_a_model_hold_only_the_stages_own_errors():
    """On a rig whose stages have no error of their own — only the thesis's 2.3° misalignment
    and perpendicularity, which α and β represent — the tables a kinematic model uses
    (trends=False) are zero within noise: no cosine error of the misalignment (7.7 µm at
    9.45 mm in the raw along-travel table), no offset from the home reading, zero at home."""
    from calflow.xytheta.stage.physics import options_off

    quiet = {**options_off(), "stage_repeatability_um": 0.01, "sensor_noise_um": 0.01}
    runs = [
        acquire(
            sweeps.characterisation(a, stop_um=s, step_um=100, cycles=1),
            simulated_xytheta(seed=3, stream=f"char-{a}", **quiet),
            meta(f"characterisation_{a}"),
        )
        for a, s in (("x", 9000.0), ("y", 3600.0))
    ]
    lut = PositionLUT.from_dataset(characterise(*runs, meta=meta("characterisation_x")))
    X, Y = np.meshgrid(np.linspace(0, 9000, 7), np.linspace(0, 3600, 5))
    raw_x, raw_y = lut.errors(X, Y, 1, 1, trends=True)
    ex, ey = lut.errors(X, Y, 1, 1, trends=False)
    assert np.max(np.abs(raw_x - raw_x.min())) > 5.0  # the raw table holds the cosine error
    assert np.max(np.abs(ex)) < 0.1 and np.max(np.abs(ey)) < 0.1
    e0 = lut.errors(0.0, 0.0, 1, 1, trends=False)
    assert e0[0] == pytest.approx(0.0, abs=1e-12) and e0[1] == pytest.approx(0.0, abs=1e-12)


def test_linear_and_cubic_interpolation():
    q = np.linspace(3, 1990, 97)
    truth = 1 + np.sin(2 * np.pi * q / 400)  # f_xx forward of synthetic(), other terms zero at y=0, dy=+1
    lut = synthetic()
    other = lut.errors(np.zeros_like(q), 0.0, 1, 1)[0] - 1.0  # constant part from Y tables, δx
    err = {
        m: np.max(np.abs(lut.errors(q, 0.0, 1, 1, method=m)[0] - other - truth)) for m in ("linear", "cubic")
    }
    assert err["cubic"] < 0.01 < 0.03 < err["linear"] < 0.08  # 50 µm grid: h²/8·|f''| ≈ 0.077 for linear
    with pytest.raises(ValueError, match="interpolation method"):
        lut.errors(1.0, 1.0, 1, 1, method="quintic")


def test_outside_the_table_raises_or_clamps():
    lut = synthetic()
    with pytest.raises(ValueError, match=r"X table xx.*outside the table \[0, 2000\]"):
        lut.errors(2100.0, 10.0, 1, 1)
    clamped = synthetic(bounds="clamp")
    assert clamped.errors(2100.0, 10.0, 1, 1)[0] == pytest.approx(clamped.errors(2000.0, 10.0, 1, 1)[0])
    with pytest.raises(ValueError):
        synthetic(bounds="wrap")


def test_compensation_solves_the_fixed_point():
    lut = synthetic()
    x_T, y_T = np.array([400.0, 777.0]), np.array([900.0, 1234.0])
    X, Y = lut.compensate(x_T, y_T, 1, -1)
    ex, ey = lut.errors(X, Y, 1, -1)
    assert np.allclose(X - ex, x_T, atol=1e-6) and np.allclose(Y - ey, y_T, atol=1e-6)
    X1, Y1 = lut.compensate(x_T, y_T, 1, -1, iterations=1)  # thesis: tables read at the target
    assert np.allclose([X1, Y1], np.add([x_T, y_T], lut.errors(x_T, y_T, 1, -1)))


def test_netcdf_round_trip(lut_ds, tmp_path):
    lut = PositionLUT.from_dataset(lut_ds)
    ds = lut.to_dataset(meta("characterisation_x"))
    assert validate_dataset(ds) == []
    ds.to_netcdf(tmp_path / "luts.nc")
    back = PositionLUT.from_dataset(xr.load_dataset(tmp_path / "luts.nc"))
    x, y = np.array([10.0, 1234.5, 1990.0]), np.array([1500.0, 3.0, 700.0])
    for d in (1, -1):
        assert np.allclose(back.errors(x, y, d, -d), lut.errors(x, y, d, -d))


def test_infer_directions_fig_4_10():
    assert infer_directions([1, 2, 2, 1, 1, 3]).tolist() == [1, 1, 1, -1, -1, 1]
    assert infer_directions([0, 0, -1], start=0, initial=-1).tolist() == [-1, -1, -1]


def test_sequential_commands_agree_with_the_stage():
    def comp(x, y, dx, dy):  # backlash-like: backward needs 2 µm more; x creeps back with y
        return x + np.where(dx < 0, 2.0, 0.0) - 0.05 * y, y + np.where(dy < 0, 2.0, 0.0)

    x_T = np.array([100, 100, 100, 100, 100, 50.0, 50.0])
    y_T = np.array([0, 100, 200, 210, 210, 210, 209.0])
    X, Y, DX, DY = sequential_commands(comp, x_T, y_T)
    prev_x, prev_y = np.concatenate([[0.0], X[:-1]]), np.concatenate([[0.0], Y[:-1]])
    for c, p, d in ((X, prev_x, DX), (Y, prev_y, DY)):
        moved = c != p
        assert np.array_equal(np.sign(c - p)[moved], d[moved])  # each move is in its assumed direction
    assert DX[1] == -1  # x target constant, command creeps back: the stage approaches backward
    assert Y[-1] == Y[-2]  # 1 µm down, less than the 2 µm gap: Y is held


def run_xy(plan_fn, compensate, seed, directions="command", **kw):
    plan = plan_fn(compensate=compensate, directions=directions, **kw)
    return xy_positioning_metrics(
        acquire(plan, simulated_xytheta(seed=seed, stream=plan.name), meta(plan.name))
    )


def test_compensation_on_the_rig_random_points(lut_ds):
    """Sec. 4.4.2 (thesis 22 → 7 µm); our rig's X stage is misaligned by α − 180° ≈ −2.3°."""
    lut = PositionLUT.from_dataset(lut_ds)
    targets = np.random.default_rng(5).uniform(100, 1900, (10, 2))
    plan_fn = functools.partial(sweeps.random_points, cycles=5, targets=targets)
    res = {"none": run_xy(plan_fn, None, 31)}
    for m in ("linear", "cubic"):
        res[m] = run_xy(plan_fn, functools.partial(lut.compensate, method=m), 31)
    res["one-shot"] = run_xy(
        plan_fn, functools.partial(lut.compensate, iterations=1), 31, directions="target"
    )
    ap = {k: v.attrs["accuracy_um"] for k, v in res.items()}
    print(
        "random points AP (um):",
        {k: round(v, 3) for k, v in ap.items()},
        "RP:",
        {k: round(v.attrs["repeatability_um"], 3) for k, v in res.items()},
    )
    assert ap["none"] > 20
    for m in ("linear", "cubic"):
        assert ap[m] < 0.05 * ap["none"] and ap[m] < 8 * XY_NOISE_UM
    assert ap["linear"] < ap["one-shot"] < 0.2 * ap["none"]


def test_compensation_on_the_rig_square(lut_ds):
    """Fig. 4.12/4.13 on a 1.8 mm square inside the characterised (and readable) range."""
    lut = PositionLUT.from_dataset(lut_ds)
    plan_fn = functools.partial(sweeps.square, side_um=1800, origin_um=100, points_per_segment=20, cycles=3)
    none = run_xy(plan_fn, None, 41).attrs["accuracy_um"]
    cmd = run_xy(plan_fn, lut.compensate, 41).attrs["accuracy_um"]
    tgt = run_xy(plan_fn, lut.compensate, 41, directions="target").attrs["accuracy_um"]
    print(
        f"square AP (um): none {none:.3f}, LUT command-directions {cmd:.3f}, LUT target-directions {tgt:.3f}"
    )
    assert none > 20 and cmd < 0.03 * none and cmd < 8 * XY_NOISE_UM
    assert tgt < 0.1 * none and cmd < tgt  # Fig. 4.10 guesses X's direction wrong on BC/DA


# --- AngleLUT ----------------------------------------------------------------------------

params = st.builds(
    Parameters,
    x_R=st.floats(-20000, 20000),
    y_R=st.floats(-20000, 20000),
    alpha=st.floats(0, 360),
    beta=st.floats(-5, 5),
)
small = st.floats(-50, 50)


@settings(max_examples=300)
@given(params, st.floats(-5000, 15000), st.floats(-5000, 15000), st.floats(-30, 30), small, small)
def test_g_cancels_f_through_the_forward_kinematics(p, X, Y, theta, f_ax, f_ay):
    g_ax, g_ay = joint_increments(f_ax, f_ay, p.alpha, p.beta)
    want = forward(X, Y, theta, p)
    got = forward(X + g_ax, Y + g_ay, theta, p, f_ax=f_ax, f_ay=f_ay)
    assert np.allclose(got, want, atol=1e-7, rtol=1e-10)


@settings(max_examples=100)
@given(params, st.floats(-3000, 3000), st.floats(-3000, 3000), st.floats(-30, 30), small, small)
def test_inverse_with_g_reaches_the_target_despite_f(p, x_T, y_T, theta, f_ax, f_ay):
    g_ax, g_ay = joint_increments(f_ax, f_ay, p.alpha, p.beta)
    X, Y = inverse(x_T, y_T, theta, p, g_ax=g_ax, g_ay=g_ay)  # Eq. (4.19), Models IV/V
    assert np.allclose(forward(X, Y, theta, p, f_ax=f_ax, f_ay=f_ay), [x_T, y_T], atol=1e-7, rtol=1e-10)


def test_angle_lut_averages_per_angle_and_interpolates():
    theta = np.array([1, 2, 1, 2, 3, 3.0000001])
    lut = AngleLUT.from_residuals(theta, [1, 4, 3, 6, 9, np.nan], [0, 0, 2, 2, 5, 5], alpha=180, beta=0)
    assert lut.theta.tolist() == [0, 1, 2, 3]  # f(0) = 0 added: the world frame is defined at Θ = 0
    assert lut.f_ax.tolist() == [0, 2, 5, 9] and lut.f_ay.tolist() == [0, 1, 1, 5]  # NaN skipped
    assert lut.f(1.5)[0] == pytest.approx(3.5)
    assert lut.f(2.0, "cubic")[0] == pytest.approx(5.0)
    g_ax, g_ay = lut.g(2.0)
    assert (g_ax, g_ay) == pytest.approx((5.0, 1.0))  # α = 180°: X moves along −x, so g = +f
    with pytest.raises(ValueError, match="outside"):
        lut.f(3.5)
    assert AngleLUT.from_residuals(theta[:2], [1, 2], [1, 2], 180, 0, bounds="clamp").f(9.0)[0] == 2.0


def test_angle_lut_on_the_rig_model_ii_to_iv(tmp_path):
    """Fig. 4.26: residuals of Model II at 5 angles → g_ax, g_ay → Model IV, on a rig whose
    dominant error is the Θ stage's (a 1 % scale error: ≈ 11 µm at 5°), the rest off."""
    from calflow.xytheta.stage.physics import options_off

    physics = {**options_off(), "theta_scale_ppm": 10000.0}
    p = simulated_xytheta().truth_model.parameters  # stands in for identified Model II parameters
    model_ii = lambda x, y, th: inverse(x, y, th, p)  # noqa: E731
    run = acquire(
        sweeps.angle_residual_plan(model_ii, cycles=2),
        simulated_xytheta(seed=3, stream="ar", **physics),
        meta("angle_residuals"),
    )
    res = angle_residuals_from_run(run)
    assert res.nan_readings == 0 and res.theta.size == 90
    lut = AngleLUT.from_residuals(res.theta, res.f_ax, res.f_ay, p.alpha, p.beta)
    ds = lut.to_dataset(meta("angle_residuals"))
    assert validate_dataset(ds) == []
    ds.to_netcdf(tmp_path / "angle.nc")
    lut = AngleLUT.from_dataset(xr.load_dataset(tmp_path / "angle.nc"))

    def model_iv(x, y, th):
        g_ax, g_ay = lut.g(th)
        return inverse(x, y, th, p, g_ax=g_ax, g_ay=g_ay)

    acc = {}
    for name, inv in (("II", model_ii), ("IV", model_iv)):
        v = acquire(
            validation(inv, cycles=3), simulated_xytheta(seed=4, stream="val", **physics), meta("validation")
        )
        acc[name] = xytheta_validation_metrics(v, meta("validation")).attrs["accuracy_um"]
    print("validation AP (um):", {k: round(v, 3) for k, v in acc.items()})
    assert acc["II"] > 10 and acc["IV"] < 0.25 * acc["II"]
