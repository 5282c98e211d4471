"""Building a rig from a campaign's ``rig`` section: the factory that
:mod:`calflow.configuration.rig_factory` names and allows, called with the options, and
what it returns checked against the rig protocol (:mod:`calflow.rigs.protocol`).

The names and the check of the ``rig`` section (built-in rigs, plug-ins allowed outside the
campaign file, "Plugins are code") are :mod:`calflow.configuration.rig_factory`'s, served
here too.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

from calflow.configuration.rig_factory import (
    CORE_OPTION_CHECKS,
    CORE_RIGS,
    ENV,
    GROUP,
    HOW_TO_ALLOW,
    allowed_modules,
    builtin,
    check_rig,
    is_allowed,
    registered,
    resolve_factory,
    target_of,
)
from calflow.errors import RigError
from calflow.rigs.protocol import Rig, missing_members

__all__ = [
    "CORE_OPTION_CHECKS",
    "CORE_RIGS",
    "ENV",
    "GROUP",
    "HOW_TO_ALLOW",
    "allowed_modules",
    "builtin",
    "check_rig",
    "is_allowed",
    "load_rig",
    "registered",
    "resolve_factory",
    "target_of",
]


def load_rig(
    name: str, robot: str, options: Mapping[str, Any], allowed: Iterable[str] | str | None = None
) -> tuple[Rig, str]:
    """Build a rig with ``factory(**options)``; return it and its data ``source``."""
    factory, source = resolve_factory(name, robot, allowed)
    try:
        rig = factory(**dict(options))
    except (TypeError, ValueError) as exc:
        raise RigError(f"rig.options: factory {name!r} rejected the options ({exc})") from None
    missing = missing_members(rig)
    if missing:
        raise RigError(f"rig.factory: {name!r} returned an object without {', '.join(missing)}")
    return rig, source
