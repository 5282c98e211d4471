"""The export of an identified hexapod model: ``bundle.json`` and ``geometry.nc``.

``bundle.json`` holds what a lab needs to command its hexapod through the identified geometry
without calflow's workflow: the base and platform joint centres (µm, 6 × 3, base joints in the
work frame, platform joints in the platform frame), the leg offsets (µm), scales (1) and
thermal expansion (1/K), the measurement frame F and tool frame G (µm, degree, the C-887 pose
convention), the controller's nominal geometry and pivot the legs were commanded through,
every parameter's value, σ, unit and whether it was free, their correlation, and the
provenance (campaign, configuration SHA-256, the model file's SHA-256, calflow versions).
``geometry.nc`` is the same as netCDF with CF units (the model file's layout,
:meth:`calflow_hexapod.models.calibration.HexapodModel.to_dataset`). Floats are written with
Python's shortest round-trip representation, so reading the bundle back gives the model's
parameters to the bit.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from calflow.data.bundle import provenance as provenance  # the export step calls it from here
from calflow.data.bundle import read_bundle
from calflow.data.bundle import write_bundle as write_bundle_json
from calflow.data.io import jsonable
from calflow.errors import DataError
from calflow_hexapod.models.calibration import HexapodModel
from calflow_hexapod.models.geometry import Geometry
from calflow_hexapod.models.ladder import NAMES, Parameters, long_name, unit

FORMAT = "calflow-hexapod-bundle"
VERSION = 1
NETCDF = "geometry.nc"

CONVENTIONS = {
    "units": "um for lengths, degree for angles, 1 for leg scales, 1/K for alpha_T",
    "pose": "(x, y, z, u, v, w): translation along the work frame's axes, R = Rx(u) Ry(v) Rz(w) about the pivot",
    "legs": "l = lambda + dl + s (lambda - lambda0) + alpha_T lambda (T - 20 degC); lambda the length the "
    "controller commands through its nominal geometry, lambda0 its value at the zero pose",
    "loop": "platform pose P = F M G^-1 for a reading M of the instrument (measurement frame F, tool frame G)",
    "command": "for a wanted reading M: legs l of P through the identified joints, lambda = l^-1(l), and the "
    "pose to command is the controller's forward kinematics of lambda (its nominal geometry, pivot)",
}


def _rows(a: np.ndarray) -> list:
    return [[float(v) for v in row] for row in np.asarray(a, dtype=float)]


def document(model: HexapodModel, prov: dict) -> dict:
    """The content of ``bundle.json`` for ``model``."""
    phi, g = model.parameters, model.controller
    return {
        "format": FORMAT,
        "version": VERSION,
        "model": model.name,
        "geometry": {
            "base_joints_um": _rows(phi.base),
            "platform_joints_um": _rows(phi.platform),
            "leg_offsets_um": [float(v) for v in phi.offset],
            "leg_scales": [float(v) for v in phi.scale],
            "alpha_T_per_K": float(phi.thermal),
            "measurement_frame": [float(v) for v in phi.frame],
            "tool_frame": [float(v) for v in phi.tool],
        },
        "controller": {
            "base_joints_um": _rows(g.base),
            "platform_joints_um": _rows(g.platform),
            "pivot_um": [float(v) for v in g.pivot],
        },
        "parameters": {
            name: {
                "value": float(value),
                "std": jsonable(model.std.get(name, float("nan"))),
                "units": unit(name),
                "long_name": long_name(name),
                "free": name in model.free,
            }
            for name, value in zip(NAMES, phi.vector())
        },
        "free": list(model.free),
        "correlation": jsonable(np.asarray(model.correlation, dtype=float)),
        "diagnostics": jsonable(dict(model.diagnostics)),
        "conventions": CONVENTIONS,
        "provenance": jsonable(prov),
    }


def write_bundle(model: HexapodModel, folder, prov: dict, meta) -> Path:
    """Write ``geometry.nc`` then ``bundle.json`` (last: the marker of a complete export)."""

    def content(folder: Path) -> dict:
        model.write(folder / NETCDF, meta)
        return document(model, prov)

    return write_bundle_json(folder, content)


def load(path) -> dict:
    """``bundle.json`` of a folder (or the file itself), checked for format, version and fields."""
    path, doc = read_bundle(path, FORMAT, VERSION, NAMES)
    pivot = (doc.get("controller") or {}).get("pivot_um")
    if not (isinstance(pivot, list) and len(pivot) == 3):
        raise DataError(f"{path}: field 'controller.pivot_um': expected 3 numbers (um)")
    return doc


def read_model(path) -> HexapodModel:
    """The :class:`HexapodModel` of a bundle: the parameters of ``parameters``, the controller's
    nominal geometry and pivot of ``controller``."""
    doc = load(path)
    p = doc["parameters"]
    phi = Parameters.from_vector(np.array([float(p[n]["value"]) for n in NAMES]))
    c = doc["controller"]
    try:
        controller = Geometry(c["base_joints_um"], c["platform_joints_um"], c["pivot_um"])
    except (KeyError, ValueError) as exc:
        raise DataError(
            f"{path}: field 'controller': expected 6 x 3 joints and a pivot (um): {exc}"
        ) from None
    std = {n: float("nan") if p[n].get("std") is None else float(p[n]["std"]) for n in doc["free"]}
    return HexapodModel(
        doc["model"],
        phi,
        controller,
        tuple(doc["free"]),
        std,
        np.asarray(doc["correlation"], dtype=float),
        dict(doc.get("diagnostics") or {}),
    )
