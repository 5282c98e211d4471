"""The linear stage's plans: evenly spaced poses, visited forward and back for some cycles."""

from __future__ import annotations

import numpy as np

from calflow.plan import Acquisition, Plan


def _sweep(name: str, positions, cycles: int) -> Plan:
    order = np.concatenate([np.arange(len(positions)), np.arange(len(positions))[::-1]])
    pose = np.tile(order, cycles) + 1
    direction = np.tile(np.repeat([1, -1], len(positions)), cycles)
    cycle = np.repeat(np.arange(cycles), 2 * len(positions))
    x = np.asarray(positions, dtype=float)[pose - 1]
    return Plan(name, {"x": x}, pose, cycle, direction, targets={"x": x}, dwell_s=0.5)


def identification(c, args) -> Acquisition:
    p = c["identification"]
    return Acquisition(
        _sweep("identification", np.linspace(0, p["stroke_um"], p["poses"]), 1), "identification"
    )


def validation(c, args) -> Acquisition:
    p = c["validation"]
    return Acquisition(
        _sweep("validation", np.linspace(0, p["stroke_um"], p["poses"]), p["cycles"]), "validation"
    )
