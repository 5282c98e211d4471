"""Acquire a plan of recorded moves: each row's approach as the rig's data recorder sees it.

For the ISO 9283 position stabilisation time and overshoot (clauses 7.5, 7.6) a run must
keep the record of each approach, not only the settled reading. Per plan row the rig
``record_move``\\ s (moves and records its sensors from the start of the move at the
plan's ``record_rate_hz`` for ``record_s``, like a controller's data recorder triggered by
the move command); the row's reading is the mean of the record's last ``average_last_s``
seconds (the attained position P_a, :func:`calflow.acquisition.streams.reduce_dwell`).
Before the first row the stage moves (unrecorded) to the plan's last command, so the first
cycle's first step is the same step as in the other cycles.

The run dataset (``calflow_kind = "run"``) has the usual ``sample`` rows plus, per sample
and ``record`` point: ``record_time`` (s since the start of the move) and ``record_<sensor>``
(the sensor's unit); ``move_start`` is the CF time of each move and ``step_<joint>`` the
commanded step (um). The run is short (seconds of rig time): it is not journaled, an
interrupted one starts over.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import xarray as xr

from calflow.acquisition.streams import reduce_dwell
from calflow.data.conventions import run_variables, time_units
from calflow.data.runs import RunMetadata, run_dataset
from calflow.errors import RigError
from calflow.instruments.readings import flags
from calflow.plan import Plan

__all__ = ["acquire_recorded_moves"]


def _record(rig, plan: Plan, command: dict, rate_hz: float, seconds: float) -> dict[str, np.ndarray]:
    chunks = list(rig.record_move(command, seconds, rate_hz))
    names = ("time", *rig.sensors, *rig.thermometers)
    absent = [k for k in names if not chunks or k not in chunks[0]]
    if absent:
        raise RigError(f"rig: a record of plan {plan.name!r} lacks {absent}")
    return {k: np.concatenate([np.asarray(c[k], dtype=float) for c in chunks]) for k in names}


def acquire_recorded_moves(
    plan: Plan,
    rig,
    meta: RunMetadata,
    journal=None,
    progress: Callable[[int, int], None] | None = None,
    controller=None,
) -> xr.Dataset:
    """Run ``plan`` (with ``extra["record_s"]`` and ``extra["record_rate_hz"]`` per row, one
    value) on ``rig``, recording every move (module docstring); ``journal`` and ``controller``
    are accepted for the runner's signature: the plan is open loop and not journaled."""
    if not hasattr(rig, "record_move"):
        raise RigError(
            f"rig {type(rig).__name__}: plan {plan.name!r} records the approach of each move and this rig "
            "has no record_move (a data recorder triggered by the move command)"
        )
    if controller is not None:
        raise RigError(f"plan {plan.name!r}: recorded moves are open loop; got a run-time controller")
    seconds, rate = float(plan.extra["record_s"][0]), float(plan.extra["record_rate_hz"][0])
    if not (plan.average_last_s and 0 < plan.average_last_s < seconds):
        raise ValueError(f"plan {plan.name!r}: average_last_s must lie in (0, record_s = {seconds}) s")
    readings, records, starts, steps = [], [], [], []
    previous = plan.row(len(plan) - 1)
    rig.move(previous)  # start where the plan ends, so every cycle's first step is like the others
    for i in range(len(plan)):
        command = plan.row(i)
        rec = _record(rig, plan, command, rate, seconds)  # record_move: point 0 at the move's start
        row = reduce_dwell([rec], window_s=plan.average_last_s)
        row.pop("n", None)
        row["time"] += plan.start_s
        readings.append({**row, **{f"cmd_{j}": v for j, v in command.items()}})
        records.append(rec)
        starts.append(float(rec["time"][0]))
        steps.append({j: command[j] - previous[j] for j in command})
        previous = command
        if progress is not None:
            progress(i + 1, len(plan))
    ds = run_dataset(readings, plan, rig.sensors, rig.thermometers, meta, flags(rig.sensors))
    n = min(r["time"].size for r in records)
    rel = np.array([r["time"][:n] for r in records]) - np.array(starts)[:, None]
    ds["record_time"] = xr.Variable(
        ("sample", "record"),
        rel,
        attrs={"units": "s", "long_name": "time of the record point since the start of the move"},
    )
    for name in rig.sensors:
        units, long_name = run_variables()[name]
        ds[f"record_{name}"] = xr.Variable(
            ("sample", "record"),
            np.array([r[name][:n] for r in records]),
            attrs={"units": units, "long_name": f"{long_name}, recorded during the move"},
        )
    ds["move_start"] = xr.Variable(
        ("sample",),
        np.array(starts) + plan.start_s,
        attrs={"units": time_units(meta.start), "long_name": "time the move started"},
    )
    for j in plan.commands:
        ds[f"step_{j}"] = xr.Variable(
            ("sample",),
            np.array([s[j] for s in steps]),
            attrs={"units": "um", "long_name": f"commanded step of joint {j}"},
        )
    ds.attrs.update(record_s=seconds, record_rate_hz=rate)
    return ds
