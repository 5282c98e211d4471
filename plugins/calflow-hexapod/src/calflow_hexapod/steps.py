"""The hexapod's workflow steps behind ``calflow identify`` and ``calflow metrics``.

Step hooks, each called as ``hook(c, args)`` (:mod:`calflow.family_contract`): ``c`` the loaded
campaign, ``args`` the step's inputs.

``identify``: one model of the ladder (campaign ``models.<name>.rung``) from the identification
run, by inverse-kinematic residuals weighted as implicit loops (:mod:`calflow_hexapod.models.identification`).
``metrics``: ISO 9283 pose accuracy and repeatability of a validation run (held-out targets or
the ISO 9283 poses) for position (AP_p, RP_l, ISO 9283:1998 7.2.1–7.2.2, µm) and for
orientation about each axis (AP_a/AP_b/AP_c, RP_a/RP_b/RP_c, degree), per target pose.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from calflow.commands.common import meta
from calflow.data.io import open_dataset, write_dataset
from calflow.errors import CalflowError
from calflow_hexapod.models.geometry import AXES

POSITION, ORIENTATION = AXES[:3], AXES[3:]


def identify(c, args) -> None:
    """``calflow identify --campaign FILE --model-name NAME --run RUN --out MODEL.nc``."""
    from calflow.identification.robust import Robust
    from calflow_hexapod.models.calibration import HexapodModel
    from calflow_hexapod.models.geometry import h811
    from calflow_hexapod.models.identification import SIGMA_POSE, run_inputs
    from calflow_hexapod.models.identification import identify as fit_model
    from calflow_hexapod.models.ladder import LADDER
    from calflow_hexapod.plans.design import noise_model, nominal_parameters

    spec = c["models"].get(args.model_name)
    if spec is None:
        raise CalflowError(
            f"{args.campaign}: key 'models': no model {args.model_name!r}; expected one of "
            f"{sorted(c['models'])}"
        )
    rung = spec.get("rung", args.model_name)
    if rung not in LADDER:
        raise CalflowError(
            f"{args.campaign}: key 'models.{args.model_name}.rung': expected one of "
            f"{sorted(LADDER)}, got {rung!r}"
        )
    run = open_dataset(args.run, kind="run")
    controller = h811()
    measured, lam, temperature = run_inputs(run, controller, source=str(args.run))
    noise = noise_model(c)
    sigma_pose = SIGMA_POSE
    sigma_leg = 0.0
    if noise is not None:
        sigma_pose = (noise["position_um"],) * 3 + (noise["angle_deg"],) * 3
        sigma_leg = noise["leg_um"]
    fit = fit_model(
        measured,
        lam,
        controller.zero_lengths,
        free=LADDER[rung],
        initial=nominal_parameters(c),
        sigma_pose=sigma_pose,
        sigma_leg_um=sigma_leg,
        temperature=temperature if rung == "thermal" else None,
        robust=Robust() if spec.get("robust") else None,
    )
    model = HexapodModel.from_identification(args.model_name, fit, controller)
    model.write(args.out, meta(c, run.attrs.get("source", "simulated"), "identification", args.model_name))


def pose_metrics(run: xr.Dataset) -> dict[str, np.ndarray]:
    """Per target pose (the run's ``pose`` index ≥ 1, pose 0 is home): the target and ISO 9283
    AP/RP of position (µm) and of each orientation axis (degree) over the run's cycles."""
    from calflow.metrics.iso9283 import iso9283
    from calflow.metrics.iso9283_orientation import iso9283_orientation

    pose = np.asarray(run["pose"].values, dtype=int)
    meas = np.stack([np.asarray(run[f"meas_{a}"].values, dtype=float) for a in AXES], axis=-1)
    target = np.stack([np.asarray(run[f"target_{a}"].values, dtype=float) for a in AXES], axis=-1)
    rows: dict[str, list] = {k: [] for k in ("target", "pose", "ap", "rp", "ap_orient", "rp_orient", "n")}
    for k in sorted(set(pose[pose > 0])):
        sel = (pose == k) & np.all(np.isfinite(meas), axis=1)
        if sel.sum() < 2:
            continue
        t = target[pose == k][0]
        pos = iso9283(t[:3], meas[sel, :3])
        ori = iso9283_orientation(t[3:], meas[sel, 3:])
        rows["target"].append(k)
        rows["pose"].append(t)
        rows["ap"].append(pos.ap)
        rows["rp"].append(pos.rp)
        rows["ap_orient"].append(ori.ap_abs)
        rows["rp_orient"].append(ori.rp)
        rows["n"].append(int(sel.sum()))
    if not rows["target"]:
        raise CalflowError("run: no target pose with two or more valid readings; ISO 9283 needs n >= 2")
    return {k: np.asarray(v) for k, v in rows.items()}


def metrics(c, args) -> None:
    """``calflow metrics --campaign FILE --run RUN --out METRICS.nc`` of a validation run."""
    run = open_dataset(args.run, kind="run")
    m = pose_metrics(run)
    dims = ("target",)
    data = {
        "ap": xr.Variable(dims, m["ap"], {"units": "um", "long_name": "ISO 9283 position accuracy AP_p"}),
        "rp": xr.Variable(
            dims, m["rp"], {"units": "um", "long_name": "ISO 9283 position repeatability RP_l"}
        ),
        "n": xr.Variable(dims, m["n"], {"units": "1", "long_name": "attained poses"}),
    }
    for i, (axis, letter) in enumerate(zip(ORIENTATION, "abc")):
        data[f"ap_{letter}"] = xr.Variable(
            dims,
            m["ap_orient"][:, i],
            {"units": "degree", "long_name": f"ISO 9283 accuracy AP_{letter} ({axis})"},
        )
        data[f"rp_{letter}"] = xr.Variable(
            dims,
            m["rp_orient"][:, i],
            {"units": "degree", "long_name": f"ISO 9283 repeatability RP_{letter} ({axis})"},
        )
    for i, axis in enumerate(AXES):
        unit = "degree" if axis in ORIENTATION else "um"
        data[f"target_{axis}"] = xr.Variable(
            dims, m["pose"][:, i], {"units": unit, "long_name": f"target {axis}"}
        )
    coords = {"target": xr.Variable(dims, m["target"], {"units": "1", "long_name": "target pose index"})}
    attrs = meta(c, run.attrs.get("source", "simulated"), run.attrs["plan"], run.attrs.get("model")).attrs(
        "metrics"
    )
    ds = xr.Dataset(data, coords=coords, attrs=attrs)
    ds.attrs.update(
        accuracy_um=float(m["ap"].max()),
        repeatability_um=float(m["rp"].max()),
        **{f"accuracy_{x}_deg": float(m["ap_orient"][:, i].max()) for i, x in enumerate("abc")},
        **{f"repeatability_{x}_deg": float(m["rp_orient"][:, i].max()) for i, x in enumerate("abc")},
        cycles=int(m["n"].min()),
    )
    if "command_difference" in run.attrs:  # a run through an exported bundle (validation_export)
        ds.attrs["command_difference"] = float(run.attrs["command_difference"])
    write_dataset(ds, args.out)
