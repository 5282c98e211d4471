"""Pose convention, inverse and forward kinematics of the hexapod."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from calflow.errors import CalflowError
from calflow_hexapod.models import geometry as g
from calflow_hexapod.models import kinematics as k

GEOMETRY = g.h811()


def poses(fraction: float = 0.8):
    """Poses within ``fraction`` of the H-811 datasheet travel on every axis at once (µm, degree)."""
    return st.lists(st.floats(-1.0, 1.0), min_size=6, max_size=6).map(
        lambda u: np.asarray(u) * fraction * g.H811_TRAVEL
    )


pivots = st.lists(st.floats(-30_000.0, 30_000.0), min_size=3, max_size=3).map(np.asarray)


@settings(max_examples=60, deadline=None)
@given(poses(), pivots)
def test_forward_inverts_inverse_over_the_workspace(pose, pivot):
    geometry = GEOMETRY.with_pivot(pivot)
    found = k.forward(geometry, k.inverse(geometry, pose))
    np.testing.assert_allclose(found[:3], pose[:3], atol=1e-6)  # µm
    np.testing.assert_allclose(found[3:], pose[3:], atol=1e-9)  # degree


def test_forward_is_vectorised_and_keeps_the_shape():
    rng = np.random.default_rng(0)
    pose = rng.uniform(-0.5, 0.5, (4, 5, 6)) * g.H811_TRAVEL
    found = k.forward(GEOMETRY, k.inverse(GEOMETRY, pose))
    assert found.shape == pose.shape
    np.testing.assert_allclose(found, pose, atol=1e-6)


def test_rotations_are_right_handed_about_moving_axes_in_the_order_u_v_w():
    np.testing.assert_allclose(g.rotation(90.0, 0.0, 0.0) @ [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], atol=1e-15)
    np.testing.assert_allclose(g.rotation(0.0, 90.0, 0.0) @ [0.0, 0.0, 1.0], [1.0, 0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(g.rotation(0.0, 0.0, 90.0) @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-15)
    # U first, then V about the once-rotated y axis, then W about the twice-rotated z axis
    u, v, w = 30.0, -20.0, 50.0
    Ru = g.rotation(u, 0.0, 0.0)
    y1 = Ru @ [0.0, 1.0, 0.0]
    Rv = _about(y1, v) @ Ru
    z2 = Rv @ [0.0, 0.0, 1.0]
    np.testing.assert_allclose(_about(z2, w) @ Rv, g.rotation(u, v, w), atol=1e-14)


def _about(axis, angle_deg):
    """Rodrigues' rotation by ``angle_deg`` about the unit vector ``axis``."""
    a = np.asarray(axis) / np.linalg.norm(axis)
    K = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    t = np.radians(angle_deg)
    return np.eye(3) + np.sin(t) * K + (1.0 - np.cos(t)) * K @ K


@settings(max_examples=100, deadline=None)
@given(st.floats(-170.0, 170.0), st.floats(-85.0, 85.0), st.floats(-170.0, 170.0))
def test_angles_invert_rotation(u, v, w):
    np.testing.assert_allclose(g.angles(g.rotation(u, v, w)), [u, v, w], atol=1e-9)


@settings(max_examples=40, deadline=None)
@given(poses(), pivots)
def test_the_pivot_stays_put_under_rotation_and_translation_moves_every_joint(pose, pivot):
    geometry = GEOMETRY.with_pivot(pivot)
    R, t = g.transform(np.concatenate([[0.0, 0.0, 0.0], pose[3:]]), pivot)
    np.testing.assert_allclose(R @ pivot + t, pivot, atol=1e-8)
    shift = np.concatenate([pose[:3], [0.0, 0.0, 0.0]])
    expected = np.linalg.norm(geometry.platform + pose[:3] - geometry.base, axis=-1)
    np.testing.assert_allclose(k.inverse(geometry, shift), expected, rtol=1e-13)


def test_zero_pose_gives_the_joint_distances():
    np.testing.assert_allclose(k.inverse(GEOMETRY, np.zeros(6)), GEOMETRY.zero_lengths, rtol=1e-15)


@settings(max_examples=20, deadline=None)
@given(poses(0.6), pivots)
@example(  # a hypothesis find: rounding of legs of 0.1 m over a 1e-6° step was 1e-5 of a 0.52 entry
    pose=np.asarray([0.0, -0.1875, 0.0, 0.84375, 0.0, -0.71875]) * 0.6 * g.H811_TRAVEL,
    pivot=np.asarray([0.0, 4828.0, 22958.0]),
)
def test_jacobian_is_the_derivative_of_the_inverse_kinematics(pose, pivot):
    geometry = GEOMETRY.with_pivot(pivot)
    h = np.array([1e-2, 1e-2, 1e-2, 1e-6, 1e-6, 1e-6])
    numeric = np.stack(
        [
            (k.inverse(geometry, pose + h[j] * e) - k.inverse(geometry, pose - h[j] * e)) / (2 * h[j])
            for j, e in enumerate(np.eye(6))
        ],
        axis=-1,
    )
    # a central difference loses about eps·|L|/h to rounding: bound it per column (h of each axis)
    rounding = 4 * np.finfo(float).eps * np.abs(k.inverse(geometry, pose)).max() / h
    jacobian = k.jacobian(geometry, pose)
    for j in range(6):
        np.testing.assert_allclose(jacobian[:, j], numeric[:, j], rtol=1e-5, atol=max(1e-6, rounding[j]))


def test_unreachable_lengths_raise_one_clear_error():
    lengths = np.stack([GEOMETRY.zero_lengths, np.full(6, 1_000.0)])  # legs of 1 mm cannot close the loop
    with pytest.raises(k.ForwardKinematicsError) as err:
        k.forward(GEOMETRY, lengths)
    assert isinstance(err.value, CalflowError)
    message = str(err.value)
    assert "\n" not in message and "1 of 2 leg-length sets" in message


def test_too_few_iterations_is_reported_not_returned():
    far = k.inverse(GEOMETRY, 0.8 * g.H811_TRAVEL)
    with pytest.raises(k.ForwardKinematicsError, match="did not converge"):
        k.forward(GEOMETRY, far, max_iter=2)
    np.testing.assert_allclose(k.forward(GEOMETRY, far), 0.8 * g.H811_TRAVEL, atol=1e-6)
