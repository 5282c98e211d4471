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

from calflow.errors import RigError
from calflow.rigs.protocol import Rig, missing_members

_FACTORY_RE = re.compile(r"^[A-Za-z_][\w]*(\.[A-Za-z_][\w]*)*:[A-Za-z_][\w]*$")

# Short names of built-in factories, per robot kind.
BUILTIN = {
    ("simulated", "xytheta"): "calflow.rigs.xytheta:simulated_xytheta",
    ("simulated", "stage1d"): "calflow.rigs.nano:nano1d",
    ("simulated", "stage2d"): "calflow.rigs.nano:nano2d",
    **{("replay", robot): "calflow.rigs.replay:replay" for robot in ("xytheta", "stage1d", "stage2d")},
    **{("gcs", robot): "calflow.rigs.gcs:gcs" for robot in ("xytheta", "stage1d", "stage2d")},
}


def resolve_factory(name: str, robot: str) -> tuple[Callable[..., Any], str]:
    """Return the factory callable named by ``name`` and the data ``source`` it implies."""
    if (name, robot) in BUILTIN:
        target, source = BUILTIN[(name, robot)], name
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
