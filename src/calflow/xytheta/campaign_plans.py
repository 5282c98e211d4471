"""The XYΘ plans of a campaign, as ``calflow acquire --plan NAME`` builds them.

Each builder reads its section of the campaign (and the ``calflow acquire`` options) and
returns a :class:`calflow.plan.Acquisition`; :mod:`calflow.xytheta.family` registers them
by name.
"""

from __future__ import annotations

from calflow.errors import CalflowError
from calflow.plan import Acquisition
from calflow.xytheta import plans, sweeps


def _model(args, plan: str):
    from calflow.xytheta.models import MicroModel

    if not args.model:
        raise CalflowError(f"calflow acquire --plan {plan}: --model MODEL.nc is required")
    return MicroModel.read(args.model[0])


def identification(c: dict, args) -> Acquisition:
    """Random poses over the identification workspace (Sec. 4.5.4)."""
    p = c["identification"]
    return Acquisition(plans.identification(p["poses"], p["x_um"], p["y_um"], p["theta_deg"], seed=c["seed"],
                                            dwell_s=p["dwell_s"]), "identification")


def validation(c: dict, args) -> Acquisition:
    """The validation targets commanded through a model's inverse (Table 4.7)."""
    model = _model(args, "validation")
    v = c["validation"]
    return Acquisition(plans.validation(model.inverse, v.get("targets"), v["cycles"], v["dwell_s"]),
                       f"validation_{model.name}", model.name)


def angle_residuals(c: dict, args) -> Acquisition:
    """Angle sweeps commanded through a base model (Fig. 4.26), for the angle tables."""
    model = _model(args, "angle_residuals")
    a = c["angle_residuals"]
    plan = sweeps.angle_residual_plan(model.inverse, a.get("targets"), a["angles_deg"], a["cycles"], a["dwell_s"])
    return Acquisition(plan, f"angle_residuals_{model.name}", model.name)


def _characterisation(axis: str):
    def build(c: dict, args) -> Acquisition:
        ch = c["characterisation"]
        plan = sweeps.characterisation(axis, ch[f"{axis}_stop_um"], ch["step_um"], ch["cycles"], ch["dwell_s"])
        return Acquisition(plan, f"characterisation_{axis}")

    build.__doc__ = f"Forward and backward sweeps of the {axis.upper()} stage (Sec. 4.4.1)."
    return build


characterisation_x = _characterisation("x")
characterisation_y = _characterisation("y")


def _compensation(c: dict, args):
    """The lookup-table correction of Sec. 4.4.2 (Eq. 4.14, 4.15), or None."""
    if args.compensation == "none":
        return None
    from calflow.data.io import open_dataset
    from calflow.xytheta.lookup import PositionLUT

    if not args.luts:
        raise CalflowError(f"calflow acquire --compensation {args.compensation}: --luts LUTS.nc is required")
    # targets beyond the characterised stroke take the table's end value (Table 4.3 has
    # points above the 3.78 mm of Y the pattern allows on this rig)
    lut = PositionLUT.from_dataset(open_dataset(args.luts, kind="luts"), bounds="clamp")
    iterations = c["xy_tests"]["iterations"]

    def compensate(x_T, y_T, dx, dy):
        return lut.compensate(x_T, y_T, dx, dy, method=args.compensation, iterations=iterations)

    return compensate


def square(c: dict, args) -> Acquisition:
    """The 4 × 4 mm square of Sec. 4.4.2, with or without table compensation."""
    xy = c["xy_tests"]
    s = xy["square"]
    plan = sweeps.square(s["side_um"], s["origin_um"], s["points_per_segment"], s["cycles"],
                         _compensation(c, args), dwell_s=xy["dwell_s"])
    return Acquisition(plan, f"square_{args.compensation}", attrs={"compensation": args.compensation})


def random_points(c: dict, args) -> Acquisition:
    """The random points of Table 4.3, with or without table compensation."""
    xy = c["xy_tests"]
    r = xy["random_points"]
    plan = sweeps.random_points(r["cycles"], r.get("targets"), _compensation(c, args), dwell_s=xy["dwell_s"])
    return Acquisition(plan, f"random_points_{args.compensation}", attrs={"compensation": args.compensation})
