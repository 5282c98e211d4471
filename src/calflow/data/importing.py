"""Importing a CSV recording as a run dataset (``calflow import-csv``).

A small YAML mapping file says which CSV column gives which run variable and how to
reach calflow's units (µm, degree, degC, seconds since the campaign start)::

    robot: xytheta                 # optional; must agree with the campaign
    plan: identification           # the run's plan attribute
    model: III                     # optional: the model that commanded the run
    dwell_s: 1.0                   # optional: dwell per pose (s)
    delimiter: ","                 # optional, default ","
    description: "vision bench, 2026-03-02"   # optional, free text
    columns:
      time: {column: t_s}                       # seconds since the campaign start
      # time: {column: stamp, format: iso}      # or ISO 8601 timestamps
      cmd_x: {column: X_cmd_mm, scale: 1000}    # value = cell * scale + offset
      meas_x: {column: x_vision_um}
      temperature: {columns: {T1: temp1, T2: temp2}}
      pose: {column: pose}                      # optional: default 0..n-1

Every problem is a one-line :class:`~calflow.errors.DataError` naming the file, the row
(1-based as in a spreadsheet; the header is row 1), the column and what was expected.
"""

from __future__ import annotations

import csv
import datetime as _dt
import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from calflow.configuration import yamlfile
from calflow.data.conventions import robot_joints, robots, run_variables
from calflow.data.runs import RunMetadata, run_dataset
from calflow.errors import ConfigError, DataError
from calflow.plan import Plan

TOP_KEYS = ("robot", "plan", "model", "dwell_s", "delimiter", "description", "columns")
FIELD_KEYS = ("column", "columns", "scale", "offset", "format")
INDEX_VARIABLES = ("pose", "cycle", "direction")
MISSING = ("", "nan", "NaN", "NAN", "NA", "N/A")  # cells read as a missing reading (NaN)


def _targets(robot: str) -> list[str]:
    """Run variables a mapping may fill for ``robot``."""
    axes = robot_joints(robot)
    names = ["time", *INDEX_VARIABLES, "temperature"]
    for prefix in ("cmd", "meas", "target"):
        names += [f"{prefix}_{a}" for a in axes]
    return names


