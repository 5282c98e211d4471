"""Recordings of real instruments as run datasets, for the replay rig (docs/data.md).

A replay campaign names one recording per run id (``rig.options.recordings``). Each is a
calflow run file (``.nc``) or a file an instrument wrote, given as::

    {file: data/recordings/axis1_ISO230.dat, format: ecmc_iso230}   # ISO 230-2, one axis x
    {file: data/recordings/tracker.csv, format: laser_tracker}      # XYZ poses, axes x and y
    {file: bench.csv, format: csv, mapping: bench-mapping.yaml}     # generic CSV mapping
    {file: ident.tif, format: frames, table: ident.csv, pattern: pattern.json}  # camera frames

A ``frames`` recording (a TIFF stack or a folder of images, its joints table, the pattern
file, optional ``camera`` fields) is decoded by the workflow's ``decode_frames`` rule
(``calflow decode-run``, :mod:`calflow.commands.decode_run`) into a run dataset, which the
replay rig serves (its ``decoded`` option).

A plain path is a ``.nc`` run file, or an instrument file recognised by its name
(``*ISO230.dat``). :func:`load` returns the run dataset and, for an instrument's file, the
:class:`~calflow.plan.Plan` the instrument ran: the poses were chosen by the instrument's
software, so replaying means commanding exactly those.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import xarray as xr

from calflow.data.runs import RunMetadata, run_dataset
from calflow.errors import DataError
from calflow.plan import Plan

# format -> the joints an instrument's file of that format records (None: the file says)
FORMATS = {"nc": None, "ecmc_iso230": ("x",), "laser_tracker": ("x", "y"), "csv": None, "frames": None}
KEYS = {
    "frames": ("file", "format", "table", "pattern", "camera", "marker", "reference_marker", "pixel_size")
}
PIXEL_SIZES = ("frame", "sequence")  # HP-code frames: each frame's own pixel size, or one pooled
RECORDING_START = "2000-01-01T00:00:00+00:00"  # times of a file without clock: a fixed, documented origin


class BadEntry(ValueError):
    """A recording entry that is not one: ``key`` (``""``, ``.file``, ``.format``, …), what was expected, the value."""

    def __init__(self, key: str, expected: str, value: Any):
        super().__init__(f"{key}: expected {expected}, got {value!r}")
        self.key, self.expected, self.value = key, expected, value


def entry(spec: Any) -> dict:
    """A recording entry normalised to {file, format, mapping}; raises :class:`BadEntry`."""
    if isinstance(spec, (str, Path)):
        name = Path(spec).name
        fmt = "ecmc_iso230" if name.upper().endswith("ISO230.DAT") else "nc" if name.endswith(".nc") else None
        if fmt is None:
            raise BadEntry(
                "",
                f"a .nc run file, an *ISO230.dat file or {{file: ..., format: one of {list(FORMATS)}}}",
                str(spec),
            )
        return {"file": str(spec), "format": fmt, "mapping": None}
    if not isinstance(spec, Mapping):
        raise BadEntry("", "a file name or {file: ..., format: ...}", spec)
    fmt = spec.get("format")
    if "format" in spec and fmt not in FORMATS:  # before the keys: they depend on it
        raise BadEntry(".format", f"one of {list(FORMATS)}", fmt)
    keys = KEYS.get(fmt, ("file", "format", "mapping"))
    unknown = sorted(set(spec) - set(keys))
    if unknown:
        raise BadEntry(f".{unknown[0]}", f"no such key (the keys are {', '.join(keys)})", spec[unknown[0]])
    if not isinstance(spec.get("file"), str) or not spec["file"]:
        raise BadEntry(".file", "the path of the recording", spec.get("file"))
    if fmt not in FORMATS:
        raise BadEntry(".format", f"one of {list(FORMATS)}", fmt)
    if fmt == "frames":
        for key, what in (
            ("table", "the joints table (CSV: frame, time, cmd_<joint>…)"),
            ("pattern", "the pattern file"),
        ):
            if not (isinstance(spec.get(key), str) and spec[key]):
                raise BadEntry(f".{key}", what, spec.get(key))
        if not isinstance(spec.get("camera", {}), Mapping):
            raise BadEntry(".camera", "a mapping of camera-model fields", spec.get("camera"))
        for key in ("marker", "reference_marker"):  # HP-code markers' numbers
            v = spec.get(key)
            if v is not None and (isinstance(v, bool) or not isinstance(v, int) or v < 0):
                raise BadEntry(f".{key}", "the number of an HP-code marker (an integer, 0 or more)", v)
        if spec.get("pixel_size") is not None and spec["pixel_size"] not in PIXEL_SIZES:
            raise BadEntry(
                ".pixel_size",
                "'frame' (each frame's own) or 'sequence' (one pooled over the frames; HP-code markers)",
                spec["pixel_size"],
            )
        if spec.get("reference_marker") is not None and spec.get("marker") == spec["reference_marker"]:
            raise BadEntry(".reference_marker", "another marker than .marker", spec["reference_marker"])
        return {**{k: spec.get(k) for k in keys}, "camera": dict(spec.get("camera") or {}), "mapping": None}
    if fmt == "csv" and not (isinstance(spec.get("mapping"), str) and spec["mapping"]):
        raise BadEntry(
            ".mapping", "the column mapping file of a csv recording (docs/data.md)", spec.get("mapping")
        )
    if fmt != "csv" and "mapping" in spec:
        raise BadEntry(
            ".mapping", f"no mapping: it applies to format 'csv' only, not {fmt!r}", spec["mapping"]
        )
    return {"file": spec["file"], "format": fmt, "mapping": spec.get("mapping")}


def check_entry(spec: Any) -> None:
    """The config check of one entry: its shape, and that its files exist (relative paths
    are from the project folder, where Snakemake runs). The file is read at acquisition."""
    e = entry(spec)
    if e["format"] == "frames" and not Path(e["file"]).exists():
        raise BadEntry(
            ".file", "an existing TIFF stack or folder of images (relative to the project folder)", e["file"]
        )
    for key in ("mapping", "table", "pattern") if e["format"] == "frames" else ("file", "mapping"):
        if e.get(key) is not None and not Path(e[key]).is_file():
            raise BadEntry(
                "" if isinstance(spec, (str, Path)) else f".{key}",
                "an existing file (paths are relative to the project folder)",
                e[key],
            )


def robot_recording(fmt: str, path: Path) -> str:
    """The robot whose runs an instrument's file of format ``fmt`` holds: the installed robot
    whose joints are exactly the ones the format records."""
    from calflow.family import joints, robots

    found = [r for r in robots() if joints(r) == FORMATS[fmt]]
    if not found:
        raise DataError(
            f"{path}: format {fmt!r} records joints {list(FORMATS[fmt])}; no installed robot "
            f"has exactly those joints"
        )
    return found[0]


def _meta(robot: str, plan: str, path: Path, start: str = RECORDING_START) -> RunMetadata:
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    return RunMetadata(
        campaign="recording", robot=robot, source="replay", plan=plan, config_sha256=digest, start=start
    )


def _imported(
    readings: list[dict], plan: Plan, sensors: list[str], meta: RunMetadata, path: Path
) -> xr.Dataset:
    ds = run_dataset(readings, plan, sensors, (), meta)
    del ds.attrs["dwell_s"]  # the instrument's file does not say
    ds.attrs["imported_from"] = path.name
    return ds


def iso230_run(path: Path, plan_name: str) -> tuple[xr.Dataset, Plan]:
    """An ecmc ISO 230-2 file as a run of the one-axis robot (µm) in the standard test cycle;
    no clock in the file, so every row has time 0 s."""
    from calflow.data.ecmc_iso230 import read, standard_cycle

    rows = standard_cycle(read(path))
    plan = Plan(
        name=plan_name,
        commands={"x": rows["target"]},
        targets={"x": rows["target"].copy()},
        pose=rows["pose"],
        cycle=rows["cycle"],
        direction=rows["direction"],
        dwell_s=0.0,
    )
    readings = [{"time": 0.0, "meas_x": float(v)} for v in rows["reading"]]
    return _imported(
        readings, plan, ["meas_x"], _meta(robot_recording("ecmc_iso230", path), plan_name, path), path
    ), plan


def tracker_run(path: Path, plan_name: str) -> tuple[xr.Dataset, Plan]:
    """A laser-tracker export as a run of the XY robot (µm): X, Y the stage's axes; the
    measured Z's range is kept as the attribute ``z_range_um``."""
    from calflow.data.laser_tracker import UM_PER_MM, read

    rec = read(path)
    cmd, meas = rec.command * UM_PER_MM, rec.measured * UM_PER_MM
    plan = Plan(
        name=plan_name,
        commands={"x": cmd[:, 0], "y": cmd[:, 1]},
        targets={"x": cmd[:, 0].copy(), "y": cmd[:, 1].copy()},
        pose=rec.pose,
        cycle=rec.cycle,
        direction=np.zeros(len(rec.pose), int),
        dwell_s=0.0,
    )
    readings = [
        {"time": float(rec.time[k]), "meas_x": float(meas[k, 0]), "meas_y": float(meas[k, 1])}
        for k in range(len(rec.pose))
    ]
    ds = _imported(
        readings,
        plan,
        ["meas_x", "meas_y"],
        _meta(robot_recording("laser_tracker", path), plan_name, path, rec.start),
        path,
    )
    z = meas[:, 2][np.isfinite(meas[:, 2])]
    ds.attrs["z_range_um"] = float(z.max() - z.min()) if z.size else float("nan")
    ds.attrs["recording_start"] = rec.start
    return ds, plan


