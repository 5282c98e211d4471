"""Loading a rig from a campaign's ``rig`` section.

``rig: {factory: "package.module:callable", options: {...}}`` names any callable
``factory(**options) -> Rig``. Built-in factories have short names (``simulated``). The
factory string is resolved with :func:`importlib.import_module` and :func:`getattr`;
nothing from the configuration is evaluated.
"""

from __future__ import annotations

import importlib
import re
from typing import Any, Callable, Mapping

from calflow.errors import CalflowError, RigError
from calflow.rigs.protocol import Rig, missing_members

_FACTORY_RE = re.compile(r"^[A-Za-z_][\w]*(\.[A-Za-z_][\w]*)*:[A-Za-z_][\w]*$")

# Built-in rigs every robot has: replay of recordings and PI GCS controllers. The robot
# families add their own short names (``simulated``), :class:`calflow.family.Family`.
CORE_RIGS = {"replay": "calflow.rigs.replay:replay", "gcs": "calflow.gcs.rig:gcs"}


def builtin(name: str, robot: str) -> str | None:
    """The ``"module:callable"`` of built-in rig ``name`` for ``robot``, or None."""
    from calflow.family import family_of

    if name in CORE_RIGS:
        return CORE_RIGS[name]
    try:
        return family_of(robot).rigs.get(robot, {}).get(name)
    except CalflowError:  # an unknown robot is reported by the config check
        return None


def resolve_factory(name: str, robot: str) -> tuple[Callable[..., Any], str]:
    """Return the factory callable named by ``name`` and the data ``source`` it implies."""
    target = builtin(name, robot)
    if target is not None:
        source = name
    elif _FACTORY_RE.match(name):
        target, source = name, "plugin"
    else:
        raise RigError(
            f"rig.factory: expected 'simulated', 'replay', 'gcs' or 'package.module:callable', got {name!r}"
        )
    module_name, attr = target.split(":")
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        raise RigError(f"rig.factory: cannot import module {module_name!r} ({exc})") from None
    factory = getattr(module, attr, None)
    if not callable(factory):
        raise RigError(f"rig.factory: module {module_name!r} has no callable {attr!r}")
    return factory, source


def load_rig(name: str, robot: str, options: Mapping[str, Any]) -> tuple[Rig, str]:
    """Build a rig with ``factory(**options)``; return it and its data ``source``."""
    factory, source = resolve_factory(name, robot)
    try:
        rig = factory(**dict(options))
    except (TypeError, ValueError) as exc:
        raise RigError(f"rig.options: factory {name!r} rejected the options ({exc})") from None
    missing = missing_members(rig)
    if missing:
        raise RigError(f"rig.factory: {name!r} returned an object without {', '.join(missing)}")
    return rig, source
