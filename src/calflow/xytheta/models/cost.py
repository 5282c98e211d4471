"""Pose-difference cost of the XYΘ identification, Eq. (4.28)–(4.30)."""

from __future__ import annotations

import numpy as np

from calflow.xytheta.models.kinematics import Parameters, forward, forward_jacobian, world_from_pattern


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


def reading_residuals(
    p: Parameters, X, Y, theta, P_mx, P_my, offset=(0.0, 0.0), ex=0.0, ey=0.0, f_ax=0.0, f_ay=0.0
) -> np.ndarray:
    """Eq. (4.28) per reading with the initial reading (x_m0, y_m0) = ``offset`` as an unknown, µm.

    [ε_x,1, ε_y,1, ε_x,2, ...], 2n elements: the calculated minus the measured tool point
    minus the offset. Estimating the offset beside φ (a nuisance parameter) instead of
    differencing it away, Eq. (4.29), leaves the residuals independent when the readings
    are: least squares on them is the generalised least squares of the differences, whose
    covariance σ² D Dᵀ is banded (the projection orthogonal to a constant offset per axis
    is what (D Dᵀ)⁻¹ weighting does), at linear cost.
    """
    x_c, y_c = forward(X, Y, theta, p, ex=ex, ey=ey, f_ax=f_ax, f_ay=f_ay)
    return np.column_stack(
        [np.asarray(x_c - P_mx, dtype=float) - offset[0], np.asarray(y_c - P_my, dtype=float) - offset[1]]
    ).ravel()


def reading_jacobian(p: Parameters, X, Y, theta, ex=0.0, ey=0.0) -> np.ndarray:
    """∂ε/∂(φ, x_m0, y_m0) of :func:`reading_residuals`, shape (2n, 6); φ as in :func:`jacobian`."""
    jx, jy = forward_jacobian(X, Y, theta, p, ex=ex, ey=ey)
    n = jx.shape[0]
    out = np.zeros((n, 2, 6))
    out[:, 0, :4], out[:, 1, :4] = jx, jy
    out[:, 0, 4] = out[:, 1, 5] = -1.0
    return out.reshape(-1, 6)


def differences_of_readings(r: np.ndarray) -> np.ndarray:
    """ε of Eq. (4.30) from the per-reading residuals of :func:`reading_residuals` (the offset
    cancels); of the rows of their Jacobian (2n × k) too, giving the pose differences' (2(n−1) × k)."""
    r = np.asarray(r)
    return _difference(r.reshape(-1, 2, *r.shape[1:])).reshape(-1, *r.shape[1:])


#: The constant entries of :meth:`Readings._derivatives`: x_R, y_R and the offset enter linearly.
_DERIVATIVES = np.zeros((2, 7, 6))
_DERIVATIVES[0, 2, 0], _DERIVATIVES[0, 3, 1], _DERIVATIVES[0, 4, 4] = 1.0, -1.0, -1.0
_DERIVATIVES[1, 2, 1], _DERIVATIVES[1, 3, 0], _DERIVATIVES[1, 4, 5] = 1.0, 1.0, -1.0


