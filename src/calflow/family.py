"""Robot families: what each family of robots registers with the core.

The core (config, data, acquisition, rigs, metrics, reports, the CLI) knows no robot. A
family — calflow's own XYΘ and nano families, or a third-party package — describes
itself with one :class:`Family` and registers it as an entry point of the group
``calflow.families`` in its ``pyproject.toml``::

    [project.entry-points."calflow.families"]
    mystage = "mylab_calflow.family:FAMILY"

Everything heavy is named as ``"module:attribute"`` and imported only when a command
needs it, so ``calflow --help`` loads no numerical library. The core asks the registry
for everything that differs between robots — the joints a run records, the named sets of
published values a campaign may declare, the report's labels, the index row, which result file feeds
which summary section, and the family's own Snakemake rules — so no core module and no
core rule names a robot (docs/families.md).
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
    * ``acquire_arguments``, ``identify_arguments``: options the family's plans read from
      ``calflow acquire``, and its identification from ``calflow identify``.
    * ``commands``: the family's own subcommands.
    * ``sensors``: short names of sensor factories for the ``gcs`` rig.
    * ``emulator``: ``"module:function"``, ``function(argv, prog=...) -> int`` serving a
      campaign's stages as a GCS controller (``calflow emulate gcs --campaign FILE``).
    * ``joints``: per robot, the joint (axis) names of its runs, in order: a run of that
      robot has ``cmd_<joint>`` and ``meas_<joint>`` (validation, import and replay read it).
    * ``axes``: axis name → ``(units, long_name)`` for joints the core does not define
      (the core knows ``x``, ``y``, ``z`` in µm and ``theta`` in degree).
    * ``reference``: the named reference sets the family provides, name → ``"module:attribute"``
      of the published values (a dict with a ``source``); a campaign that reproduces one
      declares it (``reference: <name>``) and its summary puts them beside calflow's
      (``summary["reference"]``, :mod:`calflow.reference`).
    * ``headline``: ``"module:function"``, ``function(summary) -> {"label", "key", "unit"}``
      or None: the one figure the cross-campaign index lists for a campaign (``key``
      dotted into the summary).
    * ``modes``: report label of each name of a test mode or model (``adaptive_kmz`` →
      "adaptive model (KMZ)"), the report's ``mode`` filter.
    * ``index_row``: template in ``templates/`` drawing a campaign's headline rows in the
      cross-campaign index (it receives ``s``, the summary, and ``ref``, its reference).
    * ``summary_sections``: ``"kind"`` or ``"kind:plan"`` → section name: which summary
      section each result file feeds (:func:`calflow.summary_routing.route`).
    * ``rules``: ``("package", "file.smk", ...)``: the family's Snakemake rules files inside
      ``package``, included by the Snakefile for every installed family.
    * ``workflow``: ``"module:attribute"``, a :class:`calflow.family_workflow.FamilyWorkflow`
      answering what the core rules ask about a campaign (its result files, models,
      identification inputs, the runs its ``acquire`` rule serves).
    * ``studies``: ``"module:function"``, ``function(path, campaign_dir) -> dict`` loading a
      study file over a base campaign of the family (``config/studies``).
    * ``schemas``: the package whose ``schemas/`` folder holds ``campaign-<robot>.schema.yaml``
      (``None``: the core's ``workflow/schemas``); the common keys are merged in.
    * ``options``: the option check of each rig and sensor factory the family provides,
      factory ``"module:callable"`` → ``"module:function"``: ``function(**options)`` checks the
      options without building anything and raises :class:`~calflow.errors.OptionError`
      naming the option; the config check runs it when a campaign is loaded
      (:func:`calflow.rigs.plugin.check_rig`, and for a ``gcs`` rig's sensor
      :func:`calflow.gcs.rig_options.check_options`).
    * ``history_entry``: ``"module:function"``, ``function(summary) -> {model: {parameters:
      {p: {value, std}}, correlation, accuracy_um}}``: what one campaign brings to its stage's
      history (:mod:`calflow.lifecycle.history`); None: the family's campaigns cannot name a stage.
    * ``uncertainty``: ``"module:function"``, ``function(campaign, files) ->
      list[calflow.certificate.Measurement]``: where its headline figures are in its summary,
      the data they come from and its sensor's declared uncertainty terms; the core computes
      U and the decisions (:mod:`calflow.certificate`). None: no figure has a U.
    * ``certified``: per robot, figure key → whether calflow gives its U (``accuracy_um``:
      True): the figures a stage's ``specification`` may name.
    """

    name: str
    robots: tuple[str, ...]
    rigs: Mapping[str, Mapping[str, str]]
    plans: Mapping[str, Mapping[str, str]]
    rig_options: str
    steps: Mapping[str, str]
    templates: str
    acquire_arguments: Callable[[argparse.ArgumentParser], None] | None = None
    identify_arguments: Callable[[argparse.ArgumentParser], None] | None = None
    commands: tuple[Command, ...] = ()
    sensors: Mapping[str, str] = field(default_factory=dict)
    emulator: str | None = None
    joints: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    axes: Mapping[str, tuple[str, str]] = field(default_factory=dict)
    reference: Mapping[str, str] = field(default_factory=dict)
    modes: Mapping[str, str] = field(default_factory=dict)
    index_row: str | None = None
    summary_sections: Mapping[str, str] = field(default_factory=dict)
    rules: tuple[str, ...] = ()
    workflow: str | None = None
    studies: str | None = None
    schemas: str | None = None
    history_entry: str | None = None
    headline: str | None = None
    options: Mapping[str, str] = field(default_factory=dict)
    uncertainty: str | None = None
    certified: Mapping[str, Mapping[str, bool]] = field(default_factory=dict)

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

    def joints_of(self, robot: str) -> tuple[str, ...]:
        """The joints of ``robot``'s runs, in order (empty when the family does not say)."""
        return tuple(self.joints.get(robot, ()))

    def hooks(self) -> Any:
        """The family's :class:`calflow.family_workflow.FamilyWorkflow` (the core's defaults when none)."""
        return resolve(self.workflow or "calflow.family_workflow:DEFAULT")

    def rules_files(self) -> list[str]:
        """Absolute paths of the family's Snakemake rules files (``rules``)."""
        if not self.rules:
            return []
        from importlib.resources import files

        package, *names = self.rules
        return [str(files(package).joinpath(name)) for name in names]


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


