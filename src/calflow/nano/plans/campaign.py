"""The nanopositioning plans of a campaign, as ``calflow acquire --plan NAME`` builds them.

Each builder reads its section of the campaign and returns a
:class:`calflow.plan.Acquisition`; :mod:`calflow.nano.family` registers them by name.
"""

from __future__ import annotations

import json

import numpy as np

from calflow.nano.plans import sequences as plans
from calflow.plan import Acquisition


def _grid(section: dict) -> np.ndarray:
    return np.arange(section["start_um"], section["stop_um"] + 1e-9, section["step_um"])


def _training(c: dict, build) -> Acquisition:
    """The training run: the grid of the thesis (``training.plan: grid``) or the designed
    positions and cycles (``optimal``, :mod:`calflow.nano.plans.designed`); either way the run's
    attribute ``design`` (JSON) holds, written before acquisition, the plan's Cramér–Rao bound."""
    from calflow.nano.plans import designed as design_plan

    t = c["training"]
    if t["plan"] == "optimal":
        positions, cycles, record = design_plan.designed_plan(c)
        rows = len(design_plan.cycle_rows(c, positions)) * cycles
        start = design_plan.start_s(c, rows * design_plan.reading_s(c))
    else:
        positions, cycles, record, start = (
            design_plan.grid_positions(c),
            t["cycles"],
            {"criterion": None},
            0.0,
        )
    plan = build(positions, cycles, start)
    record = {
        "plan": t["plan"],
        **record,
        **design_plan.bound(c, positions, cycles),
        "start_h": start / 3600.0,
    }
    return Acquisition(plan, "training", attrs={"design": json.dumps(record)})


def training_1d(c: dict, args) -> Acquisition:
    """Forward and backward cycles over the stroke in the training period (Sec. 5.3.2, Fig. 5.8)."""
    t = c["training"]
    return _training(
        c,
        lambda p, cycles, start: plans.training_1d(
            np.sort(p[:, 0]), cycles, t["dwell_s"], t["average_last_s"], start
        ),
    )


def metrology_1d(c: dict, args) -> Acquisition:
    """The metrology-room run of Sec. 5.3.3 (intrinsic accuracy and repeatability)."""
    m = c["metrology"]
    return Acquisition(
        plans.metrology_1d(_grid(m), m["cycles"], m["dwell_s"], m["average_last_s"]), "metrology"
    )


def _controller(plan, c: dict, args):
    from calflow.nano.models.controllers import nano_validation_controller

    return nano_validation_controller(plan, args.model or [], c)


def _validation(sequence, targets, c: dict, args) -> Acquisition:
    """The validation ``sequence`` (1-DoF or 2-DoF) over ``targets`` as the campaign's
    ``validation`` section sets it, every test through its mode's run-time controller."""
    v = c["validation"]
    plan = sequence(
        targets,
        cycles=v["cycles"],
        dwell_s=v["dwell_s"],
        tests=v["tests"],
        order=tuple(v["order"]),
        average_last_s=v["average_last_s"],
        start_s=v["start_h"] * 3600.0,
    )
    return Acquisition(plan, "validation", controller=_controller(plan, c, args))


def validation_1d(c: dict, args) -> Acquisition:
    """The five-day validation: every test through each mode's run-time controller (Fig. 5.9)."""
    return _validation(plans.validation_1d, _grid(c["validation"]), c, args)


def training_2d(c: dict, args) -> Acquisition:
    """The 2-DoF training grid (Sec. 5.4.1, Fig. 5.21)."""
    from calflow.nano.plans.design import raster

    t = c["training"]
    if t["plan"] == "grid":
        return _training(
            c,
            lambda p, cycles, start: plans.training_2d(
                t["step_um"], t["stop_um"], cycles, t["dwell_s"], t["average_last_s"], start, t["start_um"]
            ),
        )
    return _training(
        c,
        lambda p, cycles, start: plans.training_points_2d(
            p[raster(p)], cycles, t["dwell_s"], t["average_last_s"], start
        ),
    )


def validation_2d(c: dict, args) -> Acquisition:
    """The six validation points of Sec. 5.4.2 (Fig. 5.22) through the run-time controllers."""
    v = c["validation"]
    return _validation(plans.validation_2d, np.asarray(v["points_um"], dtype=float), c, args)


def step_response(c: dict, args) -> Acquisition:
    """Recorded steps of the stage (ISO 9283 7.5, 7.6), open loop, each move recorded from its start."""
    from calflow.acquisition.recorded_moves import acquire_recorded_moves

    s = c["step_response"]
    base = [s["base_um"]] * (2 if c["robot"] == "stage2d" else 1)
    plan = plans.step_response(
        s["steps_um"], s["cycles"], base, s["record_s"], s["rate_hz"], s["attained_last_s"]
    )
    attrs = {"band_nm": float(s["band_nm"])} if "band_nm" in s else {}
    return Acquisition(plan, "step_response", runner=acquire_recorded_moves, attrs=attrs)
