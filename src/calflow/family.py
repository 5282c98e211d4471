"""Robot families: what each family of robots registers with the core.

The core (config, data, acquisition, rigs, metrics, reports, the CLI) knows no robot. A
family — :mod:`calflow.xytheta`, :mod:`calflow.nano`, or a third-party package — describes
itself with one :class:`Family` and registers it as an entry point of the group
``calflow.families`` in its ``pyproject.toml``::

    [project.entry-points."calflow.families"]
    xytheta = "calflow.xytheta.family:FAMILY"

Everything heavy is named as ``"module:attribute"`` and imported only when a command
needs it, so ``calflow --help`` loads no numerical library. docs/families.md sketches a
third family.
"""

from __future__ import annotations

import argparse
import importlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from functools import lru_cache
from importlib.metadata import entry_points
from typing import Any

from calflow.errors import CalflowError

GROUP = "calflow.families"


@dataclass(frozen=True)
class Command:
    """A CLI subcommand a family adds: ``calflow <name> ...``.

    ``arguments(parser)`` declares its options (argparse only, nothing heavy);
    ``run`` names the function ``run(args) -> int | None`` it calls.
    """

    name: str
    help: str
    arguments: Callable[[argparse.ArgumentParser], None]
    run: str


@dataclass(frozen=True)
class Family:
    """One family of robots and what it brings to each workflow step.

    * ``robots``: the campaign ``robot`` values it serves (``xytheta``; ``stage1d``, ``stage2d``).
    * ``rigs``: built-in rig short names per robot, ``{robot: {"simulated": "module:factory"}}``.
    * ``plans``: per robot, plan name → ``"module:builder"``, ``builder(campaign, args)`` →
      :class:`calflow.plan.Acquisition`. ``calflow acquire --plan NAME`` looks the plan up here.
    * ``rig_options``: ``"module:function"``, ``function(campaign, factory, run_id, options,
      start_s) -> options``: what a run adds to the campaign's rig options (seeds, streams).
    * ``steps``: ``identify``, ``metrics`` (``function(args)``), ``summarise``
      (``function(campaign, files, truth) -> dict``) and ``figures`` (``function(summary,
      inputs) -> (figures, notes)``).
    * ``templates``: the package whose ``templates/`` folder holds ``<robot>.html.j2``.
    * ``modules``: per step, the modules whose code decides that step's outputs, so a
      change to them reruns the step's jobs (:mod:`calflow.provenance`).
    * ``acquire_arguments``: options the family's plans read from ``calflow acquire``.
    * ``commands``: the family's own subcommands.
    * ``sensors``: short names of sensor factories for the ``gcs`` rig.
    * ``emulator``: ``"module:function"``, ``function(argv, prog=...) -> int`` serving a
      campaign's stages as a GCS controller (``calflow emulate gcs --campaign FILE``).
    """

    name: str
    robots: tuple[str, ...]
    rigs: Mapping[str, Mapping[str, str]]
    plans: Mapping[str, Mapping[str, str]]
    rig_options: str
    steps: Mapping[str, str]
    templates: str
    modules: Mapping[str, tuple[str, ...]]
    acquire_arguments: Callable[[argparse.ArgumentParser], None] | None = None
    commands: tuple[Command, ...] = ()
    sensors: Mapping[str, str] = field(default_factory=dict)
    emulator: str | None = None

    def step(self, name: str) -> Callable[..., Any]:
        if name not in self.steps:
            raise CalflowError(f"calflow: the {self.name} family has no step {name!r}")
        return resolve(self.steps[name])

    def plan(self, robot: str, name: str) -> Callable[..., Any]:
        plans = self.plans.get(robot, {})
        if name not in plans:
            raise CalflowError(
                f"calflow acquire: --plan {name!r} is not a plan of a {robot} campaign; "
                f"expected one of {', '.join(plans)}"
            )
        return resolve(plans[name])


def resolve(target: str) -> Any:
    """The attribute named by ``"module:attribute"``."""
    module, _, attr = target.partition(":")
    return getattr(importlib.import_module(module), attr)


@lru_cache(maxsize=1)
def families() -> tuple[Family, ...]:
    """Every installed family, in entry-point name order."""
    found = []
    for ep in sorted(entry_points(group=GROUP), key=lambda e: e.name):
        fam = ep.load()
        if not isinstance(fam, Family):
            raise CalflowError(f"entry point {GROUP}:{ep.name}: {ep.value} is not a calflow.family.Family")
        found.append(fam)
    return tuple(found)


def family_of(robot: str) -> Family:
    """The family that serves campaigns with ``robot``."""
    for fam in families():
        if robot in fam.robots:
            return fam
    known = sorted(r for fam in families() for r in fam.robots)
    raise CalflowError(f"robot {robot!r}: no installed calflow family serves it; expected one of {known}")


def robots() -> tuple[str, ...]:
    return tuple(r for fam in families() for r in fam.robots)
