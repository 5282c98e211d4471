"""The hexapod plans of a campaign, as ``calflow acquire --plan NAME`` builds them.

Each builder reads its section of the campaign (and the ``calflow acquire`` options) and
returns a :class:`calflow.plan.Acquisition`; the family registers them by name:
``identification`` (random or designed, the design's bound written before acquisition),
``validation_heldout`` (targets no identification saw, through a model's inverse) and
``iso9283`` (the five ISO 9283 poses, 30 cycles by default, through a model's inverse).
"""

from __future__ import annotations

import json

import numpy as np

from calflow.errors import CalflowError
from calflow.plan import Acquisition
from calflow_hexapod.models.geometry import AXES
from calflow_hexapod.plans import design as design_plan
from calflow_hexapod.plans import poses as plans


def _model(args, plan: str):
    """The model of ``--model`` (:class:`calflow_hexapod.models.calibration.HexapodModel`)."""
    from calflow_hexapod.models.calibration import HexapodModel

    if not getattr(args, "model", None):
        raise CalflowError(f"calflow acquire --plan {plan}: --model MODEL.nc is required")
    return HexapodModel.read(args.model[0])


def identification(c: dict, args) -> Acquisition:
    """The identification poses: random over the workspace (``plan: random``) or designed
    (``plan: optimal``, :mod:`calflow_hexapod.plans.design`). The run's attribute ``design``
    (JSON) holds, written before acquisition, the Cramér–Rao σ of every model's parameters
    and the expected virtual rig time."""
    p = c["identification"]
    try:
        if p.get("plan", "random") == "optimal":
            q, record = design_plan.designed_poses(c)
            plan = plans._plan("identification", q, dwell_s=p["dwell_s"])
        else:
            plan = plans.identification(p["poses"], p["fraction"], c["seed"], p["dwell_s"])
            record = {"criterion": None}
    except ValueError as exc:
        raise CalflowError(f"campaign {c['name']}: {exc}") from None
    q = np.column_stack([plan.commands[a] for a in AXES])
    record = {"plan": p.get("plan", "random"), **record, **design_plan.bound(c, q)}
    return Acquisition(plan, "identification", attrs={"design": json.dumps(record)})


def heldout_seed(c: dict) -> int:
    """The held-out targets' seed: ``validation.heldout.seed``, else one derived from the campaign's."""
    seed = c["validation"]["heldout"].get("seed")
    if seed is not None:
        return int(seed)
    return int(np.random.SeedSequence([int(c["seed"]), 9_283]).generate_state(1)[0])


def heldout_targets(c: dict) -> np.ndarray:
    """The campaign's held-out targets (n, 6) in the measurement frame (:func:`plans.heldout_targets`)."""
    h = c["validation"]["heldout"]
    fraction = float(h.get("fraction", c["identification"]["fraction"]))
    margin = float(h.get("margin_um", plans.MARGIN_UM))
    return plans.heldout_targets(
        h["targets"], fraction, design_plan.nominal_parameters(c), heldout_seed(c), margin
    )


def validation_heldout(c: dict, args) -> Acquisition:
    """Held-out validation through a model's inverse: targets no identification saw."""
    model = _model(args, "validation_heldout")
    h = c["validation"]["heldout"]
    try:
        plan = plans.validation(model.command, heldout_targets(c), h["cycles"], c["validation"]["dwell_s"])
    except ValueError as exc:
        raise CalflowError(f"campaign {c['name']}: {exc}") from None
    return Acquisition(plan, f"validation_heldout_{model.name}", model.name)


def iso9283(c: dict, args) -> Acquisition:
    """ISO 9283 pose accuracy and repeatability (Sec. 7.2): the five poses P1–P5 of the test
    cube (``iso9283.fraction`` of the travel, at ``iso9283.orientation_deg``), as targets the
    nominal model maps to the measurement frame, ``iso9283.cycles`` cycles (30 in the
    standard) through a model's inverse."""
    s = c["iso9283"]
    try:
        q = plans.iso9283_commands(float(s["fraction"]), s.get("orientation_deg", (0.0, 0.0, 0.0)))
    except ValueError as exc:
        raise CalflowError(f"campaign {c['name']}: {exc}") from None
    model = _model(args, "iso9283")
    targets = plans.target_of(q, design_plan.nominal_parameters(c))
    plan = plans.validation(
        model.command,
        targets,
        int(s.get("cycles", 30)),
        s.get("dwell_s", c["validation"]["dwell_s"]),
        name="iso9283",
    )
    return Acquisition(plan, f"iso9283_{model.name}", model.name)
