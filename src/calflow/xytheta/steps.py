"""XYΘ steps: characterisation (Sec. 4.4), identification of Models I–V (Sec. 4.5),
observability (Fig. 4.21) and scoring of validation and XY compensation runs.

``identify`` and ``metrics`` are the family's step hooks, called as
``hook(c, args)`` (:mod:`calflow.family_contract`): ``c`` the loaded campaign, ``args`` the
step's inputs."""

from __future__ import annotations

import numpy as np

from calflow.commands.common import campaign_of, meta
from calflow.data.io import open_dataset, write_dataset
from calflow.errors import CalflowError


def characterise(args) -> None:
    """Error tables of the X and Y stages from the two characterisation sweeps (Sec. 4.4.1)."""
    from calflow.xytheta.tables.characterisation import characterise as tables

    c = campaign_of(args)
    run_x, run_y = open_dataset(args.x, kind="run"), open_dataset(args.y, kind="run")
    write_dataset(tables(run_x, run_y, meta(c, run_x.attrs["source"], "characterisation")), args.out)


def _measured(run):
    """Joint values and measured tool points (Eq. 4.27 up to x_m0, y_m0) of a run."""
    from calflow.xytheta.models import cost

    theta = run["meas_theta"].values - run["meas_theta"].values[0]
    P_mx, P_my = cost.measured_points(run["meas_x"].values, run["meas_y"].values, theta)
    return run["cmd_x"].values, run["cmd_y"].values, theta, P_mx, P_my


def _without(a, rows):
    """``a`` as floats with the rows ``rows`` set to NaN (dropped by the fit-quality figures)."""
    out = np.array(a, dtype=float)
    out[np.asarray(rows, dtype=int)] = np.nan
    return out


def _fit_quality(c: dict, X, Y, theta, P_mx, P_my, free, initial, ex, ey, f_ax=0.0, f_ay=0.0) -> dict:
    """Residual RMS and σ̂ of a model on the identification poses, and its k-fold CV RMS."""
    from calflow.xytheta.models import cost
    from calflow.xytheta.models.identification import noise_sigma
    from calflow.xytheta.models.resampling import cross_validate

    p = c["identification"]
    X, Y, theta, P_mx, P_my = (np.asarray(a, dtype=float) for a in (X, Y, theta, P_mx, P_my))
    ok = np.isfinite(X) & np.isfinite(Y) & np.isfinite(theta) & np.isfinite(P_mx) & np.isfinite(P_my)
    b = [np.broadcast_to(np.asarray(a, dtype=float), X.shape)[ok] for a in (ex, ey, f_ax, f_ay)]
    eps = cost.residuals(initial, X[ok], Y[ok], theta[ok], P_mx[ok], P_my[ok], *b)
    out = {
        "residual_rms_um": float(np.sqrt(np.mean(eps**2))),
        "sigma_fit_um": noise_sigma(eps, int(ok.sum()), len(free)),
        "cv_folds": int(p["cv_folds"]),
    }
    out["cv_rms_um"] = cross_validate(
        X, Y, theta, P_mx, P_my, tuple(free), initial, p["cv_folds"], int(c["seed"]), ex, ey, f_ax, f_ay
    )
    return out


