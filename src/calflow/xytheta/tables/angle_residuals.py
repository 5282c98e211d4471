"""Angle lookup table from residuals: f_ax(Θ), f_ay(Θ) of Fig. 4.26 (Sec. 4.5.5).

AngleLUT — Eq. (4.18)/(4.19), Fig. 4.26
---------------------------------------
Residuals f = measured world point − target at angles Θ (run commanded through Model II
or III) are averaged per angle to f_ax(Θ), f_ay(Θ) (µm). With the linear part of Eq.
(4.18), M = [[cos α, −sin(α+β)], [sin α, cos(α+β)]], det M = cos β, a joint increment g
moves the tool point by M g; the increment that cancels f solves M g = −f::

    g = −M⁻¹ f = −(1/cos β) [[cos(α+β), sin(α+β)], [−sin α, cos α]] f

(the same matrix as Eq. 4.19). Models IV/V add g_ax(Θ), g_ay(Θ) to the joint inputs.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import xarray as xr

from calflow.data.runs import RunMetadata
from calflow.xytheta.evaluation import attained_points
from calflow.xytheta.tables.position import BOUNDS, _interpolator


def joint_increments(f_ax, f_ay, alpha: float, beta: float) -> tuple[np.ndarray, np.ndarray]:
    """Joint increments g_ax, g_ay (µm) cancelling world-frame errors f_ax, f_ay (µm).

    g = −M⁻¹ f with M = [[cos α, −sin(α+β)], [sin α, cos(α+β)]] the linear part of
    Eq. (4.18) (α, β in degrees); M⁻¹ = (1/cos β)[[cos(α+β), sin(α+β)], [−sin α, cos α]]
    as in Eq. (4.19). Then forward(X + g_ax, Y + g_ay, Θ) + f = forward(X, Y, Θ).
    """
    a, ab = np.radians(alpha), np.radians(alpha + beta)
    cb = np.cos(np.radians(beta))
    f_ax, f_ay = np.asarray(f_ax, dtype=float), np.asarray(f_ay, dtype=float)
    return -(np.cos(ab) * f_ax + np.sin(ab) * f_ay) / cb, -(-np.sin(a) * f_ax + np.cos(a) * f_ay) / cb


class AngleResiduals(NamedTuple):
    """Residuals of an angle-residual run: Θ_T (degree), f_ax, f_ay (µm), NaN readings skipped."""

    theta: np.ndarray
    f_ax: np.ndarray
    f_ay: np.ndarray
    nan_readings: int
    x_T: np.ndarray | None = None  # target positions (µm), for tables over position and angle
    y_T: np.ndarray | None = None


def angle_residuals_from_run(run: xr.Dataset) -> AngleResiduals:
    """f = measured world point (Eq. 4.27) − target, for each visit (pose > 0) of a Fig. 4.26 run."""
    x, y = attained_points(run)
    visit = run["pose"].values > 0
    ok = visit & np.isfinite(x) & np.isfinite(y)
    return AngleResiduals(
        run["target_theta"].values[ok].astype(float),
        x[ok] - run["target_x"].values[ok],
        y[ok] - run["target_y"].values[ok],
        int((visit & ~ok).sum()),
        run["target_x"].values[ok].astype(float),
        run["target_y"].values[ok].astype(float),
    )


@dataclass(frozen=True, eq=False)
class AngleLUT:
    """Angle-dependent errors f_ax(Θ), f_ay(Θ) (µm) on angles ``theta`` (degree), Fig. 4.26,
    with the geometry α, β (degree) that turns them into joint increments g (Eq. 4.19)."""

    theta: np.ndarray
    f_ax: np.ndarray
    f_ay: np.ndarray
    alpha: float
    beta: float
    bounds: str = "error"
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.bounds not in BOUNDS:
            raise ValueError(f"AngleLUT.bounds: expected one of {BOUNDS}, got {self.bounds!r}")

    @classmethod
    def from_residuals(
        cls,
        theta,
        f_ax,
        f_ay,
        alpha: float,
        beta: float,
        include_zero: bool = True,
        decimals: int = 6,
        bounds: str = "error",
    ) -> AngleLUT:
        """Tabulate residuals: mean over the targets at each angle (rounded to ``decimals``).

        NaN residuals are skipped. ``include_zero`` adds f(0) = 0 when 0° was not
        measured: the world frame is defined at Θ = 0 (Eq. 4.27), where f vanishes.
        """
        t = np.round(np.asarray(theta, dtype=float).ravel(), decimals)
        fx, fy = np.asarray(f_ax, dtype=float).ravel(), np.asarray(f_ay, dtype=float).ravel()
        ok = np.isfinite(t) & np.isfinite(fx) & np.isfinite(fy)
        angles, inv = np.unique(t[ok], return_inverse=True)
        count = np.bincount(inv)
        mx, my = np.bincount(inv, fx[ok]) / count, np.bincount(inv, fy[ok]) / count
        if include_zero and not np.any(angles == 0.0):
            angles, mx, my = np.insert(angles, 0, 0.0), np.insert(mx, 0, 0.0), np.insert(my, 0, 0.0)
            order = np.argsort(angles)
            angles, mx, my = angles[order], mx[order], my[order]
        if angles.size < 2:
            raise ValueError(f"AngleLUT: expected residuals at 2 or more angles, got {angles.size}")
        return cls(angles, mx, my, float(alpha), float(beta), bounds)

    def f(self, theta, method: str = "linear") -> tuple[np.ndarray, np.ndarray]:
        """f_ax(Θ), f_ay(Θ) (µm) interpolated in Θ (degree)."""
        out = []
        for name in ("f_ax", "f_ay"):
            key = (name, method)
            if key not in self._cache:
                self._cache[key] = _interpolator(
                    np.asarray(self.theta, float),
                    np.asarray(getattr(self, name), float),
                    method,
                    f"angle table {name}",
                    self.bounds,
                )
            out.append(self._cache[key](np.asarray(theta, dtype=float)))
        return out[0], out[1]

    def g(self, theta, method: str = "linear") -> tuple[np.ndarray, np.ndarray]:
        """Joint increments g_ax(Θ), g_ay(Θ) (µm) for Eq. (4.19): :func:`joint_increments` of f(Θ)."""
        return joint_increments(*self.f(theta, method), self.alpha, self.beta)

    def to_dataset(self, meta: RunMetadata | None = None) -> xr.Dataset:
        g_ax, g_ay = joint_increments(self.f_ax, self.f_ay, self.alpha, self.beta)

        def var(data, dims, units, long_name):
            return xr.Variable(
                dims, np.asarray(data, dtype=float), attrs={"units": units, "long_name": long_name}
            )

        t = ("theta",)
        return xr.Dataset(
            {
                "f_ax": var(self.f_ax, t, "um", "angle-dependent error along x_WF, f_ax (Eq. 4.18)"),
                "f_ay": var(self.f_ay, t, "um", "angle-dependent error along y_WF, f_ay (Eq. 4.18)"),
                "g_ax": var(g_ax, t, "um", "X joint increment cancelling f, g_ax (Eq. 4.19)"),
                "g_ay": var(g_ay, t, "um", "Y joint increment cancelling f, g_ay (Eq. 4.19)"),
                "alpha": var(self.alpha, (), "degree", "alpha used to compute g"),
                "beta": var(self.beta, (), "degree", "beta used to compute g"),
            },
            coords={"theta": var(self.theta, t, "degree", "rotation angle")},
            attrs=meta.attrs("luts") if meta is not None else {},
        )

    @classmethod
    def from_dataset(cls, ds: xr.Dataset, bounds: str = "error") -> AngleLUT:
        return cls(*angle_fields(ds), bounds)


def angle_fields(ds: xr.Dataset) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, float]:
    """(theta in degrees, f_ax, f_ay in µm, alpha, beta in degrees) of a stored angle table."""
    return (
        ds["theta"].values.astype(float),
        ds["f_ax"].values.astype(float),
        ds["f_ay"].values.astype(float),
        float(ds["alpha"]),
        float(ds["beta"]),
    )
