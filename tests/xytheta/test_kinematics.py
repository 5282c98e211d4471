"""Eq. (4.18), (4.19), (4.26), (4.27): forward, inverse and the vision transform."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from calflow.xytheta.models.kinematics import (
    Parameters,
    forward,
    forward_jacobian,
    inverse,
    pattern_from_world,
    world_from_pattern,
)

params = st.builds(
    Parameters,
    x_R=st.floats(-20000, 20000),
    y_R=st.floats(-20000, 20000),
    alpha=st.floats(170, 190),
    beta=st.floats(-2, 2),
)
joint = st.tuples(st.floats(-5000, 15000), st.floats(-5000, 15000), st.floats(-30, 30))


@settings(max_examples=200)
@given(params, joint)
def test_inverse_of_forward_is_identity(p, q):
    X, Y, theta = q
    x_P, y_P = forward(X, Y, theta, p)
    X2, Y2 = inverse(x_P, y_P, theta, p)
    assert np.allclose([X2, Y2], [X, Y], atol=1e-7, rtol=1e-10)


@settings(max_examples=200)
@given(params, st.floats(-5000, 5000), st.floats(-5000, 5000), st.floats(-30, 30))
def test_forward_of_inverse_is_identity(p, x_P, y_P, theta):
    X, Y = inverse(x_P, y_P, theta, p)
    assert np.allclose(forward(X, Y, theta, p), [x_P, y_P], atol=1e-7, rtol=1e-10)


@given(
    st.floats(-5000, 5000), st.floats(-5000, 5000), st.floats(-30, 30), st.floats(0, 9000), st.floats(0, 4000)
)
def test_vision_transform_round_trip(x_P, y_P, theta, x_M, y_M):
    """Eq. (4.27) recovers the tool point from the Eq. (4.26) reading of camera point M."""
    x_m, y_m = pattern_from_world(x_P, y_P, theta, x_M, y_M)
    x_m0, y_m0 = pattern_from_world(0.0, 0.0, 0.0, x_M, y_M)
    assert np.allclose(world_from_pattern(x_m, y_m, theta, x_m0, y_m0), [x_P, y_P], atol=1e-7)


def test_home_pose_is_world_origin():
    p = Parameters(9572.9, 7795.9, 177.7, -0.11)
    assert np.allclose(forward(0.0, 0.0, 0.0, p), [0.0, 0.0], atol=1e-9)
    assert np.allclose(inverse(0.0, 0.0, 0.0, p), [0.0, 0.0], atol=1e-9)


def test_nominal_model_moves_tool_against_x_stage():
    """α = 180°: a +X stage move takes the tool point to −x in the world frame (Table 4.7 targets are negative)."""
    p = Parameters(9572.9, 7795.9)
    x_P, y_P = forward(1000.0, 0.0, 0.0, p)
    assert np.isclose(x_P, -1000.0) and np.isclose(y_P, 0.0, atol=1e-9)


@settings(max_examples=100)
@given(params, joint)
def test_analytic_jacobian_matches_finite_differences(p, q):
    X, Y, theta = q
    jx, jy = forward_jacobian(X, Y, theta, p)
    phi = p.as_array()
    for k in range(4):
        h = 1e-4 if k < 2 else 1e-6
        up, dn = phi.copy(), phi.copy()
        up[k] += h
        dn[k] -= h
        fx_up, fy_up = forward(X, Y, theta, Parameters.from_array(up))
        fx_dn, fy_dn = forward(X, Y, theta, Parameters.from_array(dn))
        assert np.isclose(jx[k], (fx_up - fx_dn) / (2 * h), rtol=1e-5, atol=1e-5)
        assert np.isclose(jy[k], (fy_up - fy_dn) / (2 * h), rtol=1e-5, atol=1e-5)
