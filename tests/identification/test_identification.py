"""Identification of x_R, y_R, α, β with the pose-difference cost, Eq. (4.28)–(4.30)."""

import numpy as np
import pytest

from calflow.identification import diagnostics
from calflow.xytheta.models import cost
from calflow.xytheta.models.identification import identify
from calflow.xytheta.models.kinematics import Parameters, forward

TRUE = Parameters(9572.9, 7795.9, 177.69, -0.11)


def _poses(n, seed=1):
    rng = np.random.default_rng(seed)
    return rng.uniform(0, 4000, n), rng.uniform(0, 2000, n), rng.uniform(0, 5, n)


def _measure(X, Y, theta, p, noise=0.0, seed=2, offset=(123.4, -56.7)):
    """Measured tool points up to an unknown offset, as Eq. (4.27) gives them."""
    rng = np.random.default_rng(seed)
    x, y = forward(X, Y, theta, p)
    return x + offset[0] + rng.normal(0, noise, x.shape), y + offset[1] + rng.normal(0, noise, y.shape)


def test_noise_free_recovers_parameters_to_1e6_relative():
    X, Y, theta = _poses(300)
    P_mx, P_my = _measure(X, Y, theta, TRUE)
    res = identify(X, Y, theta, P_mx, P_my, initial=Parameters(10000.0, 8000.0))
    got, want = res.parameters.as_array(), TRUE.as_array()
    assert np.all(np.abs(got - want) <= 1e-6 * np.abs(want))
    assert res.residual_rms_um < 1e-6


@pytest.mark.parametrize("seed", [3, 4, 5])
def test_noisy_estimate_within_a_few_standard_deviations(seed):
    X, Y, theta = _poses(400, seed)
    P_mx, P_my = _measure(X, Y, theta, TRUE, noise=0.5, seed=seed + 10)
    res = identify(X, Y, theta, P_mx, P_my, initial=Parameters(10000.0, 8000.0))
    for name in ("x_R", "y_R", "alpha", "beta"):
        err = getattr(res.parameters, name) - getattr(TRUE, name)
        assert res.std[name] > 0
        assert abs(err) < 4 * res.std[name], (name, err, res.std[name])


def test_standard_deviations_are_calibrated_over_repeats():
    """Across repeated noisy identifications the spread of α matches the reported std."""
    X, Y, theta = _poses(200, 8)
    alphas, stds = [], []
    for k in range(40):
        P_mx, P_my = _measure(X, Y, theta, TRUE, noise=1.0, seed=100 + k)
        res = identify(X, Y, theta, P_mx, P_my, initial=Parameters(10000.0, 8000.0))
        alphas.append(res.parameters.alpha)
        stds.append(res.std["alpha"])
    ratio = np.std(alphas, ddof=1) / np.mean(stds)
    assert 0.6 < ratio < 1.5


def test_fixed_parameters_stay_fixed():
    X, Y, theta = _poses(100)
    P_mx, P_my = _measure(X, Y, theta, TRUE)
    res = identify(X, Y, theta, P_mx, P_my, free=("x_R", "y_R"), initial=Parameters(10000.0, 8000.0))
    assert res.parameters.alpha == 180.0 and res.parameters.beta == 0.0
    assert np.isnan(res.correlation).sum() == 0 and res.correlation.shape == (2, 2)


def test_no_residual_dof_gives_nan_uncertainty_not_a_number_made_up():
    X, Y, theta = _poses(3)
    P_mx, P_my = _measure(X, Y, theta, TRUE)
    res = identify(X, Y, theta, P_mx, P_my, initial=Parameters(9500.0, 7700.0, 177.0, 0.0))
    assert res.dof == 0
    assert all(np.isnan(v) for v in res.std.values())


def test_nan_rows_are_dropped():
    X, Y, theta = _poses(100)
    P_mx, P_my = _measure(X, Y, theta, TRUE)
    P_mx[[5, 17]] = np.nan
    res = identify(X, Y, theta, P_mx, P_my, initial=Parameters(10000.0, 8000.0))
    assert res.n_poses == 98
    assert np.allclose(res.parameters.as_array(), TRUE.as_array(), rtol=1e-8)


