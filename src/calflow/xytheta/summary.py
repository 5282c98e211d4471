"""The campaign summary (``results/<campaign>/summary.json``, DESIGN.md).

The summary is assembled from the campaign's result files, recognised by their
attributes (``calflow_kind``, ``plan``, ``model``), so a rule hands over its inputs as a
list. XYΘ here; the nanopositioning summaries are in :mod:`calflow.nano.summary`.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import xarray as xr

from calflow import __version__, reference
from calflow.data.io import jsonable, sha256_file
from calflow.xytheta.kinematics import PARAMETER_NAMES, PARAMETER_UNITS

_SUFFIX = {"um": "um", "degree": "deg"}


def parameter_key(name: str) -> str:
    """Summary key of a parameter: its name and unit, e.g. ``x_R_um``, ``alpha_deg``."""
    return f"{name}_{_SUFFIX[PARAMETER_UNITS[name]]}"


def _model_entry(model: xr.Dataset, m: xr.Dataset) -> dict:
    corr = model["correlation"].values
    return {
        "accuracy_um": float(m.attrs["accuracy_um"]),
        "repeatability_um": float(m.attrs["repeatability_um"]),
        "free": [str(p) for p in model["parameter"].values],
        "position_table": bool(model.attrs.get("position_table", 0)),
        "angle_table": bool(model.attrs.get("angle_table", 0)),
        "parameters": {
            parameter_key(p): {"value": float(model[p].values), "std": jsonable(float(model[p].attrs.get("std", np.nan)))}
            for p in PARAMETER_NAMES
        },
        "correlation": [[jsonable(v) for v in row] for row in corr],
        "identifiability": {"r_diag": [jsonable(v) for v in model["r_diag"].values] if "r_diag" in model else [],
                            "not_identifiable": model.attrs.get("not_identifiable", "")},
        "identification": {k: jsonable(v) for k, v in model.attrs.items()
                           if k in ("residual_rms_um", "n_poses", "dof", "condition_number", "O1", "O2", "O3", "O4")},
        "per_target": [
            {"target": int(t), "x_um": float(m["target_x"].sel(target=t)), "y_um": float(m["target_y"].sel(target=t)),
             "theta_deg": float(m["target_theta"].sel(target=t)), "ap_um": float(m["ap"].sel(target=t)),
             "rp_um": float(m["rp"].sel(target=t))}
            for t in m["target"].values
        ],
    }


def _characterisation(luts: xr.Dataset) -> dict:
    out = {name: jsonable(float(luts[name])) for name in ("x_stage_angle", "perpendicularity") if name in luts}
    out["periods_um"] = {k[len("period_"):]: jsonable(float(luts[k])) for k in luts.data_vars if k.startswith("period_")}
    out["repeatability_um"] = {
        k[len("rep_"):]: {"median": jsonable(float(np.nanmedian(luts[k].values))), "max": jsonable(float(np.nanmax(luts[k].values)))}
        for k in luts.data_vars if k.startswith("rep_")
    }
    out["peak_to_valley_um"] = {
        k[len("err_"):]: jsonable(float(np.nanmax(luts[k].values) - np.nanmin(luts[k].values)))
        for k in luts.data_vars if k.startswith("err_")
    }
    return out


def _xy_test(m: xr.Dataset) -> dict:
    return {
        "accuracy_um": jsonable(float(m.attrs["accuracy_um"])),
        "repeatability_um": jsonable(float(m.attrs["repeatability_um"])),
        "per_target": [{"target": int(t), "ap_um": jsonable(float(m["ap"].sel(target=t)))} for t in m["target"].values],
    }


def _iso230_2_of_sweep(run: xr.Dataset, axis: str) -> dict:
    """ISO 230-2 of one stage from its characterisation sweep (stage frame, µm)."""
    from calflow.xytheta.characterisation import stage_positions
    from calflow.metrics.iso230_2_runs import iso230_2_of_run

    u, v = stage_positions(run)
    r = iso230_2_of_run(run, attained=u if axis == "x" else v, target=run[f"cmd_{axis}"].values)
    out = {"units": "um", "targets": len(r["targets_um"]), "cycles_forward": r["cycles_forward"],
           "cycles_backward": r["cycles_backward"]}
    for key in ("E", "E_fwd", "E_bwd", "M", "B", "B_mean", "R", "R_fwd", "R_bwd", "A", "A_fwd", "A_bwd"):
        out[f"{key}_um"] = jsonable(r[f"{key}_nm"] / 1000.0)
    return out


def xytheta_summary(campaign: dict, files: list[str], truth: dict | None) -> dict:
    """Assemble the summary of an XYΘ campaign from its result files."""
    models, validation, xy, luts, obs, iso = {}, {}, {}, None, None, {}
    for path in files:
        with xr.open_dataset(path, engine="netcdf4", decode_times=False) as ds:
            ds = ds.load()
        kind, plan = ds.attrs.get("calflow_kind"), ds.attrs.get("plan")
        if kind == "model":
            models[ds.attrs["model"]] = ds
        elif kind == "metrics" and plan == "validation":
            validation[ds.attrs["model"]] = ds
        elif kind == "metrics" and plan in ("square", "random_points"):
            xy.setdefault(plan, {})[ds.attrs.get("compensation", "none")] = _xy_test(ds)
        elif kind == "metrics" and plan == "observability":
            obs = ds
        elif kind == "luts":
            luts = ds
        elif kind == "run" and plan in ("characterisation_x", "characterisation_y"):
            iso[plan[-1]] = _iso230_2_of_sweep(ds, plan[-1])
    order = [name for name in campaign["models"] if name in models]
    summary = {
        "campaign": campaign["name"],
        "robot": campaign["robot"],
        "description": campaign.get("description", ""),
        "calflow_version": __version__,
        "seed": campaign.get("seed"),
        "rig": campaign.get("rig", {}).get("factory"),
        "models": {name: _model_entry(models[name], validation[name]) for name in order},
        "reference": reference.BY_ROBOT["xytheta"],
        "inputs": {str(p): sha256_file(p) for p in files},
    }
    if luts is not None:
        summary["characterisation"] = _characterisation(luts)
    if xy:
        summary["xy_tests"] = xy
    if iso:
        summary["iso230_2"] = iso
    if obs is not None:
        summary["observability"] = {
            "poses": [int(v) for v in obs["poses"].values],
            **{k: [jsonable(v) for v in obs[k].values] for k in ("O1", "O2", "O3", "O4")},
            "O2_plateau_poses": int(obs.attrs["O2_plateau_poses"]),
        }
    if truth and truth.get("available", True):
        summary["truth"] = {"parameters": {k: truth[k] for k in ("x_R_um", "y_R_um", "alpha_deg", "beta_deg")}}
    return summary