def family_of(robot: str, distribution: str | None = None) -> Family:
    """The family that serves campaigns with ``robot``.

    ``distribution``: the package the campaign says provides the family (campaign key
    ``distribution``), named in the error when no installed family serves ``robot``.
    """
    for fam in families():
        if robot in fam.robots:
            return fam
    raise CalflowError(missing_family(robot, distribution))


def missing_family(robot: str, distribution: str | None = None) -> str:
    """The one-line reason no installed family serves ``robot``."""
    known = sorted(r for fam in families() for r in fam.robots)
    if distribution:
        return (
            f"robot {robot!r}: its family's distribution {distribution!r} is not installed "
            f"(pip install {distribution}); installed robots: {known}"
        )
    return f"robot {robot!r}: no installed calflow family serves it; expected one of {known}"


def option_check(factory: str) -> Callable[..., Any] | None:
    """The option check a family declares for rig or sensor ``factory`` (``"module:callable"``,
    :attr:`Family.options`), or None."""
    for fam in families():
        if factory in fam.options:
            return resolve(fam.options[factory])
    return None


def robots() -> tuple[str, ...]:
    return tuple(r for fam in families() for r in fam.robots)


def joints(robot: str) -> tuple[str, ...]:
    """The joints of a robot's runs from its family; ``()`` for a robot no family serves."""
    for fam in families():
        if robot in fam.robots:
            return fam.joints_of(robot)
    return ()


def axes() -> dict[str, tuple[str, str]]:
    """Axis name → (units, long_name) of every installed family's own joints."""
    return {name: tuple(spec) for fam in families() for name, spec in fam.axes.items()}


def modes() -> dict[str, str]:
    """Report labels of test modes and models, from every installed family."""
    return {name: label for fam in families() for name, label in fam.modes.items()}


def all_rules_files() -> list[str]:
    """The Snakemake rules files of every installed family, in entry-point name order."""
    return [path for fam in families() for path in fam.rules_files()]