def test_residuals_vanish_at_truth_and_jacobian_matches_differences():
    X, Y, theta = _poses(20)
    P_mx, P_my = _measure(X, Y, theta, TRUE)
    assert np.allclose(cost.residuals(TRUE, X, Y, theta, P_mx, P_my), 0, atol=1e-8)
    J = cost.jacobian(TRUE, X, Y, theta)
    assert J.shape == (2 * 19, 4)
    phi = TRUE.as_array()
    for k in range(4):
        h = 1e-3 if k < 2 else 1e-6
        up, dn = phi.copy(), phi.copy()
        up[k] += h
        dn[k] -= h
        fd = (
            cost.residuals(Parameters.from_array(up), X, Y, theta, P_mx, P_my)
            - cost.residuals(Parameters.from_array(dn), X, Y, theta, P_mx, P_my)
        ) / (2 * h)
        assert np.allclose(J[:, k], fd, rtol=1e-5, atol=1e-6)


def test_identifiability_names_a_parameter_that_cannot_be_identified():
    """With Θ fixed at 0, x_R and y_R do not act on the tool point: R_kk = 0."""
    X, Y, _ = _poses(50)
    theta = np.zeros_like(X)
    J = cost.jacobian(TRUE, X, Y, theta)
    r, bad = diagnostics.identifiability(J, ("x_R", "y_R", "alpha", "beta"))
    assert set(bad) >= {"x_R", "y_R"}
    _, none_bad = diagnostics.identifiability(
        cost.jacobian(TRUE, *_poses(50)), ("x_R", "y_R", "alpha", "beta")
    )
    assert none_bad == []


def test_observability_indices_follow_their_definitions():
    J = cost.jacobian(TRUE, *_poses(200))
    s = np.linalg.svd(J, compute_uv=False)
    o = diagnostics.observability(J)
    assert np.isclose(o["O1"], np.prod(s) ** (1 / 4) / 4)
    assert np.isclose(o["O2"], s[-1] / s[0])
    assert np.isclose(o["O3"], s[-1])
    assert np.isclose(o["O4"], s[-1] ** 2 / s[0])


# ---------------------------------------------------------------------------- efficiency (issue 15, item 4)

from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from calflow.xytheta.models.identification import crlb  # noqa: E402

START = Parameters(10000.0, 8000.0, 180.0, 0.0)


def test_sigma_reaches_the_cramer_rao_bound_over_repeats():
    """Model II with independent noise per reading: the spread of each parameter over 300
    noisy repeats of the same poses is within 10 % of the Cramér–Rao bound (efficient), and
    the σ each fit reports estimates that bound."""
    X, Y, theta = _poses(60, 21)
    x, y = forward(X, Y, theta, TRUE)
    rng = np.random.default_rng(22)
    est, std = [], []
    for _ in range(300):
        e = rng.normal(0, 0.5, (2, X.size))
        res = identify(X, Y, theta, x + 100.0 + e[0], y - 50.0 + e[1], initial=START)
        est.append(res.parameters.as_array())
        std.append([res.std[k] for k in ("x_R", "y_R", "alpha", "beta")])
    bound = np.array(list(crlb(TRUE, X, Y, theta, 0.5).std.values()))
    ratio = np.std(est, axis=0, ddof=1) / bound
    assert np.all(ratio <= 1.1) and np.all(ratio >= 0.85), ratio
    assert np.allclose(np.sqrt(np.mean(np.square(std), axis=0)) / bound, 1.0, atol=0.05)


def test_nuisance_estimate_is_the_gls_of_the_pose_differences():
    """Estimating the initial reading is generalised least squares on Eq. (4.29) with the
    differences' covariance D Dᵀ: one Gauss–Newton GLS step from the nuisance estimate does
    not move it (dense D Dᵀ here in the test only, on 25 poses)."""
    X, Y, theta = _poses(25, 31)
    P_mx, P_my = _measure(X, Y, theta, TRUE, noise=0.7, seed=32)
    res = identify(X, Y, theta, P_mx, P_my, initial=START)
    eps = cost.residuals(res.parameters, X, Y, theta, P_mx, P_my)
    J = cost.jacobian(res.parameters, X, Y, theta)
    m = eps.size
    G = 2.0 * np.eye(m) - np.eye(m, k=2) - np.eye(m, k=-2)  # Cov(ε)/σ² of the interleaved differences
    W = np.linalg.inv(G)
    step = np.linalg.solve(J.T @ W @ J, J.T @ W @ eps)
    scale = np.array([res.std[k] for k in ("x_R", "y_R", "alpha", "beta")])
    assert np.all(np.abs(step) < 1e-6 * scale)
    # and its covariance is the GLS one, σ̂² (Jᵀ (D Dᵀ)⁻¹ J)⁻¹
    assert np.allclose(res.covariance, res.sigma_um**2 * np.linalg.inv(J.T @ W @ J), rtol=1e-6)