def csv_run(path: Path, mapping_path: str, plan_name: str) -> tuple[xr.Dataset, Plan]:
    """A CSV through a column mapping (:mod:`calflow.data.importing`), with the plan it recorded."""
    from calflow.data.importing import import_csv, load_mapping

    mapping = load_mapping(mapping_path)
    if not mapping["robot"]:
        raise DataError(f"{mapping_path}: key 'robot': a replayed csv recording needs the robot named")
    ds = import_csv(path, mapping, _meta(mapping["robot"], mapping["plan"], path))
    return ds, plan_of(ds, plan_name)


def plan_of(ds: xr.Dataset, name: str) -> Plan:
    """The plan a run dataset recorded: its commands, targets and pose/cycle/direction indices."""
    joints = [v[4:] for v in ds.data_vars if v.startswith("cmd_")]
    axes = [v[7:] for v in ds.data_vars if v.startswith("target_")]
    return Plan(
        name=name,
        commands={j: ds[f"cmd_{j}"].values.astype(float) for j in joints},
        targets={a: ds[f"target_{a}"].values.astype(float) for a in axes},
        pose=ds["pose"].values.astype(int),
        cycle=ds["cycle"].values.astype(int),
        direction=ds["direction"].values.astype(int),
        dwell_s=float(ds.attrs.get("dwell_s", 0.0)),
    )


