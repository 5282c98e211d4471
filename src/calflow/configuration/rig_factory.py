"""Which code a campaign's ``rig.factory`` names, and the check of its ``rig`` section.

``rig: {factory: "package.module:callable", options: {...}}`` names any callable
``factory(**options) -> Rig``. Built-in factories have short names (``simulated``). The
factory string is resolved with :func:`importlib.import_module` and :func:`getattr`;
nothing from the configuration is evaluated. Building the rig is :mod:`calflow.rigs.plugin`'s;
this module only names and checks, so that validating a campaign needs nothing of
:mod:`calflow.rigs` (the built-in factories and their option checks are ``module:callable``
names here, resolved when used, as a family's hooks are).

**Plugins are code.** Importing a module runs it, and so does calling its factory: a
campaign file on its own must not run arbitrary code (``factory: "os:system"``). A
``module:callable`` factory is therefore loaded only when the user allowed its module
*outside* the campaign file:

* listed in ``rig_plugins`` of ``config/config.yaml`` (``rig_plugins: [my_lab.rigs]``, or
  ``snakemake --config 'rig_plugins=["my_lab.rigs"]'``); the workflow passes the list to
  its jobs as ``CALFLOW_RIG_PLUGINS``, and ``calflow acquire --rig-plugins`` takes it too;
  a module is allowed when it or a parent package is listed;
* or registered as an entry point of the group ``calflow.rigs`` by an installed package
  (``name = "module:callable"``); a campaign may then say ``factory: <name>``.

Built-in factories (``simulated``, ``replay``, ``gcs``) are always allowed.
"""

from __future__ import annotations

import importlib
import os
import re
from collections.abc import Callable, Iterable, Mapping
from functools import lru_cache
from importlib.metadata import entry_points
from typing import Any

from calflow.errors import CalflowError, ConfigError, OptionError, RigError

_FACTORY_RE = re.compile(r"^[A-Za-z_][\w]*(\.[A-Za-z_][\w]*)*:[A-Za-z_][\w]*$")

# Built-in rigs every robot has: replay of recordings and PI GCS controllers. The robot
# families add their own short names (``simulated``), :class:`calflow.family.Family`.
CORE_RIGS = {"replay": "calflow.rigs.replay:replay", "gcs": "calflow.gcs.rig:gcs"}
# Their option checks, declared as a family declares its own (:attr:`calflow.family.Family.options`).
CORE_OPTION_CHECKS = {
    "calflow.rigs.replay:replay": "calflow.rigs.replay:check_options",
    "calflow.gcs.rig:gcs": "calflow.gcs.rig_options:check_options",
}
GROUP = "calflow.rigs"  # entry points of installed rig plug-ins: name -> "module:callable"
ENV = "CALFLOW_RIG_PLUGINS"  # the allow-list given to a job: module names, comma-separated
HOW_TO_ALLOW = (
    "plugins are code: allow the module outside the campaign file with "
    "'rig_plugins: [{module}]' in config/config.yaml (or snakemake --config "
    "'rig_plugins=[\"{module}\"]', or calflow acquire --rig-plugins {module}), "
    "or register it as a 'calflow.rigs' entry point"
)


def builtin(name: str, robot: str) -> str | None:
    """The ``"module:callable"`` of built-in rig ``name`` for ``robot``, or None."""
    from calflow.family import family_of

    if name in CORE_RIGS:
        return CORE_RIGS[name]
    try:
        return family_of(robot).rigs.get(robot, {}).get(name)
    except CalflowError:  # an unknown robot is reported by the config check
        return None


def _builtin_targets(robot: str) -> set[str]:
    """The ``module:callable`` of every built-in rig (a campaign may name them in full)."""
    from calflow.family import families

    return set(CORE_RIGS.values()) | {
        t for fam in families() for rigs in fam.rigs.values() for t in rigs.values()
    }


@lru_cache(maxsize=1)
def registered() -> dict[str, str]:
    """Rig plug-ins registered as ``calflow.rigs`` entry points: name -> ``"module:callable"``."""
    return {ep.name: ep.value for ep in entry_points(group=GROUP)}