def identify(c, args) -> None:
    """One model of the campaign's ``models`` table (Table 4.4).

    ``free``/``fixed`` parameters are identified on the identification run with the
    pose-difference cost (Eq. 4.28–4.30); ``position_table`` applies ex, ey in the joints
    (pre-calibration, Model III); a model with ``base`` and ``angle_table`` takes the base
    model's parameters and tables and adds f_ax(Θ), f_ay(Θ) tabulated from the angle
    characterisation commanded through the base model (post-calibration, Models IV, V).
    Every model gets its residual RMS and σ̂ on the identification poses and a k-fold
    cross-validated prediction RMS (``identification.cv_folds``).
    """
    from calflow.identification import diagnostics
    from calflow.identification.robust import Robust
    from calflow.xytheta.models import kinematics as kin
    from calflow.xytheta.models.identification import identify as fit
    from calflow.xytheta.models.kinematics import Parameters
    from calflow.xytheta.models.ladder import MicroModel, joint_directions
    from calflow.xytheta.models.resampling import bootstrap_std
    from calflow.xytheta.tables.position import PositionLUT, infer_directions

    spec = c["models"].get(args.model_name)
    if spec is None:
        raise CalflowError(f"{args.campaign}: key 'models.{args.model_name}': missing")
    run = open_dataset(args.run, kind="run")
    X, Y, theta, P_mx, P_my = _measured(run)
    method = c["identification"]["interpolation"]
    if "base" in spec:
        base = MicroModel.read(args.base)
        model = _angle_model(c, args, base)
        ex, ey = base.position_errors(X, Y, *joint_directions(X, Y))
        x0, y0 = kin.forward(X, Y, theta, base.parameters, ex=ex, ey=ey)
        commanded = run["cmd_theta"].values  # the table is indexed by the commanded angle
        f_ax, f_ay = model.angle_errors(x0, y0, commanded, infer_directions(commanded))
        rejected = [int(i) for i in str(base.diagnostics.get("rejected_poses", "")).split(",") if i.strip()]
        X = _without(X, np.flatnonzero(np.isin(run["pose"].values, rejected)))
        model.diagnostics.update(
            _fit_quality(c, X, Y, theta, P_mx, P_my, base.free, base.parameters, ex, ey, f_ax, f_ay)
        )
        model.write(
            args.out, meta(c, open_dataset(args.base).attrs["source"], "angle_residuals", args.model_name)
        )
        return
    position = None
    ex = ey = 0.0
    if spec.get("position_table"):
        if not args.luts:
            raise CalflowError(f"model {args.model_name}: position_table needs --luts LUTS.nc")
        position = PositionLUT.from_dataset(open_dataset(args.luts, kind="luts"))
        ex, ey = position.errors(X, Y, *joint_directions(X, Y), method=method, trends=False)
    initial = Parameters(**{**c["identification"]["initial"], **spec.get("fixed", {})})
    result = fit(
        X,
        Y,
        theta,
        P_mx,
        P_my,
        free=tuple(spec["free"]),
        initial=initial,
        ex=ex,
        ey=ey,
        robust=Robust.from_config(c["identification"]["robust"]),
    )
    X, Y = (
        _without(X, result.rejected),
        _without(Y, result.rejected),
    )  # outliers out of the fit-quality figures
    if not result.success or not np.all(np.isfinite(result.parameters.as_array())):
        raise CalflowError(f"{args.run}: identification of model {args.model_name} failed ({result.message})")
    r_diag, not_identifiable = diagnostics.identifiability(result.jacobian, result.free)
    diag = {
        "r_diag": r_diag,
        "not_identifiable": ", ".join(not_identifiable),
        "n_poses": result.n_poses,
        "dof": result.dof,
        "condition_number": float(np.linalg.cond(result.jacobian)),
        "optimizer": f"nfev={result.nfev}: {result.message}",
        "uncertainty": c["identification"]["uncertainty"],
        "sigma_um": result.sigma_um,
        "robust_loss": result.loss,
        "rejected_poses": ", ".join(str(int(run["pose"].values[i])) for i in result.rejected),
        **diagnostics.observability(result.jacobian),
        **_fit_quality(c, X, Y, theta, P_mx, P_my, result.free, result.parameters, ex, ey),
    }
    std = result.std
    if c["identification"]["uncertainty"] == "bootstrap":
        start = Parameters(**{**initial.as_dict(), **{k: getattr(result.parameters, k) for k in result.free}})
        std = bootstrap_std(
            X,
            Y,
            theta,
            P_mx,
            P_my,
            result.free,
            start,
            c["identification"]["bootstrap"],
            int(c["seed"]),
            ex,
            ey,
        )
    model = MicroModel(
        args.model_name, result.parameters, result.free, std, result.correlation, diag, position, None, method
    )
    model.write(args.out, meta(c, run.attrs["source"], "identification", args.model_name))


