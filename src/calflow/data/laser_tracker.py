"""Laser-tracker exports: commanded and measured XYZ per pose, as CSV (docs/data.md).

A laser tracker (ISO 9283's measuring instrument for poses, clause 8.3) gives one
measured point per settled pose. calflow reads the export as a CSV with a header row
(``#`` comment lines before it are skipped), delimiter ``,``, these columns in any order:

=============  ======  =====================================================
column         unit    meaning
=============  ======  =====================================================
``timestamp``  —       ISO 8601 time of the measurement (e.g. 2026-03-02T10:15:00Z)
``pose``       —       index of the commanded pose (integer >= 0)
``X_cmd_mm``   mm      commanded pose, in the tracker frame aligned to the stage
``Y_cmd_mm``   mm
``Z_cmd_mm``   mm
``X_mm``       mm      measured point
``Y_mm``       mm
``Z_mm``       mm
=============  ======  =====================================================

Optional: ``cycle`` (integer >= 0; default: the count of earlier rows with the same
pose). Other columns are ignored. Empty measured cells are lost readings (NaN).

The stage is planar (``stage2d``): X and Y are its axes, the commanded Z must be the same
in every row, and the measured Z is kept as the out-of-plane range (``z_range_um``).
Every problem is a one-line :class:`~calflow.errors.DataError` naming the file, the row
(the header is row 1, as a spreadsheet counts) and the column.
"""

from __future__ import annotations

import csv
import datetime as _dt
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calflow.data.importing import refuse_duplicate_rows
from calflow.errors import DataError

REQUIRED = ("timestamp", "pose", "X_cmd_mm", "Y_cmd_mm", "Z_cmd_mm", "X_mm", "Y_mm", "Z_mm")
UM_PER_MM = 1000.0


@dataclass(frozen=True)
class TrackerRecording:
    """A laser-tracker export: ``time`` (s since the first row's timestamp), ``start``
    (that timestamp, ISO 8601), ``pose``, ``cycle`` (n,), ``command`` and ``measured``
    (n, 3) in mm (X, Y, Z)."""

    start: str
    time: np.ndarray
    pose: np.ndarray
    cycle: np.ndarray
    command: np.ndarray
    measured: np.ndarray


def _rows(path: Path) -> tuple[list[str], list[tuple[int, list[str]]]]:
    """Header and (row number, cells) of the data rows; rows numbered as a spreadsheet does."""
    try:
        with path.open(newline="", encoding="utf-8-sig") as f:
            lines = list(csv.reader(f, strict=True))
    except FileNotFoundError:
        raise DataError(f"{path}: file not found") from None
    except UnicodeDecodeError as exc:
        raise DataError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except (OSError, csv.Error) as exc:
        raise DataError(f"{path}: not readable CSV ({exc})") from None
    numbered = [
        (k, row)
        for k, row in enumerate(lines, start=1)
        if any(c.strip() for c in row) and not row[0].lstrip().startswith("#")
    ]
    if not numbered:
        raise DataError(
            f"{path}: row 1: expected a header row with columns {list(REQUIRED)}, the file has none"
        )
    r0, header = numbered[0]
    header = [c.strip() for c in header]
    for name in REQUIRED:
        if name not in header:
            raise DataError(
                f"{path}: row {r0}: column {name!r} missing from the header; expected {list(REQUIRED)}"
            )
    if len(set(header)) != len(header):
        dup = next(h for h in header if header.count(h) > 1)
        raise DataError(f"{path}: row {r0}: column {dup!r} appears twice in the header")
    data = numbered[1:]
    if not data:
        raise DataError(f"{path}: row {r0 + 1}: expected a data row after the header, the file has none")
    for r, row in data:
        if len(row) != len(header):
            raise DataError(
                f"{path}: row {r}: expected {len(header)} fields as in the header, got {len(row)}"
            )
    return header, data


