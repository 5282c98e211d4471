"""The campaign summary (``results/<campaign>/summary.json``, DESIGN.md)."""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path

import numpy as np
import xarray as xr

from calflow import __version__, reference
from calflow.kinematics.xytheta import PARAMETER_NAMES, PARAMETER_UNITS

_SUFFIX = {"um": "um", "degree": "deg"}


def parameter_key(name: str) -> str:
    """Summary key of a parameter: its name and unit, e.g. ``x_R_um``, ``alpha_deg``."""
    return f"{name}_{_SUFFIX[PARAMETER_UNITS[name]]}"


def _clean(value):
    """A JSON-ready scalar: numpy numbers become Python numbers, NaN becomes None."""
    if value is None:
        return None
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return None if math.isnan(value) else float(value)
    return value


def sha256_file(path: str | Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def xytheta_summary(campaign: dict, models: dict[str, xr.Dataset], metrics: dict[str, xr.Dataset],
                    truth: dict | None, inputs: list[str]) -> dict:
    """Assemble the summary of an XYΘ campaign from its model and metrics datasets."""
    out_models = {}
    for name, model in models.items():
        m = metrics[name]
        out_models[name] = {
            "accuracy_um": float(m.attrs["accuracy_um"]),
            "repeatability_um": float(m.attrs["repeatability_um"]),
            "free": [str(p) for p in model["parameter"].values],
            "parameters": {
                parameter_key(p): {"value": float(model[p].values), "std": _clean(float(model[p].attrs.get("std", np.nan)))}
                for p in PARAMETER_NAMES
            },
            "identification": {k: _clean(v) for k, v in model.attrs.items()
                               if k in ("residual_rms_um", "n_poses", "dof", "O1", "O2", "O3", "O4")},
            "per_target": [
                {
                    "target": int(t),
                    "x_um": float(m["target_x"].sel(target=t)),
                    "y_um": float(m["target_y"].sel(target=t)),
                    "theta_deg": float(m["target_theta"].sel(target=t)),
                    "ap_um": float(m["ap"].sel(target=t)),
                    "rp_um": float(m["rp"].sel(target=t)),
                }
                for t in m["target"].values
            ],
        }
    summary = {
        "campaign": campaign["name"],
        "robot": campaign["robot"],
        "description": campaign.get("description", ""),
        "calflow_version": __version__,
        "seed": campaign.get("seed"),
        "rig": campaign.get("rig", {}).get("factory"),
        "models": out_models,
        "reference": reference.BY_ROBOT["xytheta"],
        "inputs": {str(p): sha256_file(p) for p in inputs},
    }
    if truth and truth.get("available", True):
        summary["truth"] = {
            "parameters": {
                "x_R_um": truth["x_R_um"],
                "y_R_um": truth["y_R_um"],
                "alpha_deg": truth["alpha_deg"],
                "beta_deg": truth["beta_deg"],
            }
        }
    return summary


def load_summary(path: str | Path) -> dict:
    return json.loads(Path(path).read_text())
