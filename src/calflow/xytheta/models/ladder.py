"""The XYΘ calibration models I–V (thesis Sec. 4.5.1, Table 4.4, Eq. 4.20–4.24).

A model is a set of identified parameters φ = {x_R, y_R, α, β} with, for Models III–V,
lookup tables — position-dependent errors ex, ey of the XY stages (Eq. 4.14, 4.15) and
angle-dependent errors f_ax, f_ay (Sec. 4.5.5) — and the forward and inverse kinematics
that use them. Which parameters are free and which tables apply is declared per model in
the campaign, so a user can compose other models. Models are netCDF files
(``calflow_kind = "model"``) carrying their tables as groups ``position_table`` and
``angle_table``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import xarray as xr

from calflow.data.io import group_names, open_dataset, write_dataset
from calflow.data.runs import RunMetadata
from calflow.xytheta.models import kinematics as kin
from calflow.xytheta.tables.angle import AngleTable
from calflow.xytheta.tables.angle_residuals import AngleLUT, joint_increments
from calflow.xytheta.tables.pose import PoseAngleLUT
from calflow.xytheta.tables.position import PositionLUT, infer_directions

_LONG = {
    "x_R": "x coordinate of the rotation centre in the world frame",
    "y_R": "y coordinate of the rotation centre in the world frame",
    "alpha": "alignment angle between x_WF and the X stage",
    "beta": "perpendicularity error between the X and Y stages",
}


def joint_directions(X, Y, start=(0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """Approach direction of each joint command of a sequence (Fig. 4.10)."""
    return infer_directions(X, start[0]), infer_directions(Y, start[1])


@dataclass
class MicroModel:
    """An identified XYΘ model."""

    name: str
    parameters: kin.Parameters
    free: tuple[str, ...]
    std: dict[str, float]
    correlation: np.ndarray
    diagnostics: dict = field(default_factory=dict)
    position: PositionLUT | None = None  # ex, ey (Models III, V)
    angle: AngleTable | AngleLUT | PoseAngleLUT | None = None  # f_ax, f_ay and g_ax, g_ay (Models IV, V)
    method: str = "linear"  # interpolation in the tables

    def position_errors(self, X, Y, dir_x, dir_y):
        """ex, ey (µm) at joints X, Y approached in dir_x, dir_y; zero without a position table."""
        if self.position is None:
            return np.zeros(np.shape(X)), np.zeros(np.shape(Y))
        return self.position.errors(X, Y, dir_x, dir_y, self.method, trends=False)

    def angle_errors(self, x, y, theta, dir_theta=None):
        """f_ax, f_ay (µm) at tool points x, y (µm) and angles Θ approached in ``dir_theta``
        (±1; None: both directions' mean); zero without an angle table."""
        if self.angle is None:
            return 0.0, 0.0
        if isinstance(self.angle, AngleTable):
            return self.angle.f(theta, dir_theta)
        if isinstance(self.angle, PoseAngleLUT):
            return self.angle.f(x, y, theta, self.method)
        return self.angle.f(theta, self.method)

    def forward(self, X, Y, theta, dir_x=1, dir_y=1):
        """Tool point (µm) from joints, Eq. (4.18) with this model's parameters and tables."""
        X, Y = np.asarray(X, dtype=float), np.asarray(Y, dtype=float)
        ex, ey = self.position_errors(X, Y, np.broadcast_to(dir_x, X.shape), np.broadcast_to(dir_y, Y.shape))
        x0, y0 = kin.forward(X, Y, theta, self.parameters, ex=ex, ey=ey)
        f_ax, f_ay = self.angle_errors(x0, y0, theta)
        return x0 + f_ax, y0 + f_ay

    def inverse(self, x_T, y_T, theta_T, start=(0.0, 0.0)):
        """Joint inputs (µm) for a sequence of task-space targets, Eq. (4.19) with g and ex, ey.

        g_ax, g_ay come from the angle table, for the approach direction of each Θ in
        the sequence (starting from Θ = 0); the position errors depend on the joint
        values themselves (X = X₀ + ex(X, Y)), solved by fixed-point iteration, with
        approach directions taken from the command sequence starting at ``start``.
        """
        dir_theta = infer_directions(theta_T) if np.ndim(theta_T) else None
        g_ax, g_ay = (
            joint_increments(
                *self.angle_errors(x_T, y_T, theta_T, dir_theta), self.angle.alpha, self.angle.beta
            )
            if self.angle is not None
            else (0.0, 0.0)
        )
        X0, Y0 = kin.inverse(x_T, y_T, theta_T, self.parameters, g_ax=g_ax, g_ay=g_ay)
        if self.position is None:
            return X0, Y0
        X, Y = np.asarray(X0, dtype=float), np.asarray(Y0, dtype=float)
        for _ in range(6):
            ex, ey = self.position_errors(X, Y, *joint_directions(X, Y, start))
            X, Y = X0 + ex, Y0 + ey
        return X, Y

    def to_dataset(self, meta: RunMetadata) -> xr.Dataset:
        data = {}
        for name in kin.PARAMETER_NAMES:
            data[name] = xr.Variable(
                (),
                getattr(self.parameters, name),
                attrs={
                    "units": kin.PARAMETER_UNITS[name],
                    "long_name": _LONG[name],
                    "free": int(name in self.free),
                    "std": self.std.get(name, float("nan")),  # fixed parameters are not estimated
                },
            )
        data["correlation"] = xr.Variable(
            ("parameter", "parameter_b"),
            np.asarray(self.correlation, dtype=float),
            attrs={"units": "1", "long_name": "correlation of the identified parameters"},
        )
        r_diag = self.diagnostics.get("r_diag")
        if r_diag is not None:
            data["r_diag"] = xr.Variable(
                ("parameter",),
                np.asarray(r_diag, dtype=float),
                attrs={"units": "1", "long_name": "diagonal of R in the QR decomposition of the Jacobian"},
            )
        coords = {
            "parameter": xr.Variable(
                ("parameter",), np.array(self.free, dtype=object), attrs={"long_name": "free parameter"}
            ),
            "parameter_b": xr.Variable(
                ("parameter_b",), np.array(self.free, dtype=object), attrs={"long_name": "free parameter"}
            ),
        }
        ds = xr.Dataset(data, coords=coords, attrs=meta.attrs("model"))
        for key, value in self.diagnostics.items():
            if key != "r_diag" and isinstance(value, (int, float, str, np.integer, np.floating)):
                ds.attrs[key] = value
        ds.attrs["model"] = self.name  # what the model is: never a diagnostic's to overwrite
        ds.attrs["position_table"] = int(self.position is not None)
        ds.attrs["angle_table"] = int(self.angle is not None)
        ds.attrs["interpolation"] = self.method
        return ds

    def groups(self) -> dict[str, xr.Dataset]:
        out = {}
        if self.position is not None:
            out["position_table"] = self.position.to_dataset()
        if self.angle is not None:
            out["angle_table"] = self.angle.to_dataset()
        return out

    def write(self, path, meta: RunMetadata) -> None:
        write_dataset(self.to_dataset(meta), path, groups=self.groups())

    @classmethod
    def read(cls, path) -> MicroModel:
        ds = open_dataset(path, kind="model")
        groups = group_names(path)
        position = (
            PositionLUT.from_dataset(open_dataset(path, group="position_table"))
            if "position_table" in groups
            else None
        )
        angle = None
        if "angle_table" in groups:
            table = open_dataset(path, group="angle_table")
            kind = {"position_angle": PoseAngleLUT, "angle_sweep": AngleTable}.get(
                table.attrs.get("table"), AngleLUT
            )
            angle = kind.from_dataset(table)
        return cls.from_dataset(ds, position, angle)

    @classmethod
    def from_dataset(cls, ds: xr.Dataset, position=None, angle=None) -> MicroModel:
        params = kin.Parameters(**{name: float(ds[name].values) for name in kin.PARAMETER_NAMES})
        free = tuple(str(v) for v in ds["parameter"].values)
        std = {name: float(ds[name].attrs.get("std", np.nan)) for name in kin.PARAMETER_NAMES}
        diagnostics = {
            k: v
            for k, v in ds.attrs.items()
            if k != "angle_table"
            and k.startswith(
                (
                    "O",
                    "residual",
                    "n_poses",
                    "dof",
                    "cv_",
                    "sigma_",
                    "angle_",
                    "uncertainty",
                    "rejected",
                    "robust",
                )
            )
        }
        return cls(
            str(ds.attrs["model"]),
            params,
            free,
            std,
            ds["correlation"].values,
            diagnostics,
            position,
            angle,
            str(ds.attrs.get("interpolation", "linear")),
        )