def allowed_modules(allowed: Iterable[str] | str | None = None) -> tuple[str, ...]:
    """The allow-list: ``allowed`` if given (a list, or a comma-separated string), else
    the environment variable ``CALFLOW_RIG_PLUGINS``."""
    if allowed is None:
        allowed = os.environ.get(ENV, "")
    if isinstance(allowed, str):
        allowed = allowed.replace(" ", ",").split(",")
    return tuple(m.strip() for m in allowed if m and m.strip())


def is_allowed(module: str, allowed: Iterable[str] | str | None = None) -> bool:
    """True when ``module`` or a parent package is allowed, or it provides a registered plug-in."""
    names = allowed_modules(allowed) + tuple(v.partition(":")[0] for v in registered().values())
    return any(module == a or module.startswith(a + ".") for a in names)


def target_of(name: str, robot: str, allowed: Iterable[str] | str | None = None) -> tuple[str, str]:
    """``("module:callable", source)`` of factory ``name``, refusing modules not allowed."""
    target = builtin(name, robot)
    if target is not None:
        return target, name
    if name in registered():
        return registered()[name], "plugin"
    if not _FACTORY_RE.match(name):
        extra = f", a registered plug-in ({', '.join(sorted(registered()))})" if registered() else ""
        raise RigError(
            f"rig.factory: expected 'simulated', 'replay', 'gcs'{extra} or "
            f"'package.module:callable', got {name!r}"
        )
    module = name.partition(":")[0]
    if not is_allowed(module, allowed) and name not in _builtin_targets(robot):
        raise RigError(f"rig.factory: {name!r} is not allowed to run; " + HOW_TO_ALLOW.format(module=module))
    return name, "plugin"


def resolve_factory(
    name: str,
    robot: str,
    allowed: Iterable[str] | str | None = None,
) -> tuple[Callable[..., Any], str]:
    """Return the factory callable named by ``name`` and the data ``source`` it implies.

    ``allowed``: the modules a ``module:callable`` factory may come from (default: the
    ``CALFLOW_RIG_PLUGINS`` environment variable); see the module docstring.
    """
    target, source = target_of(name, robot, allowed)
    module_name, attr = target.split(":")
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        raise RigError(f"rig.factory: cannot import module {module_name!r} ({exc})") from None
    factory = getattr(module, attr, None)
    if not callable(factory):
        raise RigError(f"rig.factory: module {module_name!r} has no callable {attr!r}")
    return factory, source


def check_rig(
    campaign: Mapping[str, Any], path, allowed: Iterable[str] | str | None = None, plugins: bool = True
) -> None:
    """The config check of a campaign's ``rig`` section; raises :class:`ConfigError` naming
    ``path`` and the key.

    The factory must be built in, registered, or (with ``plugins``) an allowed, importable
    callable. The option check declared for it (the core's :data:`CORE_OPTION_CHECKS`, its
    family's :attr:`calflow.family.Family.options`), else a ``check_options(**options)``
    attribute of the factory (a rig plug-in outside any family, docs/rigs.md), has its
    options checked for every run (``rig.options`` merged with ``rig.runs.<run>``)
    without building the rig. With ``plugins=False``, a ``module:callable`` factory is left
    alone: no plug-in module is imported (commands that do not open the rig).
    """
    rig, robot = campaign["rig"], campaign["robot"]
    name = rig["factory"]
    if not plugins and builtin(name, robot) is None:
        return
    try:
        factory, _ = resolve_factory(name, robot, allowed)
        target, _ = target_of(name, robot, allowed)
    except RigError as exc:
        detail = str(exc).removeprefix("rig.factory: ")
        raise ConfigError(f"{path}: key 'rig.factory': {detail}") from None
    from calflow.family import option_check, resolve

    declared = CORE_OPTION_CHECKS.get(target)
    check = resolve(declared) if declared else option_check(target) or getattr(factory, "check_options", None)
    if check is None:
        return
    options = dict(rig.get("options") or {})
    for where, opts in [("rig.options", options)] + [
        (f"rig.runs.{run}", {**options, **extra}) for run, extra in (rig.get("runs") or {}).items()
    ]:
        try:
            check(**opts)
        except OptionError as exc:
            if where != "rig.options" and exc.option not in rig["runs"][where.split(".", 2)[2]]:
                where = "rig.options"
            raise ConfigError(exc.at(path, where)) from None
        except (TypeError, ValueError) as exc:
            raise ConfigError(
                f"{path}: key '{where}': the {name!r} rig rejected the options ({exc})"
            ) from None