def read(path: str | os.PathLike) -> TrackerRecording:
    """Read a laser-tracker CSV export (module docstring)."""
    path = Path(path)
    header, data = _rows(path)
    refuse_duplicate_rows(path, data)
    col = {name: header.index(name) for name in header}

    def fail(r: int, name: str, expected: str, cell: str) -> DataError:
        return DataError(f"{path}: row {r}, column {name!r}: expected {expected}, got {cell!r}")

    def number(r: int, name: str, cells: list[str], missing_ok: bool) -> float:
        cell = cells[col[name]].strip()
        if cell == "" and missing_ok:
            return math.nan
        try:
            x = float(cell)
        except ValueError:
            raise fail(r, name, "a number (mm)", cell) from None
        if not math.isfinite(x):
            raise fail(r, name, "a finite number (mm)", cell)
        return x

    def index(r: int, name: str, cells: list[str]) -> int:
        cell = cells[col[name]].strip()
        if not cell.isdigit():
            raise fail(r, name, "an integer >= 0", cell)
        return int(cell)

    stamps = []
    for r, cells in data:
        cell = cells[col["timestamp"]].strip()
        try:
            t = _dt.datetime.fromisoformat(cell[:-1] + "+00:00" if cell.endswith("Z") else cell)
        except ValueError:
            raise fail(r, "timestamp", "an ISO 8601 timestamp (2026-03-02T10:15:00Z)", cell) from None
        if t.tzinfo is None:
            raise fail(r, "timestamp", "a timestamp with its time zone (Z or +01:00)", cell)
        stamps.append(t)
    seconds = np.array([(t - stamps[0]).total_seconds() for t in stamps])
    back = np.flatnonzero(np.diff(seconds) < 0)
    if back.size:
        r = data[int(back[0]) + 1][0]
        raise fail(
            r,
            "timestamp",
            f"a time not before the previous row's ({stamps[int(back[0])].isoformat()})",
            data[int(back[0]) + 1][1][col["timestamp"]].strip(),
        )
    pose = np.array([index(r, "pose", cells) for r, cells in data])
    if "cycle" in col:
        cycle = np.array([index(r, "cycle", cells) for r, cells in data])
    else:
        cycle = np.array([int(np.sum(pose[:k] == p)) for k, p in enumerate(pose)])
    command = np.array([[number(r, f"{a}_cmd_mm", cells, False) for a in "XYZ"] for r, cells in data])
    measured = np.array([[number(r, f"{a}_mm", cells, True) for a in "XYZ"] for r, cells in data])
    z = command[:, 2]
    if np.any(z != z[0]):
        k = int(np.argmax(z != z[0]))
        raise fail(
            data[k][0],
            "Z_cmd_mm",
            f"the commanded Z of every row ({float(z[0])!r} mm): the stage is planar",
            data[k][1][col["Z_cmd_mm"]].strip(),
        )
    return TrackerRecording(stamps[0].isoformat(), seconds, pose, cycle, command, measured)


def format_text(rec: TrackerRecording) -> str:
    """The CSV text of ``rec`` (the inverse of :func:`read`, for tests and examples)."""
    start = _dt.datetime.fromisoformat(rec.start)
    lines = [",".join(REQUIRED + ("cycle",))]
    for k in range(len(rec.pose)):
        t = (start + _dt.timedelta(seconds=float(rec.time[k]))).isoformat()
        cells = [t, str(int(rec.pose[k]))]
        cells += [repr(float(v)) for v in rec.command[k]]
        cells += ["" if math.isnan(v) else repr(float(v)) for v in rec.measured[k]]
        lines.append(",".join(cells + [str(int(rec.cycle[k]))]))
    return "\n".join(lines) + "\n"


def write(rec: TrackerRecording, path: str | os.PathLike) -> Path:
    """Write ``rec`` as a laser-tracker CSV, atomically."""
    from calflow.data.io import write_text

    return write_text(format_text(rec), path)
