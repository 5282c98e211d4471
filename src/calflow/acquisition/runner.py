"""The acquisition runner: a plan executed on a rig becomes a run dataset.

Per plan row: the controller gives the joint command (the plan's own command when the
run is open loop; a calibration model's command, computed from the latest reading, in a
validation), the rig ``move``\\ s and dwells, and the reading is taken — one ``read`` at
the end of the dwell, or, when the plan averages (Sec. 5.3.2) and the rig streams, the
mean of the dwell's last seconds reduced in bounded memory.

Acquisition is crash-safe when given a journal (:mod:`calflow.acquisition.checkpoint`): rerun after
an interruption, it resumes after the last complete sample, losing and duplicating
nothing. A simulated rig (``rig.replayable``) is brought back to its state by replaying
the recorded rows, and must reproduce them exactly; a real rig simply continues.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
import xarray as xr

from calflow.acquisition.checkpoint import Journal
from calflow.acquisition.streams import reduce_dwell
from calflow.data.runs import RunMetadata, run_dataset
from calflow.errors import RigError
from calflow.instruments.readings import flags
from calflow.plan import Plan

BATCH = 256  # rows per bulk visit: an interruption recomputes at most this many unjournaled rows


class OpenLoop:
    """The plan's commands as they are (characterisation, identification, training)."""

    needs_initial_reading = False

    def __init__(self, plan: Plan):
        self.plan = plan

    def command(self, i: int, visit) -> tuple[dict[str, float], dict]:
        return self.plan.row(i), {}

    def observe(self, i: int, reading: dict) -> None:
        pass


def _same(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(
        (x == y) or (isinstance(x, float) and isinstance(y, float) and np.isnan(x) and np.isnan(y))
        for x, y in ((a[k], b[k]) for k in a)
    )


class _Runner:
    """Moves, dwells and reads on behalf of the plan and its controller."""

    def __init__(self, plan: Plan, rig):
        self.plan, self.rig = plan, rig
        self.streams = plan.average_last_s is not None and hasattr(rig, "stream")

    def settle_and_read(self, command: dict[str, float]) -> dict:
        rig, plan = self.rig, self.plan
        rig.move(command)
        if self.streams:
            row = reduce_dwell(rig.stream(plan.dwell_s), window_s=plan.average_last_s)
            row.pop("n", None)
        else:
            rig.wait(plan.dwell_s)
            row = dict(rig.read())
        reading = {k: float(v) for k, v in row.items()}
        absent = [k for k in ("time", *rig.sensors, *rig.thermometers) if k not in reading]
        if absent:
            raise RigError(f"rig: a reading of plan {plan.name!r} lacks {absent}")
        reading["time"] += plan.start_s
        return reading

    def sample(self, i: int, controller) -> dict:
        command, extra = controller.command(i, self.settle_and_read)
        reading = self.settle_and_read(command)
        reading.update({f"cmd_{j}": float(v) for j, v in command.items()})
        reading.update(extra)
        controller.observe(i, reading)
        return reading

    def visits(self, start: int, stop: int) -> list[dict]:
        """Rows ``start:stop`` of an open-loop plan through the rig's ``visit`` (move, dwell
        and read of every row at once): the readings :meth:`sample` would give, row by row."""
        plan = self.plan
        commands = {j: np.asarray(v[start:stop], dtype=float) for j, v in plan.commands.items()}
        got = self.rig.visit(commands, plan.dwell_s)
        absent = [k for k in ("time", *self.rig.sensors, *self.rig.thermometers) if k not in got]
        if absent:
            raise RigError(f"rig: a reading of plan {plan.name!r} lacks {absent}")
        columns = {k: np.asarray(v, dtype=float).tolist() for k, v in got.items()}
        columns["time"] = (np.asarray(got["time"], dtype=float) + plan.start_s).tolist()
        columns.update({f"cmd_{j}": v.tolist() for j, v in commands.items()})
        return [dict(zip(columns, row)) for row in zip(*columns.values())]


def acquire(
    plan: Plan,
    rig,
    meta: RunMetadata,
    journal: Journal | None = None,
    progress: Callable[[int, int], None] | None = None,
    controller=None,
    stop: Callable[[list[dict], Callable[[], xr.Dataset]], bool] | None = None,
) -> xr.Dataset:
    """Visit every row of ``plan`` on ``rig`` and return the run dataset.

    ``stop(readings, partial)``, when given, is asked after each reading (and once for the
    readings a resumed journal holds); ``partial()`` is the run dataset so far. When it
    answers true the run ends there: the dataset holds the rows visited (a sequential test
    that has decided, e.g. an interim check)."""
    missing = [j for j in plan.commands if j not in rig.joints]
    if missing:
        raise RigError(
            f"rig: plan {plan.name!r} commands joints {missing} the rig does not have {list(rig.joints)}"
        )
    controller = controller or OpenLoop(plan)
    runner = _Runner(plan, rig)
    recorded = journal.load() if journal is not None else []
    start = None
    if getattr(controller, "needs_initial_reading", True):
        # the state before the first move (e.g. temperatures for a thermal model's first command)
        start = {k: float(v) for k, v in dict(rig.read()).items()}
        controller.observe(-1, start)
    offset = 0.0
    if recorded and getattr(rig, "replayable", False):
        for i, row in enumerate(recorded):
            if not _same(runner.sample(i, controller), row):
                raise RigError(
                    f"rig: the simulated rig does not reproduce sample {i} of {journal.path}; "
                    "delete the journal to start over"
                )
    elif recorded:
        for i, row in enumerate(recorded):
            controller.observe(i, row)
        # A real rig's clock restarted with this process: continue the run's time axis,
        # counting the real time that passed while acquisition was down.
        gap = time.time() - journal.last_wall if journal.last_wall is not None else 0.0
        now = start["time"] if start is not None else float(rig.read()["time"])
        offset = recorded[-1]["time"] + max(gap, 0.0) - now - plan.start_s
    readings = list(recorded)
    if journal is not None:
        journal.open(readings)
    # open loop on a rig that visits rows in bulk: the same readings, computed BATCH rows at a time
    bulk = type(controller) is OpenLoop and not runner.streams and hasattr(rig, "visit")
    bulk = bulk and stop is None  # a stop rule looks after every reading

    def partial() -> xr.Dataset:
        return run_dataset(readings, plan, rig.sensors, rig.thermometers, meta, flags(rig.sensors))

    try:
        i = len(readings)
        done = bool(readings) and stop is not None and stop(readings, partial)
        while i < len(plan) and not done:
            for reading in (
                runner.visits(i, min(i + BATCH, len(plan))) if bulk else [runner.sample(i, controller)]
            ):
                reading["time"] += offset
                readings.append(reading)
                if journal is not None:
                    journal.append(reading)
                i += 1
            if progress is not None:
                progress(i, len(plan))
            done = stop is not None and i < len(plan) and stop(readings, partial)
    finally:
        if journal is not None:
            journal.close()
    return run_dataset(readings, plan, rig.sensors, rig.thermometers, meta, flags(rig.sensors))
