"""The acquisition runner: a plan executed on a rig becomes a run dataset."""

from __future__ import annotations

from typing import Callable

import xarray as xr

from calflow.data.runs import RunMetadata, run_dataset
from calflow.errors import RigError
from calflow.plans import Plan


def acquire(plan: Plan, rig, meta: RunMetadata,
            progress: Callable[[int, int], None] | None = None) -> xr.Dataset:
    """Visit every row of ``plan`` on ``rig`` and return the run dataset.

    Per row: ``move`` to the command, ``wait`` the plan's dwell, ``read`` once.
    """
    missing = [j for j in plan.commands if j not in rig.joints]
    if missing:
        raise RigError(f"rig: plan {plan.name!r} commands joints {missing} the rig does not have {list(rig.joints)}")
    readings = []
    for i in range(len(plan)):
        rig.move(plan.row(i))
        rig.wait(plan.dwell_s)
        reading = dict(rig.read())
        absent = [k for k in ("time", *rig.sensors, *rig.thermometers) if k not in reading]
        if absent:
            raise RigError(f"rig: read() after row {i} lacks {absent}")
        readings.append(reading)
        if progress is not None:
            progress(i + 1, len(plan))
    return run_dataset(readings, plan, rig.sensors, rig.thermometers, meta)
