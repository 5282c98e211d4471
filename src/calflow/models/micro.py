"""The XYΘ calibration models I–V (thesis Sec. 4.5.1, Table 4.4, Eq. 4.20–4.24).

A model is a set of identified parameters φ = {x_R, y_R, α, β} (and, for Models III–V,
lookup tables) with the forward and inverse kinematics that use them. Models are
stored as netCDF (``calflow_kind = "model"``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import xarray as xr

from calflow.data.runs import RunMetadata
from calflow.kinematics import xytheta as kin

_LONG = {
    "x_R": "x coordinate of the rotation centre in the world frame",
    "y_R": "y coordinate of the rotation centre in the world frame",
    "alpha": "alignment angle between x_WF and the X stage",
    "beta": "perpendicularity error between the X and Y stages",
}


@dataclass
class MicroModel:
    """An identified XYΘ model."""

    name: str
    parameters: kin.Parameters
    free: tuple[str, ...]
    std: dict[str, float]
    correlation: np.ndarray
    diagnostics: dict = field(default_factory=dict)

    def forward(self, X, Y, theta):
        """Tool point (µm) from joints, Eq. (4.18) with this model's parameters."""
        return kin.forward(X, Y, theta, self.parameters)

    def inverse(self, x_T, y_T, theta_T):
        """Joint inputs (µm) for a task-space target, Eq. (4.19)."""
        return kin.inverse(x_T, y_T, theta_T, self.parameters)

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
            ("parameter", "parameter_b"), np.asarray(self.correlation, dtype=float),
            attrs={"units": "1", "long_name": "correlation of the identified parameters"},
        )
        r_diag = self.diagnostics.get("r_diag")
        if r_diag is not None:
            data["r_diag"] = xr.Variable(
                ("parameter",), np.asarray(r_diag, dtype=float),
                attrs={"units": "1", "long_name": "diagonal of R in the QR decomposition of the Jacobian"},
            )
        coords = {
            "parameter": xr.Variable(("parameter",), np.array(self.free, dtype=object), attrs={"long_name": "free parameter"}),
            "parameter_b": xr.Variable(("parameter_b",), np.array(self.free, dtype=object), attrs={"long_name": "free parameter"}),
        }
        ds = xr.Dataset(data, coords=coords, attrs=meta.attrs("model"))
        ds.attrs["model"] = self.name
        for key, value in self.diagnostics.items():
            if key != "r_diag" and isinstance(value, (int, float, str)):
                ds.attrs[key] = value
        return ds

    @classmethod
    def from_dataset(cls, ds: xr.Dataset) -> "MicroModel":
        params = kin.Parameters(**{name: float(ds[name].values) for name in kin.PARAMETER_NAMES})
        free = tuple(str(v) for v in ds["parameter"].values)
        std = {name: float(ds[name].attrs.get("std", np.nan)) for name in kin.PARAMETER_NAMES}
        diagnostics = {k: v for k, v in ds.attrs.items() if k.startswith(("O", "residual", "n_poses", "dof"))}
        return cls(str(ds.attrs["model"]), params, free, std, ds["correlation"].values, diagnostics)
