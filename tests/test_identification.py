"""Identification of x_R, y_R, α, β with the pose-difference cost, Eq. (4.28)–(4.30)."""

import numpy as np
import pytest

from calflow.identification import diagnostics
from calflow.xytheta import cost
from calflow.xytheta.identification import identify
from calflow.xytheta.kinematics import Parameters, forward

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
        fd = (cost.residuals(Parameters.from_array(up), X, Y, theta, P_mx, P_my)
              - cost.residuals(Parameters.from_array(dn), X, Y, theta, P_mx, P_my)) / (2 * h)
        assert np.allclose(J[:, k], fd, rtol=1e-5, atol=1e-6)


def test_identifiability_names_a_parameter_that_cannot_be_identified():
    """With Θ fixed at 0, x_R and y_R do not act on the tool point: R_kk = 0."""
    X, Y, _ = _poses(50)
    theta = np.zeros_like(X)
    J = cost.jacobian(TRUE, X, Y, theta)
    r, bad = diagnostics.identifiability(J, ("x_R", "y_R", "alpha", "beta"))
    assert set(bad) >= {"x_R", "y_R"}
    _, none_bad = diagnostics.identifiability(cost.jacobian(TRUE, *_poses(50)), ("x_R", "y_R", "alpha", "beta"))
    assert none_bad == []


def test_observability_indices_follow_their_definitions():
    J = cost.jacobian(TRUE, *_poses(200))
    s = np.linalg.svd(J, compute_uv=False)
    o = diagnostics.observability(J)
    assert np.isclose(o["O1"], np.prod(s) ** (1 / 4) / 4)
    assert np.isclose(o["O2"], s[-1] / s[0])
    assert np.isclose(o["O3"], s[-1])
    assert np.isclose(o["O4"], s[-1] ** 2 / s[0])