@settings(max_examples=25, deadline=None)
@given(sigma=st.floats(0.01, 10.0), n=st.integers(5, 80), seed=st.integers(0, 1000))
def test_crlb_scales_with_noise_and_repeats(sigma, n, seed):
    """The bound is linear in σ, falls as 1/√k when every pose is visited k = 2 times, and
    a constant shift of the joints' frame in X leaves it unchanged only through φ (not an offset)."""
    X, Y, theta = _poses(n, seed)
    one = crlb(TRUE, X, Y, theta, 1.0)
    b = crlb(TRUE, X, Y, theta, sigma)
    twice = crlb(TRUE, np.tile(X, 2), np.tile(Y, 2), np.tile(theta, 2), sigma)
    for k in ("x_R", "y_R", "alpha", "beta"):
        assert np.isclose(b.std[k], sigma * one.std[k], rtol=1e-9)
        assert np.isclose(twice.std[k], b.std[k] / np.sqrt(2.0), rtol=1e-9)
    assert np.allclose(b.covariance @ b.information, np.eye(4), atol=1e-6)


def test_identification_memory_and_result_are_linear_in_poses():
    """No n × n object: every array of the result is at most 2n × p."""
    X, Y, theta = _poses(3000, 41)
    P_mx, P_my = _measure(X, Y, theta, TRUE, noise=0.3, seed=42)
    res = identify(X, Y, theta, P_mx, P_my, initial=START)
    for value in vars(res).values():
        if isinstance(value, np.ndarray):
            assert value.size <= 2 * 3000 * 4


# ---------------------------------------------------------------------------- robust identification (item 5)


def _rig_run(gross_rate: float, poses: int = 800, seed: int = 5):
    """An identification run on the simulated rig whose only errors are Model II's and noise,
    with the vision sensor misreading a pattern period in ``gross_rate`` of the readings.
    The random draws do not depend on the rate: the same seed gives the same run bar the
    gross errors."""
    import yaml
    from conftest import SMALL_XYTHETA

    from calflow.configuration.config import validate
    from calflow.xytheta.plans.poses import identification
    from calflow.xytheta.stage.physics import options_off
    from calflow.xytheta.studies.montecarlo import simulate_run

    c = validate(yaml.safe_load(yaml.safe_dump(SMALL_XYTHETA)), "campaign-xytheta", "small.yaml")
    c["name"] = "small"
    c["rig"]["options"] = {**options_off(), "gross_error_rate": gross_rate}
    p = c["identification"]
    run, _ = simulate_run(
        c, identification(poses, p["x_um"], p["y_um"], p["theta_deg"], seed=seed), "identification", seed, 0.3
    )
    theta = run["meas_theta"].values - run["meas_theta"].values[0]
    P_mx, P_my = cost.measured_points(run["meas_x"].values, run["meas_y"].values, theta)
    return run, (run["cmd_x"].values, run["cmd_y"].values, theta, P_mx, P_my)


