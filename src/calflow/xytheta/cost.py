"""Pose-difference cost of the XYΘ identification, Eq. (4.28)–(4.30)."""

from __future__ import annotations

import numpy as np

from calflow.xytheta.kinematics import Parameters, forward, forward_jacobian, world_from_pattern


def measured_points(meas_x, meas_y, theta):
    """Measured tool points up to the unknown offset (x_m0, y_m0), Eq. (4.27) with x_m0 = y_m0 = 0.

    The offset cancels in the pose differences of Eq. (4.29).
    """
    return world_from_pattern(np.asarray(meas_x), np.asarray(meas_y), theta, 0.0, 0.0)


def _difference(a: np.ndarray) -> np.ndarray:
    """Consecutive differences a_i − a_{i+1} along the first axis, Eq. (4.29)."""
    return a[:-1] - a[1:]


def residuals(p: Parameters, X, Y, theta, P_mx, P_my, ex=0.0, ey=0.0, f_ax=0.0, f_ay=0.0) -> np.ndarray:
    """The vector ε of Eq. (4.30): [ε_x(1,2), ε_y(1,2), ε_x(2,3), ...], 2(n−1) elements (µm).

    ε_x,i = x_P,i(φ) − x_m0 + x_m,i cos Θ_i + y_m,i sin Θ_i (Eq. 4.28): the calculated
    minus the measured tool point; ``P_mx``, ``P_my`` are the measured points of
    :func:`measured_points`.
    """
    x_c, y_c = forward(X, Y, theta, p, ex=ex, ey=ey, f_ax=f_ax, f_ay=f_ay)
    eps_x = _difference(np.asarray(x_c - P_mx, dtype=float))
    eps_y = _difference(np.asarray(y_c - P_my, dtype=float))
    return np.column_stack([eps_x, eps_y]).ravel()


def jacobian(p: Parameters, X, Y, theta, ex=0.0, ey=0.0) -> np.ndarray:
    """∂ε/∂φ, shape (2(n−1), 4), φ = (x_R µm, y_R µm, α degree, β degree); analytic."""
    jx, jy = forward_jacobian(X, Y, theta, p, ex=ex, ey=ey)
    dx, dy = _difference(jx), _difference(jy)
    return np.stack([dx, dy], axis=1).reshape(-1, 4)


def reading_residuals(p: Parameters, X, Y, theta, P_mx, P_my, offset=(0.0, 0.0), ex=0.0, ey=0.0,
                      f_ax=0.0, f_ay=0.0) -> np.ndarray:
    """Eq. (4.28) per reading with the initial reading (x_m0, y_m0) = ``offset`` as an unknown, µm.

    [ε_x,1, ε_y,1, ε_x,2, ...], 2n elements: the calculated minus the measured tool point
    minus the offset. Estimating the offset beside φ (a nuisance parameter) instead of
    differencing it away, Eq. (4.29), leaves the residuals independent when the readings
    are: least squares on them is the generalised least squares of the differences, whose
    covariance σ² D Dᵀ is banded (the projection orthogonal to a constant offset per axis
    is what (D Dᵀ)⁻¹ weighting does), at linear cost.
    """
    x_c, y_c = forward(X, Y, theta, p, ex=ex, ey=ey, f_ax=f_ax, f_ay=f_ay)
    return np.column_stack([np.asarray(x_c - P_mx, dtype=float) - offset[0],
                            np.asarray(y_c - P_my, dtype=float) - offset[1]]).ravel()


def reading_jacobian(p: Parameters, X, Y, theta, ex=0.0, ey=0.0) -> np.ndarray:
    """∂ε/∂(φ, x_m0, y_m0) of :func:`reading_residuals`, shape (2n, 6); φ as in :func:`jacobian`."""
    jx, jy = forward_jacobian(X, Y, theta, p, ex=ex, ey=ey)
    n = jx.shape[0]
    out = np.zeros((n, 2, 6))
    out[:, 0, :4], out[:, 1, :4] = jx, jy
    out[:, 0, 4] = out[:, 1, 5] = -1.0
    return out.reshape(-1, 6)


def differences_of_readings(r: np.ndarray) -> np.ndarray:
    """ε of Eq. (4.30) from the per-reading residuals of :func:`reading_residuals` (the offset cancels)."""
    return _difference(np.asarray(r).reshape(-1, 2)).ravel()
