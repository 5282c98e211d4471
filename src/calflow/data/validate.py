"""Check a dataset against the calflow data contract (docs/architecture.md, "Datasets").

:func:`validate_dataset` returns a list of problems, one line each, that name the
variable or attribute and what was expected; an empty list means the dataset conforms.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import xarray as xr

from calflow.data.conventions import (
    GLOBAL_ATTRS,
    KINDS,
    REQUIRED_RUN_VARIABLES,
    SOURCES,
    robot_joints,
    robots,
    run_variables,
)
from calflow.errors import DataError


def _check_global(ds: xr.Dataset) -> list[str]:
    problems = [f"global attribute '{a}': missing" for a in GLOBAL_ATTRS if a not in ds.attrs]
    kind = ds.attrs.get("calflow_kind")
    if kind is not None and kind not in KINDS:
        problems.append(f"global attribute 'calflow_kind': expected one of {list(KINDS)}, got {kind!r}")
    robot = ds.attrs.get("robot")
    if robot is not None and robot not in robots():
        problems.append(f"global attribute 'robot': expected one of {list(robots())}, got {robot!r}")
    source = ds.attrs.get("source")
    if source is not None and source not in SOURCES:
        problems.append(f"global attribute 'source': expected one of {list(SOURCES)}, got {source!r}")
    if "Conventions" in ds.attrs and not str(ds.attrs["Conventions"]).startswith("CF-"):
        problems.append(
            f"global attribute 'Conventions': expected 'CF-1.11', got {ds.attrs['Conventions']!r}"
        )
    return problems


def _check_cf_variables(ds: xr.Dataset) -> list[str]:
    problems = []
    for name, var in ds.variables.items():
        if var.dtype.kind in "SUO":  # label coordinates (e.g. sensor names) carry no units
            continue
        for attr in ("units", "long_name"):
            if attr not in var.attrs:
                problems.append(f"variable '{name}': attribute '{attr}' missing")
    return problems


def _check_run(ds: xr.Dataset) -> list[str]:
    problems = []
    if "sample" not in ds.dims:
        return ["dimension 'sample': missing (a run has one row per settled pose)"]
    if ds.sizes["sample"] == 0:
        problems.append("dimension 'sample': expected at least one sample, got 0")
    for name in REQUIRED_RUN_VARIABLES:
        if name not in ds.variables:
            problems.append(f"variable '{name}': missing")
    if "time" in ds.variables:
        units = str(ds["time"].attrs.get("units", ""))
        if not units.startswith("seconds since "):
            problems.append(
                f"variable 'time': units expected 'seconds since <campaign start>', got {units!r}"
            )
        t = np.asarray(ds["time"].values, dtype=float)
        if t.size and not np.all(np.isfinite(t)):
            problems.append("variable 'time': expected finite values, found NaN or inf")
        elif t.size > 1 and np.any(np.diff(t) < 0):
            i = int(np.argmax(np.diff(t) < 0))
            problems.append(
                f"variable 'time': expected non-decreasing values, got {t[i]!r} then {t[i + 1]!r} "
                f"at sample {i + 1}"
            )
    joints = robot_joints(str(ds.attrs.get("robot")))
    for joint in joints:
        for prefix in ("cmd", "meas"):
            if f"{prefix}_{joint}" not in ds.variables:
                problems.append(f"variable '{prefix}_{joint}': missing for robot {ds.attrs.get('robot')!r}")
    known = run_variables()
    for name, var in ds.data_vars.items():
        if name in known:
            units, _ = known[name]
            got = var.attrs.get("units")
            if got is not None and got != units:
                problems.append(f"variable '{name}': units expected {units!r}, got {got!r}")
            expected_dims = ("sample", "sensor") if name == "temperature" else ("sample",)
            if var.dims != expected_dims:
                problems.append(f"variable '{name}': dims expected {expected_dims}, got {var.dims}")
    for name in sorted(n for n in ds.data_vars if n.startswith("meas_")):
        values = np.asarray(ds[name].values, dtype=float)
        if values.size and not np.any(np.isfinite(values)):
            problems.append(f"variable '{name}': expected measurements, every value is NaN")
    problems += _check_decoder(ds)
    if "direction" in ds.variables:
        bad = ~np.isin(ds["direction"].values, (-1, 0, 1))
        if bad.any():
            problems.append("variable 'direction': expected values in {-1, 0, +1}")
    if "plan" not in ds.attrs:
        problems.append("global attribute 'plan': missing")
    return problems


def _check_decoder(ds: xr.Dataset) -> list[str]:
    """The optional variables of a sensor that decodes images: ``u_meas_*`` beside their
    ``meas_*``, non-negative; ``decode_status`` integer CF flags, NaN readings where not 0."""
    problems = []
    for name in sorted(n for n in ds.data_vars if n.startswith("u_meas_")):
        if name[2:] not in ds.data_vars:
            problems.append(f"variable '{name}': expected beside '{name[2:]}', which is missing")
        values = np.asarray(ds[name].values, dtype=float)
        if np.any(values[np.isfinite(values)] < 0):
            problems.append(
                f"variable '{name}': expected standard uncertainties >= 0, found a negative value"
            )
    if "decode_status" in ds.data_vars:
        status = ds["decode_status"]
        flags = status.attrs.get("flag_values")
        if status.dtype.kind not in "iu":
            problems.append(f"variable 'decode_status': expected integer flags, got {status.dtype}")
        elif flags is None or "flag_meanings" not in status.attrs:
            problems.append(
                "variable 'decode_status': attributes 'flag_values' and 'flag_meanings' missing (CF flags)"
            )
        else:
            values = np.asarray(status.values)
            if not np.all(np.isin(values, np.asarray(flags))):
                problems.append(
                    f"variable 'decode_status': expected values in flag_values {list(np.asarray(flags))}"
                )
            failed = values != 0
            for name in sorted(n for n in ds.data_vars if n.startswith("meas_")):
                if np.any(np.isfinite(np.asarray(ds[name].values, dtype=float)[failed])):
                    problems.append(f"variable '{name}': expected NaN where decode_status is not 0 (ok)")
    return problems


def _looks_like_run(ds: xr.Dataset) -> bool:
    """A run's shape: dimension ``sample`` with plan indices, commands and measurements."""
    names = set(ds.variables)
    return (
        "sample" in ds.dims
        and {"pose", "cycle", "direction"} <= names
        and any(n.startswith("cmd_") for n in names)
        and any(n.startswith("meas_") for n in names)
    )


def validate_dataset(ds: xr.Dataset) -> list[str]:
    """Return the list of contract violations of ``ds`` (empty when it conforms)."""
    problems = _check_global(ds) + _check_cf_variables(ds)
    kind = ds.attrs.get("calflow_kind")
    if kind != "run" and kind in KINDS and _looks_like_run(ds):
        problems.append(
            f"global attribute 'calflow_kind': expected 'run' for a dataset of settled samples "
            f"(dimension 'sample', pose, cycle, direction, cmd_*, meas_*), got {kind!r}"
        )
    if kind == "run" or _looks_like_run(ds):
        problems += _check_run(ds)
    return problems


def validate_file(path: str | os.PathLike) -> list[str]:
    """Validate a netCDF file; each problem is prefixed with the file name.

    A file that cannot be opened yields a single problem naming the file and the reason.
    """
    path = Path(path)
    if not path.exists():
        return [f"{path}: file not found"]
    try:
        with xr.open_dataset(path, engine="netcdf4", decode_times=False) as ds:
            ds.load()
            return [f"{path}: {p}" for p in validate_dataset(ds)]
    except DataError as exc:
        return [str(exc)]
    except Exception as exc:
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        return [f"{path}: not a readable netCDF4 file ({reason})"]
