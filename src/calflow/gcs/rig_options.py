"""The config check of the ``gcs`` rig's options (docs/gcs.md, "The gcs rig").

:func:`check_options` is what ``calflow check-config`` and ``snakemake -n`` run
(:func:`calflow.configuration.rig_factory.check_rig`): every option's type and range, without opening a
connection or importing a sensor plug-in; a family's sensor has its options checked by its
family (:attr:`calflow.family.Family.options`). It raises :class:`OptionError` naming the option
(``axes.x.port``, ``reconnect.tries``, ...), which the config check turns into one line
naming the file and the key.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from calflow.errors import OptionError, UnknownOptionError
from calflow.gcs.emulation.controller import parse_parameter_id
from calflow.gcs.wire.protocol import check_axis

OPTIONS = (
    "axes",
    "host",
    "port",
    "serial",
    "baudrate",
    "timeout",
    "sensor",
    "reconnect",
    "reference",
    "servo",
    "scale",
    "velocity",
    "time_scale",
    "move_timeout_s",
    "poll_s",
    "recorder",
    "parameters",
)
LINK = ("host", "port", "serial", "baudrate")
RECONNECT = {"tries": "int", "backoff_s": ">=", "max_backoff_s": ">="}
RECORDER = {"rate_hz": ">", "servo_cycle_s": ">"}


def _number(name: str, value: Any, bound: str | None = ">") -> float:
    """A finite number (``bound``: ">" positive, ">=" non-negative, "!=" non-zero)."""
    expected = {
        ">": "a finite number > 0",
        ">=": "a finite number >= 0",
        "!=": "a finite non-zero number",
        None: "a finite number",
    }[bound]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise OptionError(name, expected, value)
    v = float(value)
    if (
        not math.isfinite(v)
        or (bound == ">" and v <= 0)
        or (bound == ">=" and v < 0)
        or (bound == "!=" and v == 0)
    ):
        raise OptionError(name, expected, value)
    return v


def _integer(name: str, value: Any, low: int, high: int | None = None) -> int:
    if (
        isinstance(value, bool)
        or not isinstance(value, int)
        or value < low
        or (high is not None and value > high)
    ):
        raise OptionError(name, f"an integer {low}-{high}" if high else f"an integer >= {low}", value)
    return value


def _mapping(name: str, value: Any) -> Mapping:
    if not isinstance(value, Mapping):
        raise OptionError(name, "a mapping", value)
    return value


def _link(prefix: str, spec: Mapping[str, Any]) -> None:
    if spec.get("host") is not None and not isinstance(spec["host"], str):
        raise OptionError(f"{prefix}host", "a host name or address (string)", spec["host"])
    if spec.get("serial") is not None and not isinstance(spec["serial"], str):
        raise OptionError(f"{prefix}serial", "a serial device or URL (string)", spec["serial"])
    if spec.get("port") is not None:
        _integer(f"{prefix}port", spec["port"], 1, 65535)
    if spec.get("baudrate") is not None:
        _integer(f"{prefix}baudrate", spec["baudrate"], 1)


def _axes(axes: Any, shared: Mapping[str, Any]) -> list[str]:
    if not isinstance(axes, Mapping) or not axes:
        raise OptionError("axes", "a mapping of joint names to controller axis ids", axes)
    for joint, spec in axes.items():
        spec = dict(spec) if isinstance(spec, Mapping) else {"axis": spec}
        unknown = sorted(set(spec) - {"axis", *LINK})
        if unknown:
            raise UnknownOptionError(f"axes.{joint}.{unknown[0]}", "expected axis, " + ", ".join(LINK))
        if "axis" not in spec:
            raise OptionError(f"axes.{joint}.axis", "the controller's axis id", None)
        if isinstance(spec["axis"], bool) or not isinstance(spec["axis"], (str, int)):
            raise OptionError(f"axes.{joint}.axis", "a GCS axis id (1-16 of A-Z a-z 0-9 _)", spec["axis"])
        try:
            check_axis(spec["axis"])
        except ValueError:
            raise OptionError(
                f"axes.{joint}.axis", "a GCS axis id (1-16 of A-Z a-z 0-9 _)", spec["axis"]
            ) from None
        _link(f"axes.{joint}.", spec)
        link = {**shared, **{k: spec[k] for k in LINK if k in spec}}
        if ("host" in spec) != ("serial" in spec):  # a per-joint link replaces the shared one
            link["serial" if "host" in spec else "host"] = None
        if (link.get("host") is None) == (link.get("serial") is None):
            raise OptionError(
                f"axes.{joint}", "exactly one of 'host' (TCP) or 'serial' for its controller", dict(spec)
            )
    return [str(j) for j in axes]


def _per_joint(name: str, value: Any, joints: list[str], bound: str) -> None:
    for joint, v in _mapping(name, value).items():
        if str(joint) not in joints:
            raise OptionError(f"{name}.{joint}", f"one of the joints {joints}", joint)
        _number(f"{name}.{joint}", v, bound)


def _section(name: str, value: Any, keys: Mapping[str, str]) -> None:
    for key, v in _mapping(name, value).items():
        if key not in keys:
            raise UnknownOptionError(f"{name}.{key}", "expected " + ", ".join(keys))
        if keys[key] == "int":
            _integer(f"{name}.{key}", v, 0)
        else:
            _number(f"{name}.{key}", v, keys[key])


def check_options(**options: Any) -> dict[str, Any]:
    """The ``gcs`` rig's options checked (module doc); returns them unchanged."""
    for key in options:
        if key not in OPTIONS:
            raise UnknownOptionError(key, "expected one of " + ", ".join(OPTIONS))
    _link("", options)
    joints = _axes(options.get("axes"), {k: options.get(k) for k in LINK})
    for key in ("timeout", "time_scale", "move_timeout_s", "poll_s"):
        if key in options:
            _number(key, options[key], ">")
    for key in ("reference", "servo"):
        if key in options and not isinstance(options[key], bool):
            raise OptionError(key, "true or false", options[key])
    if "scale" in options:
        _per_joint("scale", options["scale"], joints, "!=")
    if "velocity" in options:
        _per_joint("velocity", options["velocity"], joints, ">")
    if options.get("reconnect") is not None:
        _section("reconnect", options["reconnect"], RECONNECT)
    if options.get("recorder") is not None:
        _section("recorder", options["recorder"], RECORDER)
    for joint, values in _mapping("parameters", options.get("parameters") or {}).items():
        if str(joint) not in joints:
            raise OptionError(f"parameters.{joint}", f"one of the joints {joints}", joint)
        for pid, value in _mapping(f"parameters.{joint}", values).items():
            try:
                parse_parameter_id(str(pid))
            except ValueError:
                raise OptionError(f"parameters.{joint}.{pid}", "a parameter ID (0x36 or 54)", pid) from None
            _number(f"parameters.{joint}.{pid}", value, None)
    sensor = options.get("sensor")
    if not isinstance(sensor, Mapping) or not isinstance(sensor.get("factory"), str):
        raise OptionError(
            "sensor",
            "{factory: 'simulated_vision' | 'camera' | 'package.module:callable', options: {...}}",
            sensor,
        )
    unknown = sorted(set(sensor) - {"factory", "options"})
    if unknown:
        raise UnknownOptionError(f"sensor.{unknown[0]}", "expected factory, options")
    if sensor.get("options") is not None:
        _mapping("sensor.options", sensor["options"])
    _sensor_options(sensor["factory"], dict(sensor.get("options") or {}))
    return dict(options)


def _sensor_options(name: str, options: dict) -> None:
    """The sensor's options, checked by the family that provides it (a registered short name
    or its ``module:callable``; :attr:`calflow.family.Family.options`); a plug-in sensor no
    family declares is checked when the rig opens."""
    from calflow.family import option_check
    from calflow.gcs.sensors import builtin_sensors

    check = option_check(builtin_sensors().get(name, name))
    if check is None:
        return
    try:
        check(**options)
    except OptionError as exc:
        raise OptionError(
            f"sensor.options.{exc.option}", exc.expected, exc.value, unknown=exc.unknown
        ) from None
    except (TypeError, ValueError) as exc:
        raise OptionError("sensor.options", f"options the {name!r} sensor accepts ({exc})", options) from None