def _number(value: Any, where: str, key: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise DataError(f"{where}: key {key!r}: expected a finite number, got {value!r}")
    return float(value)


def check_mapping(raw: Any, where: str = "mapping") -> dict:
    """Validate a mapping (as loaded from YAML) and return it normalised.

    Each ``columns`` entry becomes ``{column|columns, scale, offset, format}``.
    ``where`` names the mapping in error messages (its file name).
    """
    if not isinstance(raw, Mapping):
        raise DataError(f"{where}: expected a mapping with keys {list(TOP_KEYS)}, got {type(raw).__name__}")
    for key in raw:
        if key not in TOP_KEYS:
            raise DataError(f"{where}: key {key!r}: unknown; expected some of {list(TOP_KEYS)}")
    out: dict[str, Any] = {}
    robot = raw.get("robot")
    if robot is not None and robot not in robots():
        raise DataError(f"{where}: key 'robot': expected one of {list(robots())}, got {robot!r}")
    out["robot"] = robot
    plan = raw.get("plan")
    if not isinstance(plan, str) or not plan.strip():
        raise DataError(f"{where}: key 'plan': expected a plan name (e.g. 'identification'), got {plan!r}")
    out["plan"] = plan
    model = raw.get("model")
    if model is not None and (not isinstance(model, str) or not model):
        raise DataError(f"{where}: key 'model': expected a model name, got {model!r}")
    out["model"] = model
    out["dwell_s"] = None if raw.get("dwell_s") is None else _number(raw["dwell_s"], where, "dwell_s")
    out["description"] = str(raw.get("description", ""))
    delimiter = raw.get("delimiter", ",")
    if not isinstance(delimiter, str) or len(delimiter) != 1 or delimiter in '"\r\n':
        raise DataError(
            f"{where}: key 'delimiter': expected one character such as ',' ';' or '\\t', got {delimiter!r}"
        )
    out["delimiter"] = delimiter
    columns = raw.get("columns")
    if not isinstance(columns, Mapping) or not columns:
        raise DataError(
            f"{where}: key 'columns': expected a mapping run variable -> {{column: NAME}}, got {columns!r}"
        )
    allowed = _targets(robot) if robot else sorted(run_variables()) + ["time"]
    fields: dict[str, dict] = {}
    for target, spec in columns.items():
        key = f"columns.{target}"
        if target not in allowed:
            raise DataError(f"{where}: key {key!r}: unknown run variable; expected one of {allowed}")
        if not isinstance(spec, Mapping):
            raise DataError(
                f"{where}: key {key!r}: expected a mapping such as {{column: NAME}}, got {spec!r}"
            )
        for k in spec:
            if k not in FIELD_KEYS:
                raise DataError(f"{where}: key '{key}.{k}': unknown; expected some of {list(FIELD_KEYS)}")
        field: dict[str, Any] = {"scale": 1.0, "offset": 0.0, "format": "number"}
        if target == "temperature":
            cols = spec.get("columns")
            if (
                "column" in spec
                or not isinstance(cols, Mapping)
                or not cols
                or not all(isinstance(n, str) and n and isinstance(c, str) and c for n, c in cols.items())
            ):
                raise DataError(
                    f"{where}: key '{key}.columns': expected a mapping thermometer name -> "
                    f"CSV column, e.g. {{T1: temp1}}, got {cols!r}"
                )
            field["columns"] = {str(n): str(c) for n, c in cols.items()}
        else:
            col = spec.get("column")
            if "columns" in spec or not isinstance(col, str) or not col:
                raise DataError(
                    f"{where}: key '{key}.column': expected the name of one CSV column, got {col!r}"
                )
            field["column"] = col
        for k in ("scale", "offset"):
            if k in spec:
                field[k] = _number(spec[k], where, f"{key}.{k}")
        fmt = spec.get("format", "number")
        if fmt not in (("number", "iso") if target == "time" else ("number",)):
            allowed_fmt = "'number' or 'iso'" if target == "time" else "'number' (only time may be 'iso')"
            raise DataError(f"{where}: key '{key}.format': expected {allowed_fmt}, got {fmt!r}")
        field["format"] = fmt
        if fmt == "iso" and (field["scale"] != 1.0 or field["offset"] != 0.0):
            raise DataError(f"{where}: key {key!r}: scale/offset do not apply to format 'iso'")
        if target in INDEX_VARIABLES and (field["scale"] != 1.0 or field["offset"] != 0.0):
            raise DataError(f"{where}: key {key!r}: scale/offset do not apply to the index {target!r}")
        fields[target] = field
    needed = ["time"] + ([f"{p}_{a}" for a in robot_joints(robot) for p in ("cmd", "meas")] if robot else [])
    for target in needed:
        if target not in fields:
            raise DataError(f"{where}: key 'columns.{target}': missing; a {robot or 'run'} run needs it")
    out["columns"] = fields
    return out


def load_mapping(path: str | os.PathLike) -> dict:
    """Read and validate a YAML mapping file; errors name the file and the key."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise DataError(f"{path}: cannot read the mapping file ({exc.strerror or exc})") from None
    try:
        raw = yamlfile.parse(text, path)
    except ConfigError as exc:  # the same one line, as the data error of an import
        raise DataError(str(exc)) from None
    return check_mapping(raw, str(path))


def _parse_start(start: str, where: str) -> _dt.datetime:
    try:
        t0 = _dt.datetime.fromisoformat(start)
    except ValueError:
        raise DataError(f"{where}: campaign start {start!r}: expected an ISO 8601 timestamp") from None
    return t0 if t0.tzinfo else t0.replace(tzinfo=_dt.UTC)


def refuse_duplicate_rows(path, rows: list[tuple[int, list[str]]]) -> None:
    """Refuse a data row that repeats an earlier one cell for cell.

    A real repeated measurement differs at least in its time stamp; an identical row is
    an export or copy error, and taking it as a new pose would count one reading twice
    (repeatability RP and every mean would be computed from a sample that is not there).
    ``rows`` are (row number, cells).
    """
    seen: dict[tuple[str, ...], int] = {}
    for r, cells in rows:
        key = tuple(c.strip() for c in cells)
        if key in seen:
            raise DataError(
                f"{path}: row {r}: repeats row {seen[key]} cell for cell; a duplicated row would count "
                "one measurement twice — remove it (or the export's duplicate) and import again"
            )
        seen[key] = r


class _Table:
    """The CSV cells, with one-line errors naming file, row and column."""

    def __init__(self, path: Path, delimiter: str):
        self.path = path
        try:
            with path.open(newline="", encoding="utf-8-sig") as f:
                rows = list(csv.reader(f, delimiter=delimiter, strict=True))
        except FileNotFoundError:
            raise DataError(f"{path}: file not found") from None
        except UnicodeDecodeError as exc:
            raise DataError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
        except csv.Error as exc:
            raise DataError(f"{path}: not readable CSV ({exc})") from None
        while rows and not any(c.strip() for c in rows[-1]):
            rows.pop()  # trailing blank lines
        if not rows:
            raise DataError(f"{path}: row 1: expected a header row, the file is empty")
        self.header = [c.strip() for c in rows[0]]
        seen: set[str] = set()
        for k, name in enumerate(self.header):
            if not name:
                raise DataError(f"{path}: row 1, field {k + 1}: expected a column name, got an empty one")
            if name in seen:
                raise DataError(f"{path}: row 1: column {name!r} appears twice in the header")
            seen.add(name)
        self.rows = rows[1:]
        if not self.rows:
            raise DataError(f"{path}: row 2: expected a data row after the header, the file has none")
        for r, row in enumerate(self.rows, start=2):
            if len(row) != len(self.header):
                raise DataError(
                    f"{path}: row {r}: expected {len(self.header)} fields as in the header, "
                    f"got {len(row)} (check the delimiter)"
                )
        refuse_duplicate_rows(path, list(enumerate(self.rows, start=2)))

    def cells(self, column: str, target: str) -> list[str]:
        if column not in self.header:
            raise DataError(
                f"{self.path}: row 1: column {column!r} (for {target}) missing from the header; "
                f"header has {self.header}"
            )
        k = self.header.index(column)
        return [row[k].strip() for row in self.rows]

    def fail(self, r: int, column: str, target: str, expected: str, cell: str) -> DataError:
        return DataError(
            f"{self.path}: row {r + 2}, column {column!r} ({target}): expected {expected}, got {cell!r}"
        )

    def numbers(self, column: str, target: str, allow_missing: bool) -> np.ndarray:
        out = np.empty(len(self.rows))
        for r, cell in enumerate(self.cells(column, target)):
            if cell in MISSING:
                if not allow_missing:
                    raise self.fail(r, column, target, "a number", cell)
                out[r] = np.nan
                continue
            try:
                value = float(cell)
            except ValueError:
                raise self.fail(r, column, target, "a number", cell) from None
            if not math.isfinite(value):
                raise self.fail(r, column, target, "a finite number", cell)
            out[r] = value
        return out

    def integers(self, column: str, target: str, choices=None) -> np.ndarray:
        values = self.numbers(column, target, allow_missing=False)
        cells = self.cells(column, target)
        for r, v in enumerate(values):
            if v != round(v) or (choices is not None and v not in choices):
                want = f"one of {sorted(choices)}" if choices is not None else "an integer"
                raise self.fail(r, column, target, want, cells[r])
        return values.astype(int)

    def iso_seconds(self, column: str, target: str, t0: _dt.datetime) -> np.ndarray:
        out = np.empty(len(self.rows))
        for r, cell in enumerate(self.cells(column, target)):
            try:
                t = _dt.datetime.fromisoformat(cell.replace("Z", "+00:00") if cell.endswith("Z") else cell)
            except ValueError:
                raise self.fail(
                    r, column, target, "an ISO 8601 timestamp (2026-03-02T10:15:00+00:00)", cell
                ) from None
            if t.tzinfo is None:
                t = t.replace(tzinfo=t0.tzinfo)
            out[r] = (t - t0).total_seconds()
        return out


def import_csv(path: str | os.PathLike, mapping: Mapping, meta: RunMetadata) -> xr.Dataset:
    """Read the CSV ``path`` through ``mapping`` into a run dataset (``calflow_kind = "run"``).

    Each mapped value is ``cell * scale + offset`` in calflow's units (µm, degree,
    degC). ``time`` is seconds since ``meta.start``: a number column (with optional
    scale, e.g. 0.001 for ms) or ISO 8601 timestamps (``format: iso``; naive ones are
    taken in the time zone of the campaign start). Empty or ``nan`` cells are missing
    readings (NaN) in ``meas_*``, ``target_*`` and ``temperature`` only. ``pose``
    defaults to 0..n-1, ``cycle`` and ``direction`` to 0. Global attributes come from
    ``meta.attrs("run")``; ``meta.robot`` and ``meta.plan`` must agree with the mapping.
    """
    path = Path(path)
    m = check_mapping(mapping)
    robot = m["robot"] or meta.robot
    if m["robot"] and m["robot"] != meta.robot:
        raise DataError(
            f"{path}: mapping robot {m['robot']!r} differs from the campaign robot {meta.robot!r}"
        )
    if robot not in robots():
        raise DataError(f"{path}: robot: expected one of {list(robots())}, got {robot!r}")
    if m["plan"] != meta.plan:
        raise DataError(
            f"{path}: mapping plan {m['plan']!r} differs from the run metadata plan {meta.plan!r}"
        )
    m = check_mapping(
        {**{k: v for k, v in m.items() if v is not None and k != "description"}, "robot": robot}, "mapping"
    )  # re-check the columns against the robot's joints
    cols = m["columns"]
    table = _Table(path, m["delimiter"])
    n = len(table.rows)

    def values(target: str, allow_missing: bool) -> np.ndarray:
        f = cols[target]
        return table.numbers(f["column"], target, allow_missing) * f["scale"] + f["offset"]

    tf = cols["time"]
    if tf["format"] == "iso":
        time = table.iso_seconds(tf["column"], "time", _parse_start(meta.start, str(path)))
    else:
        time = values("time", allow_missing=False)
    back = np.flatnonzero(np.diff(time) < 0)
    if back.size:
        r = int(back[0]) + 1
        raise DataError(
            f"{path}: row {r + 2}, column {tf['column']!r} (time): expected non-decreasing time, "
            f"got {float(time[r])!r} s after {float(time[r - 1])!r} s"
        )
    index = {}
    for name, default, choices in (
        ("pose", np.arange(n), None),
        ("cycle", np.zeros(n, int), None),
        ("direction", np.zeros(n, int), {-1, 0, 1}),
    ):
        index[name] = table.integers(cols[name]["column"], name, choices) if name in cols else default
    axes = robot_joints(robot)
    commands = {a: values(f"cmd_{a}", allow_missing=False) for a in axes}
    targets = {a: values(f"target_{a}", allow_missing=True) for a in axes if f"target_{a}" in cols}
    sensors = [f"meas_{a}" for a in axes]
    meas = {s: values(s, allow_missing=True) for s in sensors}
    thermometers: list[str] = []
    temps: dict[str, np.ndarray] = {}
    if "temperature" in cols:
        f = cols["temperature"]
        for name, column in f["columns"].items():
            thermometers.append(name)
            temps[name] = table.numbers(column, f"temperature {name}", True) * f["scale"] + f["offset"]
    readings = [
        {
            "time": float(time[i]),
            **{s: float(meas[s][i]) for s in sensors},
            **{t: float(temps[t][i]) for t in thermometers},
        }
        for i in range(n)
    ]
    plan = Plan(
        name=m["plan"],
        commands=commands,
        pose=index["pose"],
        cycle=index["cycle"],
        direction=index["direction"],
        targets=targets,
        dwell_s=m["dwell_s"] if m["dwell_s"] is not None else 0.0,
    )
    ds = run_dataset(readings, plan, sensors, thermometers, meta)
    if m["dwell_s"] is None:
        del ds.attrs["dwell_s"]
    ds.attrs["imported_from"] = path.name
    return ds
