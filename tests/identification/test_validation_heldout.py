"""Held-out validation, the Θ-indexed angle table, cross-validation, adequacy and coverage (issue 13).

Unit and property tests on synthetic data and short simulated runs; the full campaign's
held-out figures are checked in test_default_run.py.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from calflow.xytheta.models import cost
from calflow.xytheta.models.identification import identify
from calflow.xytheta.models.kinematics import Parameters, forward
from calflow.xytheta.models.resampling import cross_validate
from calflow.xytheta.plans.poses import heldout_targets, identification
from calflow.xytheta.report.heldout import adequacy, disjointness, repeatability_floor
from calflow.xytheta.stage.physics import options_off
from calflow.xytheta.steps import o2_plateau
from calflow.xytheta.tables.angle import AngleTable, _curves, angle_spectrum

NOMINAL = Parameters(10000.0, 8000.0, 180.0, 0.0)
#: a simulated rig whose only errors are geometric (and the noise of stage and sensor)
PARAMS_II = ("x_R_um", "y_R_um", "alpha_deg", "beta_deg")
GEOMETRIC_RIG = {**options_off(), "room_swing_degC": 0.0}


# ---------------------------------------------------------------------------- held-out targets


def test_heldout_targets_are_drawn_over_the_workspace_with_their_own_seed():
    t = heldout_targets(50, (0, 4000), (800, 2800), (0, 5), NOMINAL, seed=3)
    assert t.shape == (50, 3)
    assert np.all((t[:, 2] >= 0) & (t[:, 2] <= 5))
    assert not np.allclose(t[:, 2], np.round(t[:, 2]))  # a continuous Θ, not the table's integer angles
    assert np.array_equal(t, heldout_targets(50, (0, 4000), (800, 2800), (0, 5), NOMINAL, seed=3))
    assert not np.array_equal(t, heldout_targets(50, (0, 4000), (800, 2800), (0, 5), NOMINAL, seed=4))
    # the identification plan with the same seed draws other poses
    ident = identification(50, (0, 4000), (800, 2800), (0, 5), seed=3)
    assert not np.isin(np.round(t[:, 2], 9), np.round(ident.commands["theta"], 9)).any()


def _run(cmds, plan):
    import xarray as xr

    data = {f"cmd_{j}": ("sample", np.r_[0.0, cmds[:, k]]) for k, j in enumerate(("x", "y", "theta"))}
    return xr.Dataset({**data, "pose": ("sample", np.arange(len(cmds) + 1))}, attrs={"plan": plan})


def test_disjointness_finds_a_repeated_pose_and_only_it():
    rng = np.random.default_rng(0)
    train = np.column_stack([rng.uniform(0, 4000, 200), rng.uniform(800, 2800, 200), rng.uniform(0, 5, 200)])
    held = np.column_stack([rng.uniform(0, 4000, 30), rng.uniform(800, 2800, 30), rng.uniform(0, 5, 30)])
    assert (
        disjointness([_run(held, "validation_heldout")], [_run(train, "identification")])[
            "coincident_samples"
        ]
        == 0
    )
    held[7] = train[11] + [0.3, -0.2, 0.0]
    assert (
        disjointness([_run(held, "validation_heldout")], [_run(train, "identification")])[
            "coincident_samples"
        ]
        == 1
    )


# ---------------------------------------------------------------------------- angle table


def _sweep(period_deg, amplitude_um, step_deg, noise_um=0.05, cycles=2, positions=3, seed=0):
    """Synthetic swept residuals: a cubic plus one periodic component, forward and backward."""
    rng = np.random.default_rng(seed)
    grid = np.round(np.arange(0.0, 5.0 + 1e-9, step_deg), 9)
    rows = []
    for _ in range(positions):
        for c in range(cycles):
            for d in (1, -1):
                for a in grid[::d]:
                    f = 0.2 * a**3 + amplitude_um * np.sin(2 * np.pi * a / period_deg)
                    rows.append((a, f + rng.normal(0, noise_um), -f + rng.normal(0, noise_um), d, c))
    return np.array(rows), grid


@settings(max_examples=15, deadline=None)
@given(period=st.floats(1.0, 3.0), amplitude=st.floats(2.0, 15.0))
def test_table_step_follows_the_shortest_significant_period(period, amplitude):
    r, grid = _sweep(period, amplitude, 0.05)
    spectrum, _ = angle_spectrum(
        r[:, 0], r[:, 1], r[:, 2], r[:, 3], r[:, 4].astype(int), grid, samples_per_period=8
    )
    assert spectrum.shortest_period_deg == pytest.approx(period, rel=0.2)
    assert spectrum.step_deg <= spectrum.shortest_period_deg / 8 + 1e-9
    assert spectrum.step_deg > spectrum.shortest_period_deg / 16  # not finer than it needs
    assert not spectrum.undersampled and spectrum.warning == ""


def test_a_coarse_sweep_is_said_to_undersample():
    r, grid = _sweep(1.0, 10.0, 0.25)
    spectrum, _ = angle_spectrum(
        r[:, 0], r[:, 1], r[:, 2], r[:, 3], r[:, 4].astype(int), grid, samples_per_period=8
    )
    assert spectrum.undersampled
    assert "undersamples" in spectrum.warning and "step_deg" in spectrum.warning


def test_noise_alone_is_not_significant():
    r, grid = _sweep(1.0, 0.0, 0.1, noise_um=0.5)
    spectrum, _ = angle_spectrum(r[:, 0], r[:, 1], r[:, 2], r[:, 3], r[:, 4].astype(int), grid)
    assert spectrum.shortest_period_deg is None


def _curves_by_loop(theta, f, direction, cycle, grid):
    """The per-bin loop ``_curves`` replaced (issue 15): the reference of its vectorised binning."""
    k = np.rint((theta - grid[0]) / (grid[1] - grid[0])).astype(int)
    mean, noise = np.full((2, grid.size), np.nan), np.full((2, grid.size), np.nan)
    for row, d in enumerate((1, -1)):
        for j in range(grid.size):
            sel = (direction == d) & (k == j) & np.isfinite(f)
            if sel.any():
                mean[row, j] = f[sel].mean()
                even, odd = sel & (cycle % 2 == 0), sel & (cycle % 2 == 1)
                if even.any() and odd.any():
                    noise[row, j] = 0.5 * (f[even].mean() - f[odd].mean())
    return mean, noise


@settings(max_examples=60, deadline=None)
@given(
    n=st.integers(1, 300),
    bins=st.integers(2, 40),
    seed=st.integers(0, 2**31 - 1),
    nan_fraction=st.floats(0.0, 0.5),
)
def test_vectorised_binning_equals_the_per_bin_loop(n, bins, seed, nan_fraction):
    rng = np.random.default_rng(seed)
    grid = np.linspace(-1.0, 4.0, bins)
    step = grid[1] - grid[0]
    theta = rng.uniform(grid[0] - 2 * step, grid[-1] + 2 * step, n)  # some readings off the grid
    f = rng.normal(0.0, 10.0, n)
    f[rng.random(n) < nan_fraction] = np.nan
    direction, cycle = rng.choice([1, -1, 0], n), rng.integers(0, 4, n)
    got, want = _curves(theta, f, direction, cycle, grid), _curves_by_loop(theta, f, direction, cycle, grid)
    for g, w in zip(got, want):
        assert np.array_equal(np.isnan(g), np.isnan(w))
        assert np.allclose(g[np.isfinite(w)], w[np.isfinite(w)], rtol=1e-12, atol=1e-12)


def test_angle_table_is_indexed_by_theta_alone_and_interpolates_per_direction():
    table = AngleTable(
        np.array([0.0, 1.0, 2.0]), np.array([[0.0, 2.0, 4.0], [1.0, 3.0, 5.0]]), np.zeros((2, 3)), 180.0, 0.0
    )
    fx, _ = table.f(np.array([0.5, 1.5]), np.array([1, -1]))
    assert fx == pytest.approx([1.0, 4.0])
    assert table.f(0.5)[0] == pytest.approx(1.5)  # no direction: the mean
    with pytest.raises(ValueError, match="outside the table"):
        table.f(2.5)
    back = AngleTable.from_dataset(table.to_dataset())
    assert np.array_equal(back.f_ax, table.f_ax) and np.array_equal(back.theta, table.theta)


# ---------------------------------------------------------------------------- cross-validation, adequacy


def _poses(n, seed, noise_um, p: Parameters, extra=None):
    rng = np.random.default_rng(seed)
    X, Y, T = rng.uniform(0, 4000, n), rng.uniform(800, 2800, n), rng.uniform(0, 5, n)
    X[0] = Y[0] = T[0] = 0.0
    x, y = forward(X, Y, T, p)
    if extra is not None:
        x, y = x + extra(T), y - extra(T)
    return X, Y, T, x + rng.normal(0, noise_um, n), y + rng.normal(0, noise_um, n)


def test_cross_validation_matches_the_fit_when_the_model_is_right():
    truth = Parameters(9572.9, 7795.9, 177.69, -0.11)
    X, Y, T, Px, Py = _poses(300, 1, 0.5, truth)
    fit = identify(X, Y, T, Px, Py, initial=NOMINAL)
    cv = cross_validate(X, Y, T, Px, Py, ("x_R", "y_R", "alpha", "beta"), NOMINAL, k=5)
    assert cv == pytest.approx(fit.residual_rms_um, rel=0.15)
    assert cv >= fit.residual_rms_um * 0.95  # predicting poses it has not seen is no easier than fitting them


def test_adequacy_accepts_a_right_model_and_flags_a_wrong_one():
    truth = Parameters(9572.9, 7795.9, 177.69, -0.11)
    floor = {"floor_um": 0.5, "dof": 2000}
    from calflow.xytheta.models.identification import noise_sigma

    X, Y, T, Px, Py = _poses(600, 2, 0.5, truth)
    fit = identify(X, Y, T, Px, Py, initial=NOMINAL)
    eps = cost.residuals(fit.parameters, X, Y, T, Px, Py)
    right = adequacy(noise_sigma(eps, len(X), 4), len(X), 4, floor)
    assert right["adequate"] and 0.8 < right["chi2_dof"] < 1.25
    X, Y, T, Px, Py = _poses(600, 2, 0.5, truth, extra=lambda t: 12 * np.sin(2 * np.pi * t / 2.5))
    fit = identify(X, Y, T, Px, Py, initial=NOMINAL)
    eps = cost.residuals(fit.parameters, X, Y, T, Px, Py)
    wrong = adequacy(noise_sigma(eps, len(X), 4), len(X), 4, floor)
    assert wrong["adequate"] is False and "does not fit" in wrong["statement"]
    assert adequacy(1.0, 100, 4, {"floor_um": None, "dof": 0})["adequate"] is None


def test_repeatability_floor_pools_by_degrees_of_freedom():
    import xarray as xr

    a = xr.Dataset(attrs={"within_target_std_um": 1.0, "within_target_dof": 100})
    b = xr.Dataset(attrs={"within_target_std_um": 2.0, "within_target_dof": 300})
    assert repeatability_floor([a, b])["floor_um"] == pytest.approx(np.sqrt((100 + 4 * 300) / 400))


# ---------------------------------------------------------------------------- observability plateau


def test_o2_plateau_is_where_the_mean_stays_within_tolerance():
    counts = np.array([3, 5, 10, 20, 50, 100, 200, 400, 800, 1600])
    o2 = np.array([0.1, 0.3, 0.6, 0.8, 0.9, 0.97, 1.02, 0.99, 1.0, 1.01])
    limit, plateau = o2_plateau(counts, o2, 0.05)
    assert limit == pytest.approx(np.mean(o2[-2:]))
    assert plateau == 100
    o2[5] = 1.2  # one noisy overshoot before settling: the plateau is after it, not at it
    assert o2_plateau(counts, o2, 0.05)[1] == 200


# ---------------------------------------------------------------------------- Monte-Carlo coverage


@pytest.mark.parametrize(
    "model,rig", [("II", GEOMETRIC_RIG), ("I", {**GEOMETRIC_RIG, "alpha_deg": 180.0, "beta_deg": 0.0})]
)
def test_intervals_cover_the_truth_on_a_rig_the_model_describes(tmp_path, model, rig):
    """On a rig whose only errors are the model's, 95 % intervals hold the truth 90–99 % of the time."""
    import yaml
    from conftest import SMALL_XYTHETA

    from calflow.configuration.campaign import load as load_campaign
    from calflow.xytheta.studies.aggregate import aggregate
    from calflow.xytheta.studies.montecarlo import run_point

    (tmp_path / "c.yaml").write_text(yaml.safe_dump(SMALL_XYTHETA))
    c = load_campaign(tmp_path / "c.yaml")
    points = [
        run_point(c, seed, 0.05, 60, model, validation_cycles=2, rig_options=rig) for seed in range(100)
    ]
    cell = aggregate(points)["cells"][0]
    free = [k for k, v in cell["parameters"].items() if v["free"]]
    assert len(free) == (4 if model == "II" else 2)
    for key in free:
        assert 0.90 <= cell["parameters"][key]["coverage_95"] <= 0.99, (
            key,
            cell["parameters"][key]["coverage_95"],
        )
    for key in set(cell["parameters"]) - set(free):
        assert cell["parameters"][key]["coverage_95"] is None


def test_intervals_do_not_cover_the_truth_when_the_model_is_wrong(tmp_path):
    """Model II on the default rig (lead screw, backlash, yaw… it does not model): with many
    poses its σ shrink, the bias does not, and its intervals miss."""
    import yaml
    from conftest import SMALL_XYTHETA

    from calflow.configuration.campaign import load as load_campaign
    from calflow.xytheta.studies.aggregate import aggregate
    from calflow.xytheta.studies.montecarlo import run_point

    (tmp_path / "c.yaml").write_text(yaml.safe_dump(SMALL_XYTHETA))
    c = load_campaign(tmp_path / "c.yaml")
    points = [run_point(c, seed, 0.05, 1200, "II", validation_cycles=2) for seed in range(12)]
    cell = aggregate(points)["cells"][0]
    assert min(cell["parameters"][k]["coverage_95"] for k in PARAMS_II) < 0.5
