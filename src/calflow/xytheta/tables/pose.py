"""Angle-dependent error tables over target position and angle (thesis Sec. 4.5.5, Fig. 4.26).

The angle-residual run visits each of M target positions at K angles. :class:`AngleLUT`
averages the residuals over the positions, giving f_ax(Θ), f_ay(Θ); this table keeps
them per position, so it also holds the part of the position-dependent errors seen at
those poses — which is how "the quantified angle-dependent errors include a part of
position-dependent errors" and Models IV and V end up close (Table 4.8).

At a query (x, y, Θ): f is interpolated in Θ at every table position (with f = 0 at
Θ = 0, where the world frame is defined, Eq. 4.27), then the positions are combined by
inverse-distance weighting (power 2), which is exact at the table positions. g follows
from f through the inverse kinematics as in :func:`calflow.xytheta.tables.position.joint_increments`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import xarray as xr

from calflow.data.runs import RunMetadata
from calflow.xytheta.tables.angle_residuals import joint_increments


@dataclass
class PoseAngleLUT:
    """f_ax, f_ay (µm) of shape (positions, angles) at ``x``, ``y`` (µm) and ``theta`` (degree)."""

    x: np.ndarray
    y: np.ndarray
    theta: np.ndarray
    f_ax: np.ndarray
    f_ay: np.ndarray
    alpha: float
    beta: float

    @classmethod
    def from_residuals(
        cls, x_T, y_T, theta, f_ax, f_ay, alpha: float, beta: float, decimals: int = 6
    ) -> PoseAngleLUT:
        """Tabulate residuals: mean over the visits of each (position, angle); NaN skipped."""
        x_T, y_T, t = (np.round(np.asarray(a, dtype=float).ravel(), decimals) for a in (x_T, y_T, theta))
        fx, fy = np.asarray(f_ax, dtype=float).ravel(), np.asarray(f_ay, dtype=float).ravel()
        ok = np.isfinite(fx) & np.isfinite(fy)
        positions = np.unique(np.column_stack([x_T, y_T]), axis=0)
        angles = np.unique(t)
        angles = angles[angles != 0.0]
        table_x = np.full((len(positions), len(angles) + 1), np.nan)
        table_y = np.full_like(table_x, np.nan)
        table_x[:, 0] = table_y[:, 0] = 0.0
        for i, (px, py) in enumerate(positions):
            for j, a in enumerate(angles):
                sel = ok & (x_T == px) & (y_T == py) & (t == a)
                if sel.any():
                    table_x[i, j + 1], table_y[i, j + 1] = fx[sel].mean(), fy[sel].mean()
        if np.isnan(table_x).any():
            raise ValueError(
                "position-angle table: some (position, angle) has no valid residual; "
                "the angle-residual run must visit every position at every angle"
            )
        return cls(
            positions[:, 0],
            positions[:, 1],
            np.concatenate([[0.0], angles]),
            table_x,
            table_y,
            float(alpha),
            float(beta),
        )

    def f(self, x, y, theta, method: str = "linear") -> tuple[np.ndarray, np.ndarray]:
        """f_ax, f_ay (µm) at target positions x, y (µm) and angles Θ (degree)."""
        x, y, theta = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (x, y, theta)))
        if np.any(theta < self.theta[0]) or np.any(theta > self.theta[-1]):
            raise ValueError(
                f"position-angle table: angle outside the table [{self.theta[0]}, {self.theta[-1]}] degree"
            )
        fx = np.stack([np.interp(theta, self.theta, row) for row in self.f_ax], axis=-1)
        fy = np.stack([np.interp(theta, self.theta, row) for row in self.f_ay], axis=-1)
        d2 = (x[..., None] - self.x) ** 2 + (y[..., None] - self.y) ** 2
        exact = d2 < 1e-12
        w = np.where(exact.any(axis=-1, keepdims=True), exact.astype(float), 1.0 / np.maximum(d2, 1e-12))
        w = w / w.sum(axis=-1, keepdims=True)
        return (w * fx).sum(axis=-1), (w * fy).sum(axis=-1)

    def g(self, x, y, theta, method: str = "linear") -> tuple[np.ndarray, np.ndarray]:
        """Joint increments g_ax, g_ay (µm) cancelling f at the targets (Eq. 4.19)."""
        return joint_increments(*self.f(x, y, theta, method), self.alpha, self.beta)

    def to_dataset(self, meta: RunMetadata | None = None) -> xr.Dataset:
        def var(data, dims, units, long_name):
            return xr.Variable(
                dims, np.asarray(data, dtype=float), attrs={"units": units, "long_name": long_name}
            )

        d = ("position", "theta")
        ds = xr.Dataset(
            {
                "f_ax": var(self.f_ax, d, "um", "angle-dependent error along x_WF at each target position"),
                "f_ay": var(self.f_ay, d, "um", "angle-dependent error along y_WF at each target position"),
                "position_x": var(self.x, ("position",), "um", "target position x in the world frame"),
                "position_y": var(self.y, ("position",), "um", "target position y in the world frame"),
                "alpha": var(self.alpha, (), "degree", "alpha used to compute g"),
                "beta": var(self.beta, (), "degree", "beta used to compute g"),
            },
            coords={"theta": var(self.theta, ("theta",), "degree", "rotation angle")},
            attrs=meta.attrs("luts") if meta is not None else {},
        )
        ds.attrs["table"] = "position_angle"
        return ds

    @classmethod
    def from_dataset(cls, ds: xr.Dataset) -> PoseAngleLUT:
        return cls(
            ds["position_x"].values.astype(float),
            ds["position_y"].values.astype(float),
            ds["theta"].values.astype(float),
            ds["f_ax"].values.astype(float),
            ds["f_ay"].values.astype(float),
            float(ds["alpha"]),
            float(ds["beta"]),
        )
