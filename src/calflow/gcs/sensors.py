"""Sensor plug-ins of the ``gcs`` rig (docs/gcs.md, "Sensor drivers").

The ``gcs`` rig moves PI stages; what it measures comes from a *sensor*: any object with

* ``sensors: tuple[str, ...]`` and ``thermometers: tuple[str, ...]`` (the rig's own),
* ``read(positions: Mapping[str, float], time_s: float) -> Mapping[str, float]``: one
  value per sensor and thermometer; ``positions`` are the stages' actual positions
  (``POS?``) per joint in rig units (µm, degree), ``time_s`` the rig's time,
* optionally ``close()``.

A sensor is named in the rig options as ``sensor: {factory: "module:callable", options:
{...}}``; ``factory(**options)`` returns it. Short names (``simulated_vision``) are the
sensors the installed robot families register (:mod:`calflow.family`) and the core's
``camera`` (a camera over a coded pattern, :mod:`calflow.gcs.camera`).
"""

from __future__ import annotations

import importlib
import re
from collections.abc import Mapping
from typing import Any

from calflow.errors import RigError
from calflow.family import families

_FACTORY_RE = re.compile(r"^[A-Za-z_]\w*(\.[A-Za-z_]\w*)*:[A-Za-z_]\w*$")


CORE_SENSORS = {"camera": "calflow.gcs.camera:camera_sensor"}  # a camera over a pattern (gcs.camera)


def builtin_sensors() -> dict[str, str]:
    """Short sensor names: the core's (``camera``) and those the families register, to ``"module:callable"``."""
    return {**CORE_SENSORS, **{name: target for fam in families() for name, target in fam.sensors.items()}}


def resolve(target: str, name: str, where: str = "sensor.factory"):
    """The callable ``target`` (``"module:callable"``) of the factory the options call ``name``;
    a name that is not a registered short name is plug-in code and must be allowed."""
    if not _FACTORY_RE.match(target):
        raise RigError(
            f"gcs rig: {where}: expected a registered name or 'package.module:callable', got {name!r}"
        )
    module_name, attr = target.split(":")
    from calflow.configuration.rig_factory import HOW_TO_ALLOW, is_allowed

    if target == name and not is_allowed(module_name):  # not a registered short name: plug-in code
        raise RigError(
            f"gcs rig: {where}: {name!r} is not allowed to run; " + HOW_TO_ALLOW.format(module=module_name)
        )
    try:
        factory = getattr(importlib.import_module(module_name), attr, None)
    except ImportError as exc:
        raise RigError(f"gcs rig: {where}: cannot import module {module_name!r} ({exc})") from None
    if not callable(factory):
        raise RigError(f"gcs rig: {where}: module {module_name!r} has no callable {attr!r}")
    return factory


def load_sensor(spec: Mapping[str, Any] | None) -> Any:
    """Build the sensor named by ``{factory, options}`` and check its interface."""
    if not isinstance(spec, Mapping) or "factory" not in spec:
        raise RigError(
            "gcs rig: option 'sensor' is required: {factory: 'simulated_vision', 'camera' or "
            "'package.module:callable', options: {...}}"
        )
    name, options = str(spec["factory"]), dict(spec.get("options") or {})
    target = builtin_sensors().get(name, name)
    if not _FACTORY_RE.match(target):
        raise RigError(
            f"gcs rig: sensor.factory: expected 'simulated_vision', 'camera' or 'package.module:callable', got {name!r}"
        )
    factory = resolve(target, name)
    try:
        sensor = factory(**options)
    except (TypeError, ValueError) as exc:
        raise RigError(f"gcs rig: sensor.options: {name!r} rejected the options ({exc})") from None
    missing = [m for m in ("sensors", "thermometers", "read") if not hasattr(sensor, m)]
    if missing:
        raise RigError(f"gcs rig: sensor {name!r} returned an object without {', '.join(missing)}")
    return sensor
