"""Recorded moves of the ``gcs`` rig: a step response through the controller's data recorder.

``record_move(command, seconds, rate_hz)`` is the contract of the simulated nano rigs'
(the nano family's stage records) that :mod:`calflow.acquisition.recorded_moves` runs for
ISO 9283 stabilisation time and overshoot (clauses 7.5, 7.6): move, and record from the
start of the move, point i at ``t0 + i / rate_hz``, for ``seconds``; chunks of numpy arrays
with ``time`` (s, the rig's clock), every sensor and thermometer.

Through a GCS 2.0 piezo controller (E-727 / E-709 class; docs/gcs.md "Recorded moves"):

1. ``DRC {<table> <axis> 2}``: one record table per axis of the controller driving the
   commanded joints, its current position (the controller's own, capacitive, sensor);
2. ``RTR <cycles>``: one point every ``round(1 / (rate_hz * servo_cycle_s))`` servo cycles
   (the record table rate; ``servo_cycle_s`` is the rig's ``recorder`` option, 50 µs on
   the E-727), so the record's rate is the one the controller can do, read back from the
   array header's ``SAMPLE_TIME``;
3. ``DRT 0 1 0``: trigger source 1, the next command that changes a target position;
4. ``MOV``: the recording starts with it (point 1 of the tables is the move's start);
5. the dwell of ``seconds``, then on target (``ONT?``), like the rig's ``move``;
6. ``DRL?`` until the points are there, ``DRR? 1 <n> <tables>``.

The data recorder sees only the controller's sensor. The external sensor (the
interferometer) is another instrument: the sensor plug-in's ``record_move(positions,
times)`` reads it at the recorder's point times for a move started at the first of them
to the positions ``POS?`` reports once on target (the simulated interferometer does; a
sensor without it is refused with one line). The controller's record is returned beside
it as ``pos_<joint>`` (rig units).
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator, Mapping

import numpy as np

from calflow.errors import RigError

TRIGGER_ON_TARGET_CHANGE = 1  # DRT trigger source: next command that changes a target (MOV)
CURRENT_POSITION = 2  # DRC record option: the axis's sensor


class RecordedMoves:
    """``record_move`` of :class:`calflow.gcs.rig.GCSRig` (module docstring)."""

    def record_move(
        self, command: Mapping[str, float], seconds: float, rate_hz: float | None = None, chunk: int = 4096
    ) -> Iterator[dict[str, np.ndarray]]:
        """Move to ``command`` (rig units) recording from the move's start for ``seconds``
        at ``rate_hz`` (default: the ``recorder`` option ``rate_hz``); see the module doc."""
        if self._closed:
            raise RigError("gcs rig: record_move() after close()")
        rate = float(self.recorder.get("rate_hz", 10.0) if rate_hz is None else rate_hz)
        if not (rate > 0 and math.isfinite(rate) and float(seconds) >= 0 and int(chunk) > 0):
            raise RigError("gcs rig: record_move needs seconds >= 0, rate_hz > 0 and chunk > 0")
        if not hasattr(self.sensor, "record_move"):
            raise RigError(
                f"gcs rig: sensor {type(self.sensor).__name__} cannot be read along a move "
                "(no record_move(positions, times)); the controller's data recorder records "
                "only its own sensor"
            )
        link = self._recording_link(command)
        n = int(math.floor(float(seconds) * rate + 1e-9))
        cycle = float(self.recorder.get("servo_cycle_s", 5e-5))
        tables = {i + 1: (a, CURRENT_POSITION) for i, a in enumerate(link.axes)}
        self._run(
            link,
            "DRC",
            lambda retry: link.ctl.configure_recorder(tables, max(1, round(1.0 / (rate * cycle)))),
        )
        self._recording = False  # stream() sets its own rate again
        self._run(link, "DRT", lambda retry: link.ctl.arm_recorder(TRIGGER_ON_TARGET_CHANGE))
        targets = {a: float(command[j]) / self.scale[j] for j, a in link.joints.items() if j in command}
        started = self.time()
        self._run(link, "MOV", lambda retry: link.ctl.move(targets))  # MOV is absolute: a resend is harmless
        self.wait(seconds)
        settled = self._run(
            link,
            "wait on target",
            lambda retry: link.ctl.wait_on_target(
                timeout=self.move_timeout_s, poll=self.poll_s, axes=list(targets)
            ),
        )
        header, data = self._run(link, "DRR?", lambda retry: self._read_points(link, list(tables), n))
        dt = float(header.get("SAMPLE_TIME", cycle))
        times = started + dt * np.arange(n)
        positions = {j: settled.get(a, np.nan) * self.scale[j] for j, a in link.joints.items()}
        values = self._sensor("record_move", positions, times)
        record = {
            "time": times,
            **{k: np.asarray(values[k], dtype=float) for k in (*self.sensors, *self.thermometers)},
            **{f"pos_{j}": data[:, i] * self.scale[j] for i, j in enumerate(link.joints)},
        }
        return iter([{k: v[s : s + int(chunk)] for k, v in record.items()} for s in range(0, n, int(chunk))])

    def _recording_link(self, command: Mapping[str, float]):
        unknown = sorted(set(command) - set(self.joints))
        if unknown:
            raise RigError(f"gcs rig: command names joints {unknown}; the rig has {list(self.joints)}")
        links = [link for link in self.links if set(command) & set(link.joints)]
        if len(links) != 1:
            raise RigError(
                "gcs rig: record_move needs the commanded joints on one controller (one data "
                f"recorder triggered by one MOV); {sorted(command)} are on {len(links)}"
            )
        return links[0]

    def _read_points(self, link, tables: list[int], n: int):
        """``DRL?`` until ``n`` points are recorded (bounded by ``move_timeout_s``), ``DRR?``."""
        deadline = time.monotonic() + self.move_timeout_s
        while link.ctl.recorded_points(tables[0]) < n:
            if time.monotonic() > deadline:
                raise RigError(
                    f"gcs rig: {link.name}: the data recorder has not recorded {n} points "
                    f"after {self.move_timeout_s} s"
                )
            time.sleep(self.poll_s)
        return link.ctl.read_recorder(tables, first=1, count=n)
