"""An identified hexapod model: what it predicts, how it compensates, and its netCDF file.

:func:`predict` runs a commanded pose through the model the way the hexapod runs it: the
controller's inverse kinematics through its nominal geometry gives leg lengths λ, the model's
legs have the lengths l(λ) of :class:`calflow_hexapod.models.ladder.Parameters`, the platform goes
where the identified joints put it (forward kinematics) and the instrument sees the target
through the measurement and tool frames, M = F⁻¹ P G. :func:`command` inverts it in closed
form and one forward solve: for a wanted reading M, P = F M G⁻¹, l = the identified inverse
kinematics of P, λ = l⁻¹(l), and the pose to command is the controller's forward kinematics
of λ — the compensation a calibrated C-887 setup needs. Lengths µm, angles degree.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import xarray as xr

from calflow.data.io import open_dataset, write_dataset
from calflow.data.runs import RunMetadata
from calflow_hexapod.models import kinematics
from calflow_hexapod.models.geometry import Geometry, compose, invert, pose_of, transform
from calflow_hexapod.models.ladder import NAMES, Parameters, long_name, unit


def _frames(phi: Parameters):
    return transform(phi.frame), transform(phi.tool)


def reading(phi: Parameters, controller: Geometry, lengths, start) -> np.ndarray:
    """The instrument's reading M = F⁻¹ P G (n, 6) when the legs have ``lengths`` (n, 6) µm:
    P from the forward kinematics of the model's joints, started at ``start`` (n, 6)."""
    pose = kinematics.forward(phi.geometry(controller.pivot), lengths, start=start)
    (RF, tF), (RG, tG) = _frames(phi)
    R, t = compose(*compose(*invert(RF, tF), *transform(pose, controller.pivot)), RG, tG)
    return pose_of(R, t)


def predict(phi: Parameters, controller: Geometry, commands, temperature=None) -> np.ndarray:
    """Readings M (n, 6) the model predicts for commanded poses (n, 6) about the controller's pivot."""
    commands = np.asarray(commands, dtype=float)
    lam = kinematics.inverse(controller, commands)
    return reading(phi, controller, phi.leg_lengths(lam, controller.zero_lengths, temperature), commands)


def command(phi: Parameters, controller: Geometry, targets, temperature=None) -> np.ndarray:
    """Poses (n, 6) to command so that the model's reading is ``targets`` (n, 6): the inverse of
    :func:`predict`. Raises :class:`calflow_hexapod.models.kinematics.ForwardKinematicsError` for a
    target the controller's geometry cannot reach."""
    targets = np.asarray(targets, dtype=float)
    (RF, tF), (RG, tG) = _frames(phi)
    R, t = compose(*compose(RF, tF, *transform(targets)), *invert(RG, tG))  # P = F M G⁻¹
    x = np.einsum("...ab,ib->...ia", R, phi.platform) + t[..., None, :]
    lengths = np.linalg.norm(x - phi.base, axis=-1)
    lam = phi.commanded_lengths(lengths, controller.zero_lengths, temperature)
    start = pose_of(R, t, controller.pivot)
    return kinematics.forward(controller, lam, start=start)


@dataclass
class HexapodModel:
    """An identified model of the ladder: its parameters (every one of :data:`NAMES`, the fixed
    ones at their starting value), which were free, their σ and correlation, the controller's
    nominal geometry it was identified against, and the fit's diagnostics."""

    name: str
    parameters: Parameters
    controller: Geometry
    free: tuple[str, ...]
    std: dict[str, float]
    correlation: np.ndarray
    diagnostics: dict = field(default_factory=dict)

    @classmethod
    def from_identification(cls, name: str, fit, controller: Geometry) -> HexapodModel:
        """From :class:`calflow_hexapod.models.identification.Identification`."""
        diagnostics = {
            "chi2_dof": fit.chi2_dof,
            "residual_rms_um": fit.residual_rms_um,
            "n_poses": fit.n_poses,
            "dof": fit.dof,
            "dropped": ",".join(fit.dropped),
            "rejected": len(fit.rejected),
            "robust": fit.loss,
        }
        return cls(name, fit.parameters, controller, fit.free, dict(fit.std), fit.correlation, diagnostics)

    def predict(self, commands, temperature=None) -> np.ndarray:
        return predict(self.parameters, self.controller, commands, temperature)

    def command(self, targets, temperature=None) -> np.ndarray:
        return command(self.parameters, self.controller, targets, temperature)

    def to_dataset(self, meta: RunMetadata) -> xr.Dataset:
        data = {}
        for name, value in zip(NAMES, self.parameters.vector()):
            data[name] = xr.Variable(
                (),
                float(value),
                attrs={
                    "units": unit(name),
                    "long_name": long_name(name),
                    "free": int(name in self.free),
                    "std": self.std.get(name, float("nan")),
                },
            )
        data["correlation"] = xr.Variable(
            ("parameter", "parameter_b"),
            np.asarray(self.correlation, dtype=float),
            attrs={"units": "1", "long_name": "correlation of the identified parameters"},
        )
        for part in ("base", "platform"):
            data[f"controller_{part}"] = xr.Variable(
                ("leg", "xyz"),
                getattr(self.controller, part),
                attrs={"units": "um", "long_name": f"{part} joints of the controller's nominal geometry"},
            )
        data["controller_pivot"] = xr.Variable(
            ("xyz",), self.controller.pivot, attrs={"units": "um", "long_name": "pivot point (SPI R S T)"}
        )
        free = np.array(self.free, dtype=object)
        coords = {
            "parameter": xr.Variable(("parameter",), free, attrs={"long_name": "free parameter"}),
            "parameter_b": xr.Variable(("parameter_b",), free, attrs={"long_name": "free parameter"}),
            "leg": xr.Variable(("leg",), np.arange(1, 7), attrs={"long_name": "leg number"}),
            "xyz": xr.Variable(
                ("xyz",), np.array(["x", "y", "z"], dtype=object), attrs={"long_name": "axis"}
            ),
        }
        ds = xr.Dataset(data, coords=coords, attrs=meta.attrs("model"))
        for key, value in self.diagnostics.items():
            if isinstance(value, (int, float, str, np.integer, np.floating)):
                ds.attrs[key] = value
        ds.attrs["model"] = self.name
        return ds

    def write(self, path, meta: RunMetadata) -> None:
        write_dataset(self.to_dataset(meta), path)

    @classmethod
    def read(cls, path) -> HexapodModel:
        return cls.from_dataset(open_dataset(path, kind="model"))

    @classmethod
    def from_dataset(cls, ds: xr.Dataset) -> HexapodModel:
        phi = Parameters.from_vector(np.array([float(ds[name].values) for name in NAMES]))
        controller = Geometry(
            ds["controller_base"].values, ds["controller_platform"].values, ds["controller_pivot"].values
        )
        free = tuple(str(v) for v in ds["parameter"].values)
        std = {name: float(ds[name].attrs["std"]) for name in free}
        keys = ("chi2_dof", "residual_rms_um", "n_poses", "dof", "dropped", "rejected", "robust")
        diagnostics = {k: ds.attrs[k] for k in keys if k in ds.attrs}
        return cls(str(ds.attrs["model"]), phi, controller, free, std, ds["correlation"].values, diagnostics)
