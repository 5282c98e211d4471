"""Crash-safe acquisition: an append-only journal of completed samples.

The journal appears with the first sample read. Each settled sample is appended to
``<output>.journal`` as one JSON line and flushed to
the operating system at once, so a killed process (even SIGKILL) loses at most the
sample being read; the file is fsync'ed every few seconds against power loss. A
trailing line cut short by the kill is ignored. The first line records a digest of the
plan, so a journal of another plan is never resumed.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import numpy as np

from calflow.plan import Plan

WALL = "_wall_clock_s"  # journal-only key: when the sample was taken (Unix time)


def plan_digest(plan: Plan) -> str:
    """SHA-256 of the plan's rows (commands, indices, dwell)."""
    import hashlib

    h = hashlib.sha256()
    h.update(plan.name.encode())
    h.update(np.float64(plan.dwell_s).tobytes())
    for name in sorted(plan.commands):
        h.update(name.encode())
        h.update(np.ascontiguousarray(plan.commands[name], dtype=float).tobytes())
    for arr in (plan.pose, plan.cycle, plan.direction):
        h.update(np.ascontiguousarray(arr, dtype=np.int64).tobytes())
    return h.hexdigest()


def _encode(reading: dict) -> str:
    # JSON has no NaN; keep it as null and restore it on load.
    return json.dumps({k: (None if isinstance(v, float) and v != v else v) for k, v in reading.items()})


class Journal:
    """Append-only record of the samples of one acquisition."""

    def __init__(self, path: str | os.PathLike, digest: str, fsync_every_s: float = 2.0):
        self.path = Path(path)
        self.digest = digest
        self.fsync_every_s = fsync_every_s
        self._file = None
        self._pending = False  # opened without readings: the file is made by the first append
        self._last_sync = 0.0
        self.last_wall: float | None = None  # wall-clock time of the last recorded sample

    def load(self) -> list[dict]:
        """Readings already recorded for this plan (empty if none or for another plan)."""
        if not self.path.exists():
            return []
        lines = self.path.read_text(encoding="utf-8").split("\n")
        try:
            header = json.loads(lines[0])
        except (json.JSONDecodeError, IndexError):
            return []
        if header.get("plan_digest") != self.digest:
            return []
        readings = []
        for line in lines[1:]:
            try:
                row = json.loads(line)
            except json.JSONDecodeError:
                break  # the line being written when the process died
            readings.append({k: (float("nan") if v is None else v) for k, v in row.items()})
        self.last_wall = readings[-1].get(WALL) if readings else None
        for r in readings:
            r.pop(WALL, None)
        return readings

    def open(self, readings: list[dict]) -> None:
        """Start the journal afresh with ``readings`` already in it (rewritten whole).

        With no readings yet, the file is created by the first :meth:`append`: a run that
        fails before its first sample (a deterministic configuration or rig error) leaves
        no journal behind.
        """
        self._pending = not readings
        if not readings:
            return
        self._write(readings)

    def _write(self, readings: list[dict]) -> None:
        self._pending = False
        self.path.parent.mkdir(parents=True, exist_ok=True)
        tmp = self.path.with_suffix(self.path.suffix + ".tmp")
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(json.dumps({"plan_digest": self.digest}) + "\n")
            for r in readings:
                f.write(_encode({**r, WALL: self.last_wall}) + "\n")
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, self.path)
        self._file = open(self.path, "a", encoding="utf-8")

    def append(self, reading: dict) -> None:
        if self._file is None and getattr(self, "_pending", False):
            self._write([])
        self._file.write(_encode({**reading, WALL: time.time()}) + "\n")
        self._file.flush()
        now = time.monotonic()
        if now - self._last_sync > self.fsync_every_s:
            os.fsync(self._file.fileno())
            self._last_sync = now

    def close(self, remove: bool = False) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None
        if remove and self.path.exists():
            self.path.unlink()
