"""Building run datasets (``calflow_kind = "run"``) from acquired samples."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import xarray as xr

from calflow import __version__
from calflow.data.conventions import CF_CONVENTIONS, run_variables, time_units, utc_now


@dataclass
class RunMetadata:
    """Global attributes of a run dataset (docs/architecture.md, "Datasets")."""

    campaign: str
    robot: str
    source: str
    plan: str
    config_sha256: str
    start: str = "2026-01-01T00:00:00+00:00"
    model: str | None = None
    history: str = ""
    extra: dict = field(default_factory=dict)

    def attrs(self, kind: str = "run") -> dict:
        attrs = {
            "Conventions": CF_CONVENTIONS,
            "calflow_kind": kind,
            "calflow_version": __version__,
            "campaign": self.campaign,
            "robot": self.robot,
            "source": self.source,
            "plan": self.plan,
            "created": utc_now(),
            "config_sha256": self.config_sha256,
            "history": self.history or f"{utc_now()} calflow {__version__}",
        }
        if self.model:
            attrs["model"] = self.model
        attrs.update(self.extra)
        return attrs


def _command(argv: list[str]) -> list[str]:
    """The command line a file's ``history`` records: without ``--sections``, which only limits
    what the step may read (a step that runs gives the same file with or without it)."""
    out, skip = [], False
    for arg in argv:
        if skip:
            skip = False
        elif arg == "--sections":
            skip = True
        elif not arg.startswith("--sections="):
            out.append(arg)
    return out


def meta(c: dict, source: str, plan: str, model: str | None = None) -> RunMetadata:
    """The global attributes of a file a step writes from campaign ``c`` (the whole campaign or
    the sections it was handed, :mod:`calflow.configuration.handed`): the stamp of the whole
    campaign the file comes from, whichever sections the step reads, and the command line
    that made it (without ``--sections``)."""
    import shlex
    import sys

    from calflow.configuration.campaign import Sections
    from calflow.configuration.config import campaign_digest

    return RunMetadata(
        campaign=c["name"],
        robot=c["robot"],
        source=source,
        plan=plan,
        config_sha256=campaign_digest(c.campaign if isinstance(c, Sections) else c),
        start=c["start"],
        model=model,
        history=f"calflow {__version__}: {' '.join(shlex.quote(a) for a in _command(sys.argv[1:]))}",
    )


def _var(values, name: str, dims=("sample",)) -> xr.Variable:
    units, long_name = run_variables()[name]
    return xr.Variable(dims, values, attrs={"units": units, "long_name": long_name})


def run_dataset(
    readings: Sequence[Mapping[str, float]],
    plan,
    sensors: Sequence[str],
    thermometers: Sequence[str],
    meta: RunMetadata,
    flags: Mapping[str, dict] | None = None,
) -> xr.Dataset:
    """Assemble a run dataset from one reading per plan row.

    ``readings[i]`` is what the rig's ``read()`` returned after row ``i`` settled. ``flags``:
    the sensors whose readings are CF flags (an image sensor's ``decode_status``), each with
    its attributes (:func:`calflow.instruments.readings.flags`); stored as ``int8``.
    """
    n = len(readings)
    data: dict[str, xr.Variable] = {}
    data["time"] = xr.Variable(
        ("sample",),
        np.array([r["time"] for r in readings], dtype=float),
        attrs={"units": time_units(meta.start), "long_name": "time of the reading", "standard_name": "time"},
    )
    for joint, values in plan.commands.items():
        sent = [r.get(f"cmd_{joint}") for r in readings]
        values = np.asarray(values[:n] if any(v is None for v in sent) else sent, dtype=float)
        data[f"cmd_{joint}"] = _var(values, f"cmd_{joint}")
    for axis, values in plan.targets.items():
        data[f"target_{axis}"] = _var(np.asarray(values[:n], dtype=float), f"target_{axis}")
    for sensor in sensors:
        data[sensor] = _var(np.array([r[sensor] for r in readings], dtype=float), sensor)
    for name, attrs in (flags or {}).items():
        if name in data:
            data[name] = xr.Variable(("sample",), data[name].values.astype("int8"), attrs)
    if thermometers:
        temps = np.array([[r[t] for t in thermometers] for r in readings], dtype=float).reshape(
            n, len(thermometers)
        )
        data["temperature"] = _var(temps, "temperature", ("sample", "sensor"))
    data["pose"] = _var(np.asarray(plan.pose[:n], dtype="int32"), "pose")
    data["cycle"] = _var(np.asarray(plan.cycle[:n], dtype="int32"), "cycle")
    data["direction"] = _var(np.asarray(plan.direction[:n], dtype="int8"), "direction")
    if "test" in plan.extra:
        data["test"] = xr.Variable(
            ("sample",),
            np.asarray(plan.extra["test"][:n], dtype="int32"),
            attrs={"units": "1", "long_name": "index of the validation test"},
        )
    if "mode" in plan.extra:
        data["test_mode"] = xr.Variable(
            ("sample",),
            np.asarray(plan.extra["mode"][:n], dtype="int8"),
            attrs={
                "units": "1",
                "long_name": "calibration used by the test",
                "flag_values": np.arange(len(plan.modes), dtype="int8"),
                "flag_meanings": " ".join(plan.modes),
            },
        )
    visits = [r for r in readings if "kmz_time" in r]
    if visits:
        for key, units, long_name in (
            ("kmz_time", None, "time of the kilometre-zero visit"),
            ("kmz_command", "um", "joint command at the kilometre-zero visit"),
            ("kmz_measured", "um", "sensor reading at the kilometre-zero visit"),
        ):
            attrs = {"units": units or time_units(meta.start), "long_name": long_name}
            data[key] = xr.Variable(
                ("kmz_visit",), np.array([r[key] for r in visits], dtype=float), attrs=attrs
            )
    coords = {}
    if thermometers:
        coords["sensor"] = xr.Variable(
            ("sensor",), np.array(list(thermometers), dtype=object), attrs={"long_name": "thermocouple name"}
        )
    ds = xr.Dataset(data, coords=coords, attrs=meta.attrs("run"))
    ds.attrs["dwell_s"] = float(plan.dwell_s)
    return ds