def _angle_model(c: dict, args, base):
    """Model IV/V: the base model plus the angle table from the angle characterisation run."""
    from calflow.xytheta.models.ladder import MicroModel
    from calflow.xytheta.tables.angle import AngleTable
    from calflow.xytheta.tables.angle_residuals import angle_residuals_from_run
    from calflow.xytheta.tables.pose import PoseAngleLUT

    a = c["angle_residuals"]
    sweep = open_dataset(args.residuals, kind="run")
    alpha, beta = base.parameters.alpha, base.parameters.beta
    diag = dict(base.diagnostics)
    if a["table"] == "position_angle":
        r = angle_residuals_from_run(sweep)
        angle = PoseAngleLUT.from_residuals(r.x_T, r.y_T, r.theta, r.f_ax, r.f_ay, alpha, beta)
        diag["angle_table_kind"] = (
            "position_angle (at the reference validation poses: in-sample for Table 4.7)"
        )
        diag["angle_residual_nan"] = int(r.nan_readings)
    else:
        try:
            angle, spectrum = AngleTable.from_sweep(
                sweep, alpha, beta, a["samples_per_period"], a["significance"], a["min_fraction"]
            )
        except ValueError as exc:
            raise CalflowError(f"{args.residuals}: {exc}") from None
        diag.update(
            angle_table_kind="angle",
            angle_step_deg=spectrum.step_deg,
            angle_sweep_step_deg=spectrum.sweep_step_deg,
            angle_shortest_period_deg=spectrum.shortest_period_deg if spectrum.shortest_period_deg else 0.0,
            angle_noise_um=spectrum.noise_um,
            angle_interpolation_error_um=spectrum.interpolation_error_um,
            angle_undersampled=int(spectrum.undersampled),
            angle_warning=spectrum.warning,
        )
        diag["angle_residual_nan"] = int(np.sum(~np.isfinite(sweep["meas_x"].values)))
    return MicroModel(
        args.model_name,
        base.parameters,
        base.free,
        base.std,
        base.correlation,
        diag,
        base.position,
        angle,
        base.method,
    )


def metrics(c, args) -> None:
    """ISO 9283 of a validation run (world frame) or of a square/random-points run (stage frame)."""
    from calflow.xytheta.evaluation import xytheta_validation_metrics
    from calflow.xytheta.tables.characterisation import xy_positioning_metrics

    run = open_dataset(args.run, kind="run")
    m = meta(c, run.attrs["source"], run.attrs["plan"], run.attrs.get("model"))
    if run.attrs["plan"] in ("validation", "validation_heldout", "interim_check", "as_found"):
        ds = xytheta_validation_metrics(run, m)
    else:
        ds = xy_positioning_metrics(run, m)
        ds.attrs["compensation"] = run.attrs.get("compensation", "none")
    write_dataset(ds, args.out)


def o2_plateau(counts, o2, tolerance: float = 0.05) -> tuple[float, int]:
    """O2's limit and the pose count from which it stays within ``tolerance`` of it (Fig. 4.21).

    ``o2`` is the mean over repeats at each count. The limit is the mean of the values at
    the largest quarter of the counts (at least two), where O2 has settled; the plateau is
    the first count from which every later mean stays within ``tolerance`` × limit — not the
    first time one noisy value touches a maximum.
    """
    counts, o2 = np.asarray(counts), np.asarray(o2, dtype=float)
    tail = max(2, len(o2) // 4)
    limit = float(np.mean(o2[-tail:]))
    inside = np.abs(o2 - limit) <= tolerance * abs(limit)
    outside = np.flatnonzero(~inside)
    first = 0 if outside.size == 0 else int(outside[-1]) + 1
    return limit, int(counts[min(first, len(counts) - 1)])


def observability(args) -> None:
    """Observability indices O1–O4 against the number of random poses (Fig. 4.21).

    The Jacobian of the pose-difference cost at the starting parameters, over the
    campaign's identification ranges; each count is averaged over ``repeats`` draws.
    """
    import xarray as xr

    from calflow.identification import diagnostics
    from calflow.xytheta.models import cost
    from calflow.xytheta.models.kinematics import Parameters
    from calflow.xytheta.plans.poses import identification

    c = campaign_of(args)
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
        {
            name: xr.Variable(
                ("poses",),
                values[:, j],
                attrs={"units": units[name], "long_name": f"observability index {name} (Eq. 4.{10 + j})"},
            )
            for j, name in enumerate(("O1", "O2", "O3", "O4"))
        },
        coords={
            "poses": xr.Variable(
                ("poses",), counts, attrs={"units": "1", "long_name": "number of random poses"}
            )
        },
        attrs=meta(c, "simulated", "observability").attrs("metrics"),
    )
    limit, plateau = o2_plateau(counts, values[:, 1], o["tolerance"])
    ds.attrs.update(
        O2_plateau_poses=int(plateau),
        O2_limit=float(limit),
        O2_plateau_tolerance=float(o["tolerance"]),
        repeats=int(o["repeats"]),
    )
    write_dataset(ds, args.out)
