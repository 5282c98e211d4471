"""The GCS data recorder: record tables, trigger, rate, and the GCS array format of ``DRR?``.

GCS 2.0 data recorder semantics (PI E-727 / E-709 user manuals, "Data Recorder"; command
descriptions DRC, DRC?, DRT, DRT?, RTR, RTR?, DRL?, DRR?, TNR?):

* ``DRC {<RecTableID> <Source> <RecOption>}`` says what a record table records: ``Source``
  is an axis, ``RecOption`` 0 (nothing), 1 (target position) or 2 (current position, the
  controller's sensor);
* ``DRT <RecTableID> <TriggerSource> <Value>`` (table 0: all tables) arms the recording:
  0 (default) and 1 start it with the next command that changes a target position
  (``MOV``), 2 with the next command of any kind;
* ``RTR <Rate>``: one point every ``Rate`` servo cycles; ``DRL? [{<RecTableID>}]``: points
  recorded so far; the recorder stops when a table is full;
* ``DRR? [<StartPoint> [<NumberOfPoints> [{<RecTableID>}]]]`` answers in the GCS array
  format: header lines ``# KEY = VALUE`` (``# REM`` lines are remarks), ending with
  ``# END_HEADER``, then one line per point with one column per table, separated by
  spaces; every line but the last ends with "SP LF" (MS249E §8.2).

:func:`format_array` and :func:`parse_array` are the two sides of that format; the
recorder state (:class:`DataRecorder`) is pure and driven by the emulated controller;
:class:`RecorderCommands` sends the commands from the client's side.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

import numpy as np

from calflow.gcs.wire.protocol import GCSProtocolError, check_axis, parse_axis_values

OPTIONS = {0: "Nothing", 1: "Target Position", 2: "Current Position"}


class RecorderError(Exception):
    """A GCS error code raised by a recorder command (57, 58, 59, 1, 17)."""


@dataclass
class DataRecorder:
    """Record tables of one controller. Times are simulation seconds."""

    tables: int = 4
    points: int = 65536  # per table
    servo_cycle_s: float = 5e-5  # E-727: 20 kHz servo update
    rate: int = 1  # RTR
    config: dict[int, tuple[str, int]] = field(default_factory=dict)
    trigger: int = 0
    start: float | None = None  # simulation time of the first point
    armed: bool = False
    recordings: int = 0  # how many recordings have started (seeds their noise)

    @property
    def sample_time(self) -> float:
        return self.servo_cycle_s * self.rate

    def configure(self, table: int, source: str, option: int, axes: set[str]) -> None:
        """``DRC``: checks first; the caller applies all pairs of a line or none."""
        self.check_table(table)
        if option not in OPTIONS:
            raise RecorderError(58)
        if source not in axes:
            raise RecorderError(59)
        self.config[table] = (source, option)

    def check_table(self, table: int) -> None:
        if not 1 <= table <= self.tables:
            raise RecorderError(57)

    def arm(self, table: int, source: int) -> None:
        """``DRT``: table 0 (or any table: one trigger for all, as on the E-727)."""
        if table != 0:
            self.check_table(table)
        if source not in (0, 1, 2):
            raise RecorderError(17)
        self.trigger, self.armed = source, True

    def set_rate(self, rate: int) -> None:
        if not 1 <= rate <= 10**6:
            raise RecorderError(17)
        self.rate = rate

    def command_seen(self, moves: bool, now: float) -> bool:
        """Start the armed recording if this command triggers it; True if it started."""
        if self.armed and (moves or self.trigger == 2):
            self.start, self.armed = now, False
            self.recordings += 1
            return True
        return False

    def recorded(self, now: float) -> int:
        """``DRL?``: points recorded by ``now`` (0 before the trigger)."""
        if self.start is None or now < self.start:
            return 0
        return min(self.points, int(math.floor((now - self.start) / self.sample_time + 1e-9)) + 1)

    def times(self, first: int, count: int) -> np.ndarray:
        """Simulation times of points ``first`` .. ``first + count - 1`` (1-based)."""
        assert self.start is not None
        return self.start + (np.arange(count) + first - 1) * self.sample_time


def format_array(columns: list[np.ndarray], names: list[str], sample_time: float, remark: str) -> list[str]:
    """Lines of a GCS array (header, ``# END_HEADER``, one line per point)."""
    n = len(columns[0]) if columns else 0
    head = [
        f"# REM {remark}",
        "# VERSION = 1",
        "# TYPE = 1",
        "# SEPARATOR = 32",
        f"# DIM = {len(columns)}",
        f"# SAMPLE_TIME = {sample_time:.9g}",
        f"# NDATA = {n}",
        *(f"# NAME{i} = {name}" for i, name in enumerate(names)),
        "# END_HEADER",
    ]
    rows = np.column_stack(columns) if columns else np.empty((0, 0))
    return head + [" ".join(f"{v:.9g}" for v in row) for row in rows]


def parse_array(lines: list[str]) -> tuple[dict[str, str], np.ndarray]:
    """Header (``KEY -> VALUE``, remarks dropped) and data (points x columns) of a GCS array.

    Raises ``ValueError`` on a missing ``# END_HEADER``, a row of the wrong width, a value
    that is not a number, or a point count other than ``NDATA``.
    """
    header: dict[str, str] = {}
    for i, line in enumerate(lines):
        text = line.strip()
        if text.upper() == "# END_HEADER":
            rows = [r.split() for r in lines[i + 1 :] if r.strip()]
            break
        if not text.startswith("#"):
            raise ValueError(f"GCS array: header line {line!r} does not start with '#'")
        key, sep, value = text[1:].partition("=")
        if sep and not key.strip().upper().startswith("REM"):
            header[key.strip().upper()] = value.strip()
    else:
        raise ValueError("GCS array: no '# END_HEADER' line")
    dim = int(header.get("DIM", len(rows[0]) if rows else 0))
    if any(len(r) != dim for r in rows):
        raise ValueError(f"GCS array: rows must have DIM = {dim} columns")
    data = np.array(rows, dtype=float).reshape(len(rows), dim)
    if "NDATA" in header and int(header["NDATA"]) != len(rows):
        raise ValueError(f"GCS array: NDATA = {header['NDATA']} but {len(rows)} rows")
    return header, data


class RecorderCommands:
    """The data recorder as a client drives it: ``DRC``/``RTR``, ``DRT``, ``DRL?``, ``DRR?``.

    A mixin of :class:`calflow.gcs.wire.client.GCSController`, which provides ``command`` (a
    non-query command followed by the ``ERR?`` check) and ``query`` (reply lines).
    """

    def configure_recorder(self, tables: Mapping[int, tuple[str, int]], rate: int | None = None) -> None:
        """``DRC`` table -> (axis, option: 1 target, 2 current position); ``RTR`` rate."""
        args = [x for t, (axis, opt) in tables.items() for x in (int(t), check_axis(axis), int(opt))]
        self.command("DRC", *args)
        if rate is not None:
            self.command("RTR", int(rate))

    def arm_recorder(self, trigger: int = 2) -> None:
        """``DRT 0 <trigger> 0``: 2 starts recording with the next command (the ERR? check)."""
        self.command("DRT", 0, int(trigger), 0)

    def recorded_points(self, table: int = 1) -> int:
        """``DRL? <table>``: points recorded so far."""
        return parse_axis_values(self.query("DRL?", int(table)), int, command="DRL?")[str(table)]

    def read_recorder(
        self, tables: Iterable[int], first: int = 1, count: int | None = None
    ) -> tuple[dict[str, str], np.ndarray]:
        """``DRR?``: (header, points x tables array) in the GCS array format."""
        tables = [int(t) for t in tables]
        n = self.recorded_points(tables[0]) - first + 1 if count is None else int(count)
        lines = self.query("DRR?", int(first), n, *tables)
        try:
            return parse_array(lines)
        except ValueError as exc:
            raise GCSProtocolError(f"reply to DRR?: {exc}", command="DRR?") from None