@pytest.mark.parametrize("loss", ["soft_l1", "huber", "linear"])
def test_gross_errors_in_one_percent_of_readings_are_rejected_and_the_fit_is_the_clean_one(loss):
    from calflow.identification.robust import Robust

    clean_run, clean = _rig_run(0.0)
    dirty_run, dirty = _rig_run(0.01)
    injected = np.flatnonzero(
        (dirty_run["meas_x"].values != clean_run["meas_x"].values)
        | (dirty_run["meas_y"].values != clean_run["meas_y"].values)
    )
    assert 3 <= injected.size <= 20  # ~1 % of 801 readings, each a whole 8 µm period
    reference = identify(*clean, initial=START)
    robust = identify(*dirty, initial=START, robust=Robust(loss=loss))
    plain = identify(*dirty, initial=START)
    assert list(robust.rejected) == list(injected)
    assert robust.n_poses == reference.n_poses - injected.size
    for k in ("x_R", "y_R", "alpha", "beta"):
        shift = abs(getattr(robust.parameters, k) - getattr(reference.parameters, k))
        assert shift < 0.3 * reference.std[k], (k, shift, reference.std[k])
        assert robust.std[k] == pytest.approx(reference.std[k], rel=0.1)
    assert plain.sigma_um > 1.2 * robust.sigma_um  # the gross errors would have inflated every σ
    assert robust.loss == loss and plain.rejected == ()


def test_robust_screening_rejects_nothing_on_clean_data():
    from calflow.identification.robust import Robust

    _, clean = _rig_run(0.0, poses=300, seed=9)
    res = identify(*clean, initial=START, robust=Robust())
    assert res.rejected == ()
    assert np.allclose(
        res.parameters.as_array(), identify(*clean, initial=START).parameters.as_array(), rtol=1e-10
    )


@settings(max_examples=12, deadline=None)
@given(poses=st.integers(3, 9), seed=st.integers(0, 10_000), gross=st.sampled_from([0.0, 0.3]))
def test_robust_screening_on_few_poses_keeps_enough_readings_to_fit(poses, seed, gross):
    """With a handful of poses (the Monte-Carlo study's 5) a rejection may not leave fewer
    residual degrees of freedom than unknowns: the fit stays defined and rejects nothing then."""
    from calflow.identification.robust import Robust

    _, data = _rig_run(gross, poses=poses, seed=seed)
    res = identify(*data, initial=START, robust=Robust())
    unknowns = 4 + 2  # x_R, y_R, α, β and the initial reading
    assert res.rejected == () or 2 * res.n_poses - unknowns >= unknowns
    assert np.all(np.isfinite(res.parameters.as_array()))


def test_robust_config_and_its_errors():
    from calflow.identification.robust import Robust, mad_sigma, outliers

    assert Robust.from_config({"loss": "none"}) is None
    assert Robust.from_config({"loss": "huber", "reject_sigma": 4}) == Robust(loss="huber", reject_sigma=4)
    with pytest.raises(ValueError, match="robust loss"):
        Robust(loss="tukey")
    with pytest.raises(ValueError, match="reject_sigma"):
        Robust(reject_sigma=0)
    r = np.random.default_rng(0).normal(0, 2.0, (4000, 2))
    assert mad_sigma(r) == pytest.approx(2.0, rel=0.05)
    r[7, 1] = 40.0
    assert np.flatnonzero(outliers(r, 2.0, 6.0)).tolist() == [7]


@pytest.mark.parametrize("loss", ["linear", "soft_l1", "huber", "cauchy"])
def test_gauss_newton_minimises_the_same_objective_as_scipy(loss):
    """IRLS Gauss–Newton and scipy's least_squares with the same robust loss agree on a
    curve fit with 5 % gross outliers."""
    from scipy.optimize import least_squares

    from calflow.identification.gauss_newton import solve

    rng = np.random.default_rng(7)
    t = np.linspace(0, 3, 400)
    y = 2.0 * np.exp(-0.7 * t) + 0.3 + rng.normal(0, 0.02, t.size)
    y[rng.choice(t.size, 20, replace=False)] += rng.choice([-1, 1], 20) * 0.5
    fun = lambda v: v[0] * np.exp(-v[1] * t) + v[2] - y  # noqa: E731
    jac = lambda v: np.column_stack([np.exp(-v[1] * t), -v[0] * t * np.exp(-v[1] * t), np.ones_like(t)])  # noqa: E731
    ours = solve(fun, jac, [1.0, 1.0, 0.0], loss, 0.05)
    ref = least_squares(
        fun, [1.0, 1.0, 0.0], jac=jac, loss=loss, f_scale=0.05, xtol=1e-14, ftol=1e-14, gtol=1e-14
    )
    assert ours.success and "Gauss-Newton" in ours.message
    assert np.allclose(ours.x, ref.x, rtol=1e-6, atol=1e-8), (ours.x, ref.x)


