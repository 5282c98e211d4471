"""The XYΘ plans of a campaign, as ``calflow acquire --plan NAME`` builds them.

Each builder reads its section of the campaign (and the ``calflow acquire`` options) and
returns a :class:`calflow.plan.Acquisition`; :mod:`calflow.xytheta.family` registers them
by name.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from calflow.errors import CalflowError
from calflow.plan import Acquisition
from calflow.xytheta.plans import poses as plans
from calflow.xytheta.plans import sweeps


def _model(args, plan: str):
    from calflow.xytheta.models.ladder import MicroModel

    if not args.model:
        raise CalflowError(f"calflow acquire --plan {plan}: --model MODEL.nc is required")
    return MicroModel.read(args.model[0])


def identification(c: dict, args) -> Acquisition:
    """The identification poses (Sec. 4.5.4): random over the workspace (``plan: random``) or
    designed for the most information in the least rig time (``plan: optimal``,
    :mod:`calflow.xytheta.design.plan`). The run's attribute ``design`` (JSON) holds, written
    before acquisition, the Cramér–Rao σ of every model's parameters and the expected virtual
    rig time under the campaign's noise and time models."""
    import json

    from calflow.xytheta.design import plan as design_plan

    p = c["identification"]
    if p["plan"] == "optimal":
        try:
            if p["design"]["criterion"] == "discrepancy" and getattr(args, "luts", None):
                from calflow.xytheta.design.discrepancy import with_kernel_from_tables

                c = with_kernel_from_tables(c, args.luts)
            plan, record = design_plan.identification_plan(c)
        except ValueError as exc:
            raise CalflowError(f"campaign {c['name']}: {exc}") from None
    else:
        plan = plans.identification(
            p["poses"], p["x_um"], p["y_um"], p["theta_deg"], seed=c["seed"], dwell_s=p["dwell_s"]
        )
        q = np.column_stack([plan.commands["x"], plan.commands["y"], plan.commands["theta"]])
        record = {"criterion": None, **design_plan.bound(c, q)}
    return Acquisition(plan, "identification", attrs={"design": json.dumps({"plan": p["plan"], **record})})


def validation(c: dict, args) -> Acquisition:
    """The validation targets commanded through a model's inverse (Table 4.7)."""
    model = _model(args, "validation")
    v = c["validation"]
    return Acquisition(
        plans.validation(model.inverse, v.get("targets"), v["cycles"], v["dwell_s"]),
        f"validation_{model.name}",
        model.name,
    )


def heldout_seed(c: dict) -> int:
    """The held-out targets' seed: ``validation.heldout.seed``, else one derived from the campaign's."""
    seed = c["validation"]["heldout"].get("seed")
    return (
        int(seed)
        if seed is not None
        else int(np.random.SeedSequence([int(c["seed"]), 9_283]).generate_state(1)[0])
    )


def validation_heldout(c: dict, args) -> Acquisition:
    """Held-out validation through a model's inverse: targets no identification or table saw."""
    from calflow.xytheta.models.kinematics import Parameters

    model = _model(args, "validation_heldout")
    p, h = c["identification"], c["validation"]["heldout"]
    targets = plans.heldout_targets(
        h["targets"], p["x_um"], p["y_um"], p["theta_deg"], Parameters(**p["initial"]), heldout_seed(c)
    )
    plan = dataclasses.replace(
        plans.validation(model.inverse, targets, h["cycles"], c["validation"]["dwell_s"]),
        name="validation_heldout",
    )
    return Acquisition(plan, f"validation_heldout_{model.name}", model.name)


def angle_positions(c: dict, base) -> np.ndarray:
    """World-frame positions (M, 2) of the angle characterisation, µm.

    ``angle_residuals.targets`` when given; else ``angle_residuals.positions`` joint poses
    drawn over the identification workspace at Θ = 0 from their own random stream, put
    in the world frame by the base model's forward kinematics (Eq. 4.18), keeping only
    those whose whole Θ sweep (through the base model's inverse) stays inside the
    identification workspace — a rotation of 5° moves the joints by about a millimetre.
    """
    a, p = c["angle_residuals"], c["identification"]
    if a.get("targets") is not None:
        return np.asarray(a["targets"], dtype=float)
    rng = np.random.default_rng(np.random.SeedSequence([int(c["seed"]), 4_26]))
    out = []
    for _ in range(100 * int(a["positions"])):
        X = p["x_um"][0] + (p["x_um"][1] - p["x_um"][0]) * rng.random()
        Y = p["y_um"][0] + (p["y_um"][1] - p["y_um"][0]) * rng.random()
        x, y = (float(np.ravel(v)[0]) for v in base.forward(np.array([X]), np.array([Y]), np.zeros(1)))
        try:
            q = sweeps.angle_sweep(base.inverse, [(x, y)], a["theta_deg"], a["step_deg"], 2).commands
        except ValueError:  # the sweep leaves the base model's position tables
            continue
        if np.all((q["x"][1:] >= p["x_um"][0]) & (q["x"][1:] <= p["x_um"][1])) and np.all(
            (q["y"][1:] >= p["y_um"][0]) & (q["y"][1:] <= p["y_um"][1])
        ):
            out.append((x, y))
            if len(out) == int(a["positions"]):
                return np.array(out)
    raise CalflowError(
        "angle_residuals.positions: no position found whose Θ sweep stays inside the "
        "identification workspace; widen identification.x_um / y_um or narrow theta_deg"
    )


def angle_residuals(c: dict, args) -> Acquisition:
    """The angle characterisation through a base model (Sec. 4.5.5), for the angle tables.

    Default (``table: angle``): Θ swept forward and backward over ``theta_deg`` in
    ``step_deg`` steps at positions no validation visits (:func:`angle_positions`).
    Opt-in ``table: position_angle``: the thesis's Fig. 4.26 run, at the Table 4.7
    positions (the reference validation's own poses) unless ``targets`` says otherwise.
    """
    model = _model(args, "angle_residuals")
    a = c["angle_residuals"]
    if a["table"] == "position_angle":
        plan = sweeps.angle_residual_plan(
            model.inverse, a.get("targets"), a["angles_deg"], a["cycles"], a["dwell_s"]
        )
    else:
        plan = sweeps.angle_sweep(
            model.inverse, angle_positions(c, model), a["theta_deg"], a["step_deg"], a["cycles"], a["dwell_s"]
        )
    return Acquisition(plan, f"angle_residuals_{model.name}", model.name, attrs={"angle_table": a["table"]})


def _characterisation(axis: str):
    def build(c: dict, args) -> Acquisition:
        ch = c["characterisation"]
        plan = sweeps.characterisation(
            axis, ch[f"{axis}_stop_um"], ch["step_um"], ch["cycles"], ch["dwell_s"]
        )
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
    from calflow.xytheta.tables.position import PositionLUT

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
    plan = sweeps.square(
        s["side_um"],
        s["origin_um"],
        s["points_per_segment"],
        s["cycles"],
        _compensation(c, args),
        dwell_s=xy["dwell_s"],
    )
    return Acquisition(plan, f"square_{args.compensation}", attrs={"compensation": args.compensation})


def random_points(c: dict, args) -> Acquisition:
    """The random points of Table 4.3, with or without table compensation."""
    xy = c["xy_tests"]
    r = xy["random_points"]
    plan = sweeps.random_points(r["cycles"], r.get("targets"), _compensation(c, args), dwell_s=xy["dwell_s"])
    return Acquisition(plan, f"random_points_{args.compensation}", attrs={"compensation": args.compensation})
