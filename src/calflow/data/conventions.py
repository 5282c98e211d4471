"""Names, units and attributes of calflow datasets (docs/architecture.md, "Datasets").

Lengths are in micrometres (``um``), angles in ``degree``, temperatures in ``degC``;
time is CF time in seconds since the campaign start.
"""

from __future__ import annotations

import datetime as _dt

CF_CONVENTIONS = "CF-1.11"

KINDS = ("run", "model", "metrics", "luts", "truth")
ROBOTS = ("xytheta", "stage1d", "stage2d")
SOURCES = ("simulated", "replay", "gcs", "plugin")
PLANS = (
    "characterisation_x",
    "characterisation_y",
    "identification",
    "angle_residuals",
    "validation",
    "training",
    "metrology",
    "square",
    "random_points",
)

GLOBAL_ATTRS = (
    "Conventions",
    "calflow_kind",
    "calflow_version",
    "campaign",
    "robot",
    "source",
    "created",
    "config_sha256",
    "history",
)

# Units of the quantities a joint or sensor of each name carries.
AXIS_UNITS = {"x": "um", "y": "um", "z": "um", "theta": "degree"}
AXIS_NAMES = {"x": "x", "y": "y", "z": "z", "theta": "rotation angle"}

# variable -> (units, long_name) for the run dataset (calflow_kind = "run").
RUN_VARIABLES: dict[str, tuple[str, str]] = {
    "pose": ("1", "index of the plan pose"),
    "cycle": ("1", "index of the plan cycle"),
    "direction": ("1", "approach direction (+1 forward, -1 backward, 0 none)"),
}
for _axis, _unit in AXIS_UNITS.items():
    _name = AXIS_NAMES[_axis]
    RUN_VARIABLES[f"cmd_{_axis}"] = (_unit, f"joint command {_name}")
    RUN_VARIABLES[f"meas_{_axis}"] = (_unit, f"external sensor reading {_name} in the sensor frame")
    RUN_VARIABLES[f"target_{_axis}"] = (_unit, f"task-space target {_name}")
RUN_VARIABLES["temperature"] = ("degC", "thermocouple temperature")

REQUIRED_RUN_VARIABLES = ("time", "pose", "cycle", "direction")
ROBOT_JOINTS = {"xytheta": ("x", "y", "theta"), "stage1d": ("x",), "stage2d": ("x", "y")}


def utc_now() -> str:
    """The current UTC time as an ISO 8601 string (seconds).

    Honours ``SOURCE_DATE_EPOCH`` (reproducible-builds convention), so two runs of a
    campaign can produce byte-identical files.
    """
    import os

    epoch = os.environ.get("SOURCE_DATE_EPOCH")
    now = (
        _dt.datetime.fromtimestamp(int(epoch), _dt.UTC)
        if epoch and epoch.isdigit()
        else _dt.datetime.now(_dt.UTC)
    )
    return now.replace(microsecond=0).isoformat()


def time_units(start: str) -> str:
    """CF units string for seconds since the campaign start ``start`` (ISO 8601)."""
    return f"seconds since {start}"