class Readings:
    """The per-reading residuals of Eq. (4.28) as the linear map they are, for fast fitting.

    With u = 1 − cos Θ, s = sin Θ and the joints corrected by ex, ey, each reading's
    residual (:func:`reading_residuals`) is a fixed row of data times a coefficient
    vector that alone depends on φ and the offset:

        ε_x = [Xe, Ye, u, s, 1, f_ax − P_mx, f_ay − P_my] · [cos α, −sin(α+β), x_R, −y_R, −x_m0, 1, 0]
        ε_y = [Xe, Ye, u, s, 1, f_ax − P_mx, f_ay − P_my] · [sin α, cos(α+β), y_R, x_R, −y_m0, 0, 1]

    so the trigonometry of Θ is done once, and the normal equations of Gauss–Newton
    (Jᵀ W J, Jᵀ W ε) are 7 × 7 products with the data's Gram matrix: O(1) per iteration
    for least squares once DᵀD is formed (O(n), once), O(n) for a weighted (robust) one.
    ``phi`` below is (x_R µm, y_R µm, α degree, β degree, x_m0 µm, y_m0 µm). Same values
    as :func:`reading_residuals` and :func:`reading_jacobian`, up to rounding.
    """

    def __init__(self, X, Y, theta, P_mx, P_my, ex=0.0, ey=0.0, f_ax=0.0, f_ay=0.0, _columns=None):
        if _columns is not None:
            self.columns = _columns
        else:
            X = np.asarray(X, dtype=float)
            t = np.radians(np.asarray(theta, dtype=float))
            self.columns = np.empty((7, X.size))  # the data rows above as columns, contiguous per column
            for j, column in enumerate(
                (
                    X - ex,
                    np.asarray(Y, dtype=float) - ey,
                    1.0 - np.cos(t),
                    np.sin(t),
                    1.0,
                    f_ax - np.asarray(P_mx, dtype=float),
                    f_ay - np.asarray(P_my, dtype=float),
                )
            ):
                self.columns[j] = column
        self._gram = None

    def subset(self, rows) -> Readings:
        """The readings at ``rows`` (index or boolean mask)."""
        return Readings(None, None, None, None, None, _columns=self.columns[:, rows])

    @property
    def gram(self) -> np.ndarray:
        """DᵀD, 7 × 7."""
        if self._gram is None:
            self._gram = self.columns @ self.columns.T
        return self._gram

    @staticmethod
    def _coefficients(phi) -> np.ndarray:
        """Coefficients (7, 2) of ε_x, ε_y at ``phi``."""
        x_R, y_R, alpha, beta, x0, y0 = phi
        a, ab = np.radians(alpha), np.radians(alpha + beta)
        return np.array(
            [
                [np.cos(a), np.sin(a)],
                [-np.sin(ab), np.cos(ab)],
                [x_R, y_R],
                [-y_R, x_R],
                [-x0, -y0],
                [1.0, 0.0],
                [0.0, 1.0],
            ]
        )

    @staticmethod
    def _derivatives(phi) -> np.ndarray:
        """∂ of the coefficients of ε_x, ε_y by ``phi``, (2, 7, 6)."""
        a, ab, d = np.radians(phi[2]), np.radians(phi[2] + phi[3]), np.pi / 180.0
        ca, sa, cab, sab = np.cos(a), np.sin(a), np.cos(ab), np.sin(ab)
        E = _DERIVATIVES.copy()
        E[0, 0, 2], E[0, 1, 2], E[0, 1, 3] = -sa * d, -cab * d, -cab * d
        E[1, 0, 2], E[1, 1, 2], E[1, 1, 3] = ca * d, -sab * d, -sab * d
        return E

    def residuals(self, phi) -> np.ndarray:
        """[ε_x,1, ε_y,1, ε_x,2, ...] (µm), as :func:`reading_residuals`."""
        out = np.empty((self.columns.shape[1], 2))
        out.T[...] = self._coefficients(phi).T @ self.columns  # (n × 7) @ (7 × 2) in numpy is slow at large n
        return out.ravel()

    def jacobian(self, phi) -> np.ndarray:
        """∂ε/∂phi, shape (2n, 6), as :func:`reading_jacobian`."""
        E = self._derivatives(phi)
        out = np.empty((self.columns.shape[1], 2, 6))
        for k in range(2):
            out[:, k, :].T[...] = E[k].T @ self.columns
        return out.reshape(-1, 6)

    def normal(self, phi, r, w=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(Jᵀ W J, Jᵀ W ε, Jᵀ J) at ``phi`` for residuals ``r`` and per-residual weights
        ``w`` (None: all one) without forming J."""
        E = self._derivatives(phi)
        R = np.asarray(r).reshape(-1, 2)
        G = self.gram
        plain = E[0].T @ G @ E[0] + E[1].T @ G @ E[1]
        if w is not None:
            W = np.asarray(w).reshape(-1, 2)
            N = sum(E[k].T @ ((self.columns * W[:, k]) @ self.columns.T) @ E[k] for k in range(2))
            R = W * R
        else:
            N = plain
        DR = self.columns @ R  # Dᵀ W ε per axis, (7, 2)
        return N, E[0].T @ DR[:, 0] + E[1].T @ DR[:, 1], plain