def load(
    spec: Any, run_id: str, where: str = "recordings", decoded: str | None = None
) -> tuple[Path, xr.Dataset | None, Plan | None]:
    """The recording ``spec`` of run ``run_id``: (path, run dataset or None for a ``.nc``
    file the replay rig opens itself, the instrument's plan or None). A ``frames``
    recording is served from its ``decoded`` run file (``calflow decode-run``)."""
    try:
        s = entry(spec)
    except BadEntry as exc:
        raise DataError(f"{where}.{run_id}{exc.key}: expected {exc.expected}, got {exc.value!r}") from None
    path = Path(s["file"])
    if s["format"] == "nc":
        return path, None, None
    if s["format"] == "frames":
        if not decoded or not Path(decoded).is_file():
            raise DataError(
                f"{path}: {where}.{run_id}: frames are served decoded: run 'calflow decode-run' "
                f"(the workflow's decode_frames rule) and give its file (calflow acquire --decoded), got {decoded!r}"
            )
        from calflow.data.io import open_dataset

        ds = open_dataset(decoded, kind="run")
        return Path(decoded), ds, plan_of(ds, run_id)
    if not path.is_file():
        raise DataError(f"{path}: file not found ({where}.{run_id})")
    if s["format"] == "ecmc_iso230":
        return (path, *iso230_run(path, run_id))
    if s["format"] == "laser_tracker":
        return (path, *tracker_run(path, run_id))
    return (path, *csv_run(path, s["mapping"], run_id))


def in_campaign_time(ds: xr.Dataset, campaign_start: str) -> xr.Dataset:
    """``ds`` with ``time`` in seconds since ``campaign_start`` (ISO 8601), when the
    recording has a clock (its ``recording_start`` attribute); unchanged otherwise (an
    ISO 230-2 file has none)."""
    import datetime as dt

    from calflow.data.conventions import time_units

    origin = ds.attrs.get("recording_start")
    if not origin:
        return ds
    try:
        start = dt.datetime.fromisoformat(str(campaign_start).replace("Z", "+00:00"))
    except ValueError:
        raise DataError(f"campaign start: expected an ISO 8601 time, got {campaign_start!r}") from None
    shift = (dt.datetime.fromisoformat(origin) - start).total_seconds()
    t = ds["time"]
    return ds.assign(time=t.copy(data=t.values + shift).assign_attrs(units=time_units(campaign_start)))
