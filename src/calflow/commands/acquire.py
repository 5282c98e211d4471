"""``calflow acquire``: build a run's plan from the campaign, run it on the rig, write the run."""

from __future__ import annotations

from calflow.commands.common import campaign as load, meta, open_rig
from calflow.errors import CalflowError

XYTHETA_PLANS = ("identification", "validation", "characterisation_x", "characterisation_y",
                 "angle_residuals", "square", "random_points")
NANO_PLANS = ("training", "metrology", "validation")


def _xytheta_plan(c: dict, args):
    from calflow.models.micro import MicroModel
    from calflow.plans import sweeps
    from calflow.plans import xytheta as plans

    model = MicroModel.read(args.model[0]) if args.model else None
    if args.plan in ("validation", "angle_residuals") and model is None:
        raise CalflowError(f"calflow acquire --plan {args.plan}: --model MODEL.nc is required")
    if args.plan == "identification":
        p = c["identification"]
        return plans.identification(p["poses"], p["x_um"], p["y_um"], p["theta_deg"], seed=c["seed"],
                                    dwell_s=p["dwell_s"]), None
    if args.plan == "validation":
        v = c["validation"]
        return plans.validation(model.inverse, v.get("targets"), v["cycles"], v["dwell_s"]), model.name
    if args.plan == "angle_residuals":
        a = c["angle_residuals"]
        return sweeps.angle_residual_plan(model.inverse, a.get("targets"), a["angles_deg"], a["cycles"],
                                          a["dwell_s"]), model.name
    if args.plan in ("characterisation_x", "characterisation_y"):
        ch = c["characterisation"]
        axis = args.plan[-1]
        return sweeps.characterisation(axis, ch[f"{axis}_stop_um"], ch["step_um"], ch["cycles"], ch["dwell_s"]), None
    # square / random_points, with or without lookup-table compensation (Sec. 4.4.2)
    xy = c["xy_tests"]
    compensate = None
    if args.compensation != "none":
        from calflow.data.io import open_dataset
        from calflow.lookup import PositionLUT

        if not args.luts:
            raise CalflowError(f"calflow acquire --compensation {args.compensation}: --luts LUTS.nc is required")
        # targets beyond the characterised stroke take the table's end value (Table 4.3 has
        # points above the 3.78 mm of Y the pattern allows on this rig)
        lut = PositionLUT.from_dataset(open_dataset(args.luts, kind="luts"), bounds="clamp")

        def compensate(x_T, y_T, dx, dy):
            return lut.compensate(x_T, y_T, dx, dy, method=args.compensation, iterations=xy["iterations"])
    if args.plan == "square":
        s = xy["square"]
        plan = sweeps.square(s["side_um"], s["origin_um"], s["points_per_segment"], s["cycles"], compensate,
                             dwell_s=xy["dwell_s"])
    else:
        plan = sweeps.random_points(xy["random_points"]["cycles"], xy["random_points"].get("targets"), compensate,
                                    dwell_s=xy["dwell_s"])
    return plan, None


def _nano_plan(c: dict, args):
    import numpy as np

    from calflow.plans import nano

    t, v = c["training"], c["validation"]
    grid = np.arange(t["start_um"], t["stop_um"] + 1e-9, t["step_um"])
    if c["robot"] == "stage1d":
        if args.plan == "training":
            return nano.training_1d(grid, t["cycles"], t["dwell_s"], t["average_last_s"], 0.0)
        pos = np.arange(v["start_um"], v["stop_um"] + 1e-9, v["step_um"])
        if args.plan == "metrology":
            m = c["metrology"]
            mpos = np.arange(m["start_um"], m["stop_um"] + 1e-9, m["step_um"])
            return nano.metrology_1d(mpos, m["cycles"], m["dwell_s"], m["average_last_s"])
        return nano.validation_1d(pos, v["cycles"], v["dwell_s"], v["tests"], tuple(v["order"]),
                                  v["average_last_s"], start_s=v["start_h"] * 3600.0)
    if args.plan == "training":
        return nano.training_2d(t["step_um"], t["stop_um"], t["cycles"], t["dwell_s"], t["average_last_s"])
    if args.plan == "validation":
        return nano.validation_2d(np.asarray(v["points_um"], dtype=float), v["cycles"], v["tests"], v["dwell_s"],
                                  tuple(v["order"]), v["average_last_s"], start_s=v["start_h"] * 3600.0)
    raise CalflowError(f"calflow acquire: --plan {args.plan!r} is not a plan of a {c['robot']} campaign")


def run(args) -> None:
    from calflow.acquisition import acquire, terminal_progress
    from calflow.checkpoint import Journal, plan_digest
    from calflow.data.io import write_dataset, write_json

    c = load(args.campaign)
    controller = None
    if c["robot"] == "xytheta":
        if args.plan not in XYTHETA_PLANS:
            raise CalflowError(f"calflow acquire: --plan {args.plan!r} is not a plan of an xytheta campaign")
        plan, model_name = _xytheta_plan(c, args)
        run_id = args.plan if model_name is None else f"{args.plan}_{model_name}"
        if args.plan in ("square", "random_points"):
            run_id = f"{args.plan}_{args.compensation}"
    else:
        if args.plan not in NANO_PLANS:
            raise CalflowError(f"calflow acquire: --plan {args.plan!r} is not a plan of a {c['robot']} campaign")
        plan, model_name, run_id = _nano_plan(c, args), None, args.plan
        if args.plan == "validation":
            from calflow.controllers import nano_validation_controller

            controller = nano_validation_controller(plan, args.model or [], c)
    rig, source = open_rig(c, run_id, plan.start_s)
    journal = Journal(f"{args.out}.journal", plan_digest(plan))
    try:
        ds = acquire(plan, rig, meta(c, source, args.plan, model_name), journal,
                     terminal_progress(f"{c['name']} {run_id}"), controller)
        truth = rig.truth() if hasattr(rig, "truth") else {"available": False}
    finally:
        rig.close()
    if args.plan in ("square", "random_points"):
        ds.attrs["compensation"] = args.compensation
    if args.truth:
        write_json(truth, args.truth)
    write_dataset(ds, args.out)
    journal.close(remove=True)
