"""The acquisition runner: a plan executed on a rig becomes a run dataset.

Acquisition is crash-safe when given a journal (:mod:`calflow.checkpoint`): rerun after
an interruption, it resumes after the last complete sample, losing and duplicating
nothing. A simulated rig (``rig.replayable``) is brought back to its state by replaying
the recorded rows, and must reproduce them exactly; a real rig simply continues.
"""

from __future__ import annotations

import sys
import time
from typing import Callable

import numpy as np
import xarray as xr

from calflow.checkpoint import Journal
from calflow.data.runs import RunMetadata, run_dataset
from calflow.errors import RigError
from calflow.plans import Plan


def _same(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(
        (x == y) or (isinstance(x, float) and isinstance(y, float) and np.isnan(x) and np.isnan(y))
        for x, y in ((a[k], b[k]) for k in a)
    )


def _sample(rig, plan: Plan, i: int) -> dict:
    rig.move(plan.row(i))
    rig.wait(plan.dwell_s)
    reading = {k: float(v) for k, v in dict(rig.read()).items()}
    absent = [k for k in ("time", *rig.sensors, *rig.thermometers) if k not in reading]
    if absent:
        raise RigError(f"rig: read() after row {i} of plan {plan.name!r} lacks {absent}")
    return reading


def acquire(plan: Plan, rig, meta: RunMetadata, journal: Journal | None = None,
            progress: Callable[[int, int], None] | None = None) -> xr.Dataset:
    """Visit every row of ``plan`` on ``rig`` and return the run dataset.

    Per row: ``move`` to the command, ``wait`` the plan's dwell, ``read`` once.
    """
    missing = [j for j in plan.commands if j not in rig.joints]
    if missing:
        raise RigError(f"rig: plan {plan.name!r} commands joints {missing} the rig does not have {list(rig.joints)}")
    readings = journal.load() if journal is not None else []
    offset = 0.0
    if readings and getattr(rig, "replayable", False):
        for i, recorded in enumerate(readings):
            if not _same(_sample(rig, plan, i), recorded):
                raise RigError(f"rig: the simulated rig does not reproduce sample {i} of {journal.path}; "
                               "delete the journal to start over")
    elif readings:
        # A real rig's clock restarted with this process: continue the run's time axis,
        # counting the real time that passed while acquisition was down.
        gap = time.time() - journal.last_wall if journal.last_wall is not None else 0.0
        offset = readings[-1]["time"] + max(gap, 0.0) - float(rig.read()["time"])
    if journal is not None:
        journal.open(readings)
    try:
        for i in range(len(readings), len(plan)):
            reading = _sample(rig, plan, i)
            reading["time"] += offset
            readings.append(reading)
            if journal is not None:
                journal.append(reading)
            if progress is not None:
                progress(i + 1, len(plan))
    finally:
        if journal is not None:
            journal.close()
    return run_dataset(readings, plan, rig.sensors, rig.thermometers, meta)


def terminal_progress(label: str, stream=sys.stderr) -> Callable[[int, int], None] | None:
    """A progress bar with an ETA when ``stream`` is a terminal, else ``None``."""
    if not stream.isatty():
        return None
    start = time.monotonic()
    last = [0.0]

    def show(done: int, total: int) -> None:
        now = time.monotonic()
        if done < total and now - last[0] < 0.2:
            return
        last[0] = now
        frac = done / total
        eta = (now - start) / frac * (1 - frac) if frac else float("nan")
        bar = "#" * int(30 * frac)
        stream.write(f"\r{label} [{bar:<30}] {done}/{total} ETA {eta:6.0f} s")
        if done == total:
            stream.write("\n")
        stream.flush()

    return show