def test_gauss_newton_hands_a_singular_problem_to_scipy():
    from calflow.identification.gauss_newton import solve

    t = np.linspace(0, 1, 50)
    fun = lambda v: (v[0] + v[1]) * t - 2.0 * t  # noqa: E731  only v0 + v1 is determined
    jac = lambda v: np.column_stack([t, t])  # noqa: E731
    sol = solve(fun, jac, [0.0, 0.0])
    assert "scipy" in sol.message and np.isclose(sol.x.sum(), 2.0)


@settings(max_examples=40, deadline=None)
@given(n=st.integers(2, 60), seed=st.integers(0, 2**31 - 1), weighted=st.booleans())
def test_readings_are_the_reading_residuals_as_a_linear_map(n, seed, weighted):
    """cost.Readings (Θ's trigonometry once, normal equations from the data's Gram) gives
    the residuals, Jacobian and normal equations of reading_residuals/reading_jacobian."""
    rng = np.random.default_rng(seed)
    X, Y, theta = rng.uniform(0, 4000, n), rng.uniform(0, 2000, n), rng.uniform(-5, 5, n)
    P_mx, P_my = rng.normal(0, 5000, n), rng.normal(0, 5000, n)
    ex, ey, f_ax, f_ay = rng.normal(0, 3, (4, n))
    p = Parameters(*rng.normal([9500, 7800, 178, 0], [500, 500, 3, 0.5]))
    offset = rng.normal(0, 100, 2)
    phi = np.concatenate([p.as_array(), offset])
    readings = cost.Readings(X, Y, theta, P_mx, P_my, ex, ey, f_ax, f_ay)
    r = cost.reading_residuals(p, X, Y, theta, P_mx, P_my, offset, ex, ey, f_ax, f_ay)
    J = cost.reading_jacobian(p, X, Y, theta, ex, ey)
    scale = np.max(np.abs(readings.columns))
    assert np.allclose(readings.residuals(phi), r, rtol=0, atol=1e-12 * scale)
    assert np.allclose(readings.jacobian(phi), J, rtol=1e-12, atol=1e-12 * scale)
    w = rng.uniform(0.1, 1.0, 2 * n) if weighted else np.ones(2 * n)
    N, g, plain = readings.normal(phi, r, w if weighted else None)
    assert np.allclose(N, J.T @ (J * w[:, None]), rtol=1e-10, atol=1e-12 * scale**2)
    assert np.allclose(g, J.T @ (w * r), rtol=1e-10, atol=1e-10 * scale * np.abs(r).max())
    assert np.allclose(plain, J.T @ J, rtol=1e-10, atol=1e-12 * scale**2)
    sub = rng.random(n) < 0.5
    assert np.allclose(
        readings.subset(sub).residuals(phi),
        readings.residuals(phi).reshape(-1, 2)[sub].ravel(),
        rtol=0,
        atol=1e-12 * scale,
    )


def test_cross_validation_refits_each_fold_as_identify_does():
    """The bare fold fits of cross_validate (shared trigonometry, row subsets) are the
    identification of each fold's training poses."""
    from calflow.xytheta.models.resampling import cross_validate

    X, Y, theta = _poses(200, 11)
    P_mx, P_my = _measure(X, Y, theta, TRUE, noise=0.5, seed=12)
    X[17] = np.nan  # a dropped row
    free, start = ("x_R", "y_R", "alpha", "beta"), Parameters(10000.0, 8000.0)
    ok = np.flatnonzero(np.isfinite(X))
    folds = np.array_split(np.random.default_rng(4).permutation(ok[1:]), 5)
    sq, count = 0.0, 0
    for fold in folds:
        train = np.sort(np.concatenate([[ok[0]], np.setdiff1d(ok[1:], fold)]))
        fit = identify(X[train], Y[train], theta[train], P_mx[train], P_my[train], free=free, initial=start)
        test = np.sort(fold)
        eps = cost.residuals(fit.parameters, X[test], Y[test], theta[test], P_mx[test], P_my[test])
        sq, count = sq + eps @ eps, count + eps.size
    assert cross_validate(X, Y, theta, P_mx, P_my, free, start, 5, 4) == pytest.approx(
        np.sqrt(sq / count), rel=1e-9
    )


