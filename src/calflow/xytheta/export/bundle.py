"""The controller-neutral export of an XYΘ model: ``bundle.json`` and CSV tables.

``bundle.json`` holds the identified parameters φ = {x_R, y_R, α, β} (value, σ, units,
free or fixed), their correlation, the interpolation in the tables, a description of
every table (CSV files with ``name [unit]`` headers, :mod:`.tables`) and the provenance
(campaign, configuration hash, calflow version of the model and of the export, the model
file's SHA-256). :func:`read_model` rebuilds the :class:`MicroModel` — the same tables,
the same inverse (Eq. 4.19) — for :class:`calflow.xytheta.export.Compensator`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from calflow.data.bundle import read_bundle
from calflow.data.bundle import write_bundle as write_bundle_json
from calflow.data.io import jsonable
from calflow.xytheta.export.tables import rebuild, write_tables
from calflow.xytheta.models import kinematics as kin

FORMAT = "calflow-xytheta-bundle"
VERSION = 1

LIMITS = (
    "The bundle is the whole model: parameters, position tables (own-axis and cross-axis terms) and the "
    "angle table; the Compensator applies all of them as calflow's in-process model does. Controller files "
    "(LinuxCNC, TwinCAT) hold the own-axis terms only."
)


def write_bundle(model, folder, prov: dict, controllers: dict | None = None) -> Path:
    """Write ``model`` (a :class:`MicroModel`) as a bundle in ``folder``; returns bundle.json.

    ``controllers``: what the controller files written beside it hold (:mod:`.writer`)."""

    def document(folder: Path) -> dict:
        params = {
            name: {
                "value": float(getattr(model.parameters, name)),
                "std": jsonable(model.std.get(name, np.nan)),
                "units": kin.PARAMETER_UNITS[name],
                "free": name in model.free,
            }
            for name in kin.PARAMETER_NAMES
        }
        tables = {name: write_tables(ds, folder, name) for name, ds in model.groups().items()}
        return {
            "format": FORMAT,
            "version": VERSION,
            "model": model.name,
            "parameters": params,
            "free": list(model.free),
            "correlation": jsonable(np.asarray(model.correlation, dtype=float)),
            "interpolation": model.method,
            "tables": tables,
            "provenance": jsonable(prov),
            "conventions": {
                "units": "um for positions and errors, degree for angles",
                "errors": "target - measured; joint command = inverse kinematics + table error (Eq. 4.19)",
                "kinematics": "thesis Eq. 4.18 (forward) and 4.19 (inverse)",
            },
            "limits": LIMITS,
            "controllers": jsonable(controllers or {}),
        }

    return write_bundle_json(folder, document)


def load(folder) -> dict:
    """``bundle.json`` of ``folder`` (or the file itself), checked for format and version."""
    return read_bundle(folder, FORMAT, VERSION, kin.PARAMETER_NAMES)[1]


def read_model(folder):
    """The :class:`MicroModel` of a bundle, tables and all."""
    from calflow.xytheta.models.ladder import MicroModel
    from calflow.xytheta.tables.angle import AngleTable
    from calflow.xytheta.tables.angle_residuals import AngleLUT
    from calflow.xytheta.tables.pose import PoseAngleLUT
    from calflow.xytheta.tables.position import PositionLUT

    path = Path(folder)
    folder = path if path.is_dir() else path.parent
    doc = load(path)
    p = doc["parameters"]
    params = kin.Parameters(**{n: float(p[n]["value"]) for n in kin.PARAMETER_NAMES})
    std = {n: float("nan") if p[n].get("std") is None else float(p[n]["std"]) for n in kin.PARAMETER_NAMES}
    tables = {name: rebuild(folder, spec) for name, spec in doc["tables"].items()}
    position = PositionLUT.from_dataset(tables["position_table"]) if "position_table" in tables else None
    angle = None
    if "angle_table" in tables:
        t = tables["angle_table"]
        angle = {"position_angle": PoseAngleLUT, "angle_sweep": AngleTable}.get(
            t.attrs.get("table"), AngleLUT
        ).from_dataset(t)
    return MicroModel(
        doc["model"],
        params,
        tuple(doc["free"]),
        std,
        np.asarray(doc["correlation"], dtype=float),
        {},
        position,
        angle,
        doc["interpolation"],
    )
