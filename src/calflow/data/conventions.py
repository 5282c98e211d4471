"""Names, units and attributes of calflow datasets (docs/architecture.md, "Datasets").

Lengths are in micrometres (``um``), angles in ``degree``, temperatures in ``degC``;
time is CF time in seconds since the campaign start.
"""

from __future__ import annotations

import datetime as _dt

CF_CONVENTIONS = "CF-1.11"

KINDS = ("run", "model", "metrics", "luts", "truth")
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

# Units of the quantities a joint or sensor of each name carries; a robot family adds its
# own axes (calflow.family.Family.axes), and says which joints each of its robots has
# (Family.joints): the core names no robot.
AXIS_UNITS = {"x": "um", "y": "um", "z": "um", "theta": "degree"}
AXIS_NAMES = {"x": "x", "y": "y", "z": "z", "theta": "rotation angle"}


def _axis_variables(axis: str, unit: str, name: str) -> dict[str, tuple[str, str]]:
    return {
        f"cmd_{axis}": (unit, f"joint command {name}"),
        f"meas_{axis}": (unit, f"external sensor reading {name} in the sensor frame"),
        f"u_meas_{axis}": (unit, f"standard uncertainty of the sensor reading {name} (its decoder's)"),
        f"target_{axis}": (unit, f"task-space target {name}"),
    }


# variable -> (units, long_name) for the run dataset (calflow_kind = "run").
RUN_VARIABLES: dict[str, tuple[str, str]] = {
    "pose": ("1", "index of the plan pose"),
    "cycle": ("1", "index of the plan cycle"),
    "direction": ("1", "approach direction (+1 forward, -1 backward, 0 none)"),
}
for _axis, _unit in AXIS_UNITS.items():
    RUN_VARIABLES.update(_axis_variables(_axis, _unit, AXIS_NAMES[_axis]))
RUN_VARIABLES["temperature"] = ("degC", "thermocouple temperature")
# Optional, from a sensor that decodes images (calflow.instruments.pattern): per reading,
# the decoder's status (CF flags: 0 decoded; the others name why the frame was not).
RUN_VARIABLES["decode_status"] = ("1", "decode status of the sensor's frame")

REQUIRED_RUN_VARIABLES = ("time", "pose", "cycle", "direction")


def run_variables() -> dict[str, tuple[str, str]]:
    """:data:`RUN_VARIABLES` and the ``cmd_``/``meas_``/``target_`` variables of every
    installed family's own axes (:attr:`calflow.family.Family.axes`)."""
    from calflow.family import axes

    out = dict(RUN_VARIABLES)
    for axis, (unit, name) in axes().items():
        for var, spec in _axis_variables(axis, unit, name).items():
            out.setdefault(var, spec)
    return out


def robots() -> tuple[str, ...]:
    """The robots of every installed family (:func:`calflow.family.robots`)."""
    from calflow.family import robots as _robots

    return _robots()


def robot_joints(robot: str) -> tuple[str, ...]:
    """The joints of ``robot``'s runs, in order, from its family; ``()`` when none serves it."""
    from calflow.family import joints

    return joints(robot)


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
