"""XYΘ steps: characterisation (Sec. 4.4), identification of Models I–V (Sec. 4.5),
observability (Fig. 4.21) and scoring of validation and XY compensation runs."""

from __future__ import annotations

import numpy as np

from calflow.commands.common import campaign as load, meta
from calflow.data.io import open_dataset, write_dataset
from calflow.errors import CalflowError


def characterise(args) -> None:
    """Error tables of the X and Y stages from the two characterisation sweeps (Sec. 4.4.1)."""
    from calflow.xytheta.characterisation import characterise as tables

    c = load(args.campaign)
    run_x, run_y = open_dataset(args.x, kind="run"), open_dataset(args.y, kind="run")
    write_dataset(tables(run_x, run_y, meta(c, run_x.attrs["source"], "characterisation")), args.out)


def _measured(run):
    """Joint values and measured tool points (Eq. 4.27 up to x_m0, y_m0) of a run."""
    from calflow.xytheta import cost

    theta = run["meas_theta"].values - run["meas_theta"].values[0]
    P_mx, P_my = cost.measured_points(run["meas_x"].values, run["meas_y"].values, theta)
    return run["cmd_x"].values, run["cmd_y"].values, theta, P_mx, P_my


def identify(args) -> None:
    """One model of the campaign's ``models`` table (Table 4.4).

    ``free``/``fixed`` parameters are identified on the identification run with the
    pose-difference cost (Eq. 4.28–4.30); ``position_table`` applies ex, ey in the joints
    (pre-calibration, Model III); a model with ``base`` and ``angle_table`` takes the base
    model's parameters and tables and adds f_ax, f_ay tabulated from the angle-residual
    run commanded through the base model (post-calibration, Models IV, V).
    """
    from calflow.identification import diagnostics
    from calflow.xytheta.identification import identify as fit
    from calflow.xytheta.kinematics import Parameters
    from calflow.xytheta.lookup import AngleLUT, PositionLUT, angle_residuals_from_run
    from calflow.xytheta.pose_lookup import PoseAngleLUT
    from calflow.xytheta.models import MicroModel, joint_directions

    c = load(args.campaign)
    spec = c["models"].get(args.model_name)
    if spec is None:
        raise CalflowError(f"{args.campaign}: key 'models.{args.model_name}': missing")
    if "base" in spec:
        base = MicroModel.read(args.base)
        residuals = angle_residuals_from_run(open_dataset(args.residuals, kind="run"))
        if c["angle_residuals"]["table"] == "position_angle":
            angle = PoseAngleLUT.from_residuals(residuals.x_T, residuals.y_T, residuals.theta, residuals.f_ax,
                                                residuals.f_ay, base.parameters.alpha, base.parameters.beta)
        else:
            angle = AngleLUT.from_residuals(residuals.theta, residuals.f_ax, residuals.f_ay,
                                            base.parameters.alpha, base.parameters.beta)
        model = MicroModel(args.model_name, base.parameters, base.free, base.std, base.correlation,
                           dict(base.diagnostics), base.position, angle, base.method)
        model.diagnostics["angle_residual_nan"] = int(residuals.nan_readings)
        model.write(args.out, meta(c, open_dataset(args.base).attrs["source"], "angle_residuals", args.model_name))
        return
    run = open_dataset(args.run, kind="run")
    X, Y, theta, P_mx, P_my = _measured(run)
    position = None
    ex = ey = 0.0
    if spec.get("position_table"):
        if not args.luts:
            raise CalflowError(f"model {args.model_name}: position_table needs --luts LUTS.nc")
        position = PositionLUT.from_dataset(open_dataset(args.luts, kind="luts"))
        ex, ey = position.errors(X, Y, *joint_directions(X, Y), method=c["identification"]["interpolation"],
                                 trends=False)
    initial = {**c["identification"]["initial"], **spec.get("fixed", {})}
    result = fit(X, Y, theta, P_mx, P_my, free=tuple(spec["free"]), initial=Parameters(**initial), ex=ex, ey=ey)
    if not result.success or not np.all(np.isfinite(result.parameters.as_array())):
        raise CalflowError(f"{args.run}: identification of model {args.model_name} failed ({result.message})")
    r_diag, not_identifiable = diagnostics.identifiability(result.jacobian, result.free)
    diag = {
        "r_diag": r_diag,
        "not_identifiable": ", ".join(not_identifiable),
        "residual_rms_um": result.residual_rms_um,
        "n_poses": result.n_poses,
        "dof": result.dof,
        "condition_number": float(np.linalg.cond(result.jacobian)),
        "optimizer": f"scipy.optimize.least_squares(method='lm'), nfev={result.nfev}: {result.message}",
        **diagnostics.observability(result.jacobian),
    }
    model = MicroModel(args.model_name, result.parameters, result.free, result.std, result.correlation, diag,
                       position, None, c["identification"]["interpolation"])
    model.write(args.out, meta(c, run.attrs["source"], "identification", args.model_name))


def metrics(args) -> None:
    """ISO 9283 of a validation run (world frame) or of a square/random-points run (stage frame)."""
    from calflow.xytheta.characterisation import xy_positioning_metrics
    from calflow.xytheta.evaluation import xytheta_validation_metrics

    c = load(args.campaign)
    run = open_dataset(args.run, kind="run")
    m = meta(c, run.attrs["source"], run.attrs["plan"], run.attrs.get("model"))
    if run.attrs["plan"] == "validation":
        ds = xytheta_validation_metrics(run, m)
    else:
        ds = xy_positioning_metrics(run, m)
        ds.attrs["compensation"] = run.attrs.get("compensation", "none")
    write_dataset(ds, args.out)


def observability(args) -> None:
    """Observability indices O1–O4 against the number of random poses (Fig. 4.21).

    The Jacobian of the pose-difference cost at the starting parameters, over the
    campaign's identification ranges; each count is averaged over ``repeats`` draws.
    """
    import xarray as xr

    from calflow.identification import diagnostics
    from calflow.xytheta import cost
    from calflow.xytheta.kinematics import Parameters
    from calflow.xytheta.plans import identification

    c = load(args.campaign)
    o = c["observability"]
    p = c["identification"]
    phi = Parameters(**p["initial"])
    counts = np.unique(np.geomspace(o["min_poses"], o["max_poses"], o["steps"]).round().astype(int))
    values = np.zeros((len(counts), 4))
    for k, n in enumerate(counts):
        for r in range(o["repeats"]):
            plan = identification(int(n), p["x_um"], p["y_um"], p["theta_deg"], seed=c["seed"] + 1000 * r + k)
            J = cost.jacobian(phi, plan.commands["x"][1:], plan.commands["y"][1:], plan.commands["theta"][1:])
            idx = diagnostics.observability(J)
            values[k] += [idx[name] for name in ("O1", "O2", "O3", "O4")]
    values /= o["repeats"]
    units = {"O1": "1", "O2": "1", "O3": "1", "O4": "1"}
    ds = xr.Dataset(
        {name: xr.Variable(("poses",), values[:, j], attrs={"units": units[name],
                                                            "long_name": f"observability index {name} (Eq. 4.{10 + j})"})
         for j, name in enumerate(("O1", "O2", "O3", "O4"))},
        coords={"poses": xr.Variable(("poses",), counts, attrs={"units": "1", "long_name": "number of random poses"})},
        attrs=meta(c, "simulated", "observability").attrs("metrics"),
    )
    o2 = values[:, 1]
    plateau = counts[np.argmax(o2 >= 0.95 * o2.max())]
    ds.attrs["O2_plateau_poses"] = int(plateau)
    write_dataset(ds, args.out)