def test_gauss_newton_with_normal_equations_reaches_the_jacobian_path_optimum():
    """Gauss–Newton on the 7 × 7 normal equations of cost.Readings stops where the same
    solver on the explicit Jacobian does."""
    from calflow.identification.gauss_newton import solve

    X, Y, theta = _poses(300, 21)
    P_mx, P_my = _measure(X, Y, theta, TRUE, noise=0.5, seed=22)
    readings = cost.Readings(X, Y, theta, P_mx, P_my)
    start = np.array([10000.0, 8000.0, 180.0, 0.0, 0.0, 0.0])
    for loss in ("linear", "soft_l1"):
        fast = solve(readings.residuals, readings.jacobian, start, loss, 1.0, normal=readings.normal)
        slow = solve(readings.residuals, readings.jacobian, start, loss, 1.0)
        assert fast.success and "Gauss-Newton" in fast.message
        assert np.allclose(fast.x, slow.x, rtol=1e-10, atol=1e-9)


def test_identification_jacobian_is_that_of_the_pose_differences():
    """Identification.jacobian (differenced from the reading Jacobian of the fit) is
    cost.jacobian at the estimate, Eq. (4.30), in the free columns."""
    X, Y, theta = _poses(150, 31)
    P_mx, P_my = _measure(X, Y, theta, TRUE, noise=0.5, seed=32)
    for free in (("x_R", "y_R", "alpha", "beta"), ("x_R", "y_R")):
        res = identify(X, Y, theta, P_mx, P_my, free=free, initial=Parameters(10000.0, 8000.0, 177.69, -0.11))
        cols = [("x_R", "y_R", "alpha", "beta").index(name) for name in free]
        want = cost.jacobian(res.parameters, X, Y, theta)[:, cols]
        assert res.jacobian.shape == want.shape
        assert np.allclose(res.jacobian, want, rtol=1e-12, atol=1e-9)


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), k=st.integers(1, 5))
def test_lock_step_gauss_newton_equals_one_problem_at_a_time(seed, k):
    """solve_batch on k curve fits gives each the solution solve gives it alone."""
    from calflow.identification.gauss_newton import solve, solve_batch

    rng = np.random.default_rng(seed)
    t = np.linspace(0, 3, 60)
    ys = [
        rng.uniform(0.5, 3) * np.exp(-rng.uniform(0.2, 1.5) * t) + rng.normal(0, 0.02, t.size)
        for _ in range(k)
    ]
    x0 = np.tile([1.0, 1.0], (k, 1))

    def residuals(x, y):
        return x[0] * np.exp(-x[1] * t) - y

    def jacobian(x):
        return np.column_stack([np.exp(-x[1] * t), -x[0] * t * np.exp(-x[1] * t)])

    def cost(X):
        return np.array([residuals(x, y) @ residuals(x, y) for x, y in zip(X, ys)])

    def normal(X):
        J = [jacobian(x) for x in X]
        return np.stack([j.T @ j for j in J]), np.stack([j.T @ residuals(x, y) for j, x, y in zip(J, X, ys)])

    x, converged = solve_batch(cost, normal, x0, [t.size] * k)
    for f in range(k):
        alone = solve(lambda v, y=ys[f]: residuals(v, y), jacobian, x0[f])
        if converged[f]:
            assert "Gauss-Newton" in alone.message and np.allclose(x[f], alone.x, rtol=1e-12, atol=1e-12)
        else:  # left at its start for the caller, where solve needed scipy too
            assert "scipy" in alone.message and np.array_equal(x[f], x0[f])


def test_lock_step_gauss_newton_leaves_a_singular_problem_to_the_caller():
    from calflow.identification.gauss_newton import solve_batch

    t = np.linspace(0, 1, 50)
    J = np.column_stack([t, t])  # only v0 + v1 is determined
    x, converged = solve_batch(
        lambda X: np.array([np.sum(((x[0] + x[1]) * t - 2 * t) ** 2) for x in X]),
        lambda X: (np.stack([J.T @ J] * len(X)), np.stack([J.T @ ((x[0] + x[1]) * t - 2 * t) for x in X])),
        np.zeros((2, 2)),
        [50, 50],
    )
    assert not converged.any() and np.array_equal(x, np.zeros((2, 2)))
