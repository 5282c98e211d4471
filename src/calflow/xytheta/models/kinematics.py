"""Kinematics of the serial XYΘ micro-robot (thesis Sec. 4.5, Fig. 4.16).

Joint coordinates ``X``, ``Y`` in µm and ``theta`` (Θ) in degrees; tool point P (the
pattern origin) in the world frame WF in µm. Parameters φ = {x_R, y_R, α, β}: the
rotation centre (µm), the alignment angle α between x_WF and the X stage and the
perpendicularity error β between the X and Y stages (degrees).

All functions broadcast over numpy arrays.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

PARAMETER_NAMES = ("x_R", "y_R", "alpha", "beta")
PARAMETER_UNITS = {"x_R": "um", "y_R": "um", "alpha": "degree", "beta": "degree"}
NOMINAL = {"alpha": 180.0, "beta": 0.0}


@dataclass(frozen=True)
class Parameters:
    """Geometric parameters φ of Eq. (4.18): x_R, y_R in µm; alpha, beta in degrees."""

    x_R: float
    y_R: float
    alpha: float = 180.0
    beta: float = 0.0

    def as_array(self) -> np.ndarray:
        return np.array([self.x_R, self.y_R, self.alpha, self.beta], dtype=float)

    @classmethod
    def from_array(cls, values) -> Parameters:
        x_R, y_R, alpha, beta = (float(v) for v in values)
        return cls(x_R, y_R, alpha, beta)

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


def forward(X, Y, theta, p: Parameters, ex=0.0, ey=0.0, f_ax=0.0, f_ay=0.0):
    """Tool point (x_P, y_P) in µm from joints, Eq. (4.18).

    ``ex``, ``ey`` are position-dependent errors of the X and Y joints (µm) and
    ``f_ax``, ``f_ay`` the angle-dependent errors along x_WF, y_WF (µm).
    """
    a, ab, t = np.radians(p.alpha), np.radians(p.alpha + p.beta), np.radians(theta)
    Xe, Ye = np.asarray(X) - ex, np.asarray(Y) - ey
    x_P = Xe * np.cos(a) - Ye * np.sin(ab) + p.x_R + f_ax - p.x_R * np.cos(t) - p.y_R * np.sin(t)
    y_P = Xe * np.sin(a) + Ye * np.cos(ab) + p.y_R + f_ay + p.x_R * np.sin(t) - p.y_R * np.cos(t)
    return x_P, y_P


def inverse(x_P, y_P, theta, p: Parameters, g_ax=0.0, g_ay=0.0, ex=0.0, ey=0.0):
    """Joint inputs (X, Y) in µm that bring the tool point to (x_P, y_P), Eq. (4.19).

    Θ is a joint input itself (the commanded angle equals the target angle). ``g_ax``,
    ``g_ay`` are the joint increments that cancel the angle-dependent errors and
    ``ex``, ``ey`` the position-dependent errors (µm), both added to the joint inputs.
    """
    a, ab = np.radians(p.alpha), np.radians(p.alpha + p.beta)
    t = np.radians(theta)
    cb = np.cos(np.radians(p.beta))
    X = (
        (
            x_P * np.cos(ab)
            + y_P * np.sin(ab)
            - p.x_R * np.cos(ab)
            - p.y_R * np.sin(ab)
            + p.x_R * np.cos(t + ab)
            + p.y_R * np.sin(t + ab)
        )
        / cb
        + g_ax
        + ex
    )
    Y = (
        (
            -x_P * np.sin(a)
            + y_P * np.cos(a)
            + p.x_R * np.sin(a)
            - p.y_R * np.cos(a)
            - p.x_R * np.sin(t + a)
            + p.y_R * np.cos(t + a)
        )
        / cb
        + g_ay
        + ey
    )
    return X, Y


def forward_jacobian(X, Y, theta, p: Parameters, ex=0.0, ey=0.0):
    """∂(x_P, y_P)/∂(x_R, y_R, α, β) of Eq. (4.18), angles per degree.

    Returns two arrays of shape (..., 4): the rows for x_P and for y_P.
    """
    a, ab, t = np.radians(p.alpha), np.radians(p.alpha + p.beta), np.radians(theta)
    Xe, Ye = np.asarray(X, dtype=float) - ex, np.asarray(Y, dtype=float) - ey
    d = np.pi / 180.0
    one = np.ones_like(Xe + t)
    jx = np.stack(
        [
            one - np.cos(t),
            -np.sin(t) * one,
            (-Xe * np.sin(a) - Ye * np.cos(ab)) * d,
            (-Ye * np.cos(ab)) * d,
        ],
        axis=-1,
    )
    jy = np.stack(
        [
            np.sin(t) * one,
            one - np.cos(t),
            (Xe * np.cos(a) - Ye * np.sin(ab)) * d,
            (-Ye * np.sin(ab)) * d,
        ],
        axis=-1,
    )
    return jx, jy


def world_from_pattern(x_m, y_m, theta, x_m0, y_m0):
    """Tool point P in the world frame from a vision reading, Eq. (4.27).

    ``x_m``, ``y_m`` (µm) locate the camera point M in the pattern frame; ``theta`` is
    the pattern rotation since the initial pose (degrees); ``x_m0``, ``y_m0`` are the
    initial reading (µm).
    """
    t = np.radians(theta)
    x_P = x_m0 - x_m * np.cos(t) - y_m * np.sin(t)
    y_P = y_m0 + x_m * np.sin(t) - y_m * np.cos(t)
    return x_P, y_P


def pattern_from_world(x_P, y_P, theta, x_M, y_M):
    """The vision reading of the fixed camera point M = (x_M, y_M), Eq. (4.26) solved.

    Eq. (4.26) reads D^WF = T D^PF with T = [[cos Θ, sin Θ], [-sin Θ, cos Θ]]; T is a
    rotation, so D^PF = Tᵀ D^WF.
    """
    t = np.radians(theta)
    dx, dy = x_M - np.asarray(x_P), y_M - np.asarray(y_P)
    x_m = dx * np.cos(t) - dy * np.sin(t)
    y_m = dx * np.sin(t) + dy * np.cos(t)
    return x_m, y_m
