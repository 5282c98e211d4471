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

import importlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from functools import lru_cache
from importlib.metadata import entry_points
from typing import Any

from calflow.errors import CalflowError
from calflow.step import Option, Step

GROUP = "calflow.families"


@dataclass(frozen=True)
class Family:
    """One family of robots: what it contributes to each part of the workflow.

    Its fields fall into the contract's contribution kinds (:data:`calflow.family_contract.KINDS`);
    every hook — a ``"module:attribute"`` string — has its
    signature declared once in :data:`calflow.family_contract.HOOKS` and is checked when the
    family registers. docs/families.md describes each field and hook.

    * who: ``name``, ``robots`` (the campaign ``robot`` values it serves), ``joints`` (per robot,
      the joint names of its runs, in order), ``axes`` (units and long name of joints the core
      does not define), ``schemas`` (the package whose ``schemas/`` holds
      ``campaign-<robot>.schema.yaml``; ``None``: the core's).
    * rig: ``rigs`` (robot → short name → factory), ``rig_options`` (what a run adds to the rig
      options), ``options`` (factory → its option check; every rig factory has one), ``sensors``
      (of the ``gcs`` rig), ``emulator``.
    * plans: ``plans`` (robot → plan name → builder).
    * steps: ``steps`` (``check``, ``identify``, ``metrics``, ``summarise``, ``figures``, each
      ``hook(c, args)``), ``step_options`` (core step → the :class:`calflow.step.Option` s the
      family adds to it: ``calflow acquire --luts``).
    * report: ``templates`` (the package whose ``templates/`` holds ``<robot>.html.j2``),
      ``index_row``, ``headline``, ``modes``, ``reference``, ``summary_sections``.
    * certificate: ``uncertainty``, ``certified``. lifecycle: ``history_entry``.
    * workflow: ``workflow`` (a :class:`calflow.family_workflow.FamilyWorkflow`), ``rules``
      (``("package", "file.smk", ...)``), ``studies``. commands: ``commands`` (the family's own
      steps, each a :class:`calflow.step.Step`).
    """

    name: str
    robots: tuple[str, ...]
    rigs: Mapping[str, Mapping[str, str]]
    plans: Mapping[str, Mapping[str, str]]
    rig_options: str
    steps: Mapping[str, str]
    templates: str
    step_options: Mapping[str, tuple[Option, ...]] = field(default_factory=dict)
    commands: tuple[Step, ...] = ()
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
        from calflow.family_contract import workflow_of

        return workflow_of(self)

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
    """Every installed family, in entry-point name order, each checked against the contract
    when it registers (:func:`calflow.family_contract.check_family`): a family that does not
    keep it is refused with one line naming it, the hook and what was expected."""
    from calflow.family_contract import check_family

    found = []
    for ep in sorted(entry_points(group=GROUP), key=lambda e: e.name):
        fam = ep.load()
        if not isinstance(fam, Family):
            raise CalflowError(f"entry point {GROUP}:{ep.name}: {ep.value} is not a calflow.family.Family")
        check_family(fam)
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


#: names a family module could import before steps were declared by :class:`calflow.step.Step`
_REPLACED = {
    "Command": "a family's own steps are calflow.step.Step objects in Family.commands",
}


def __getattr__(name: str):
    """A removed name fails with what replaced it (docs/families.md, "Steps"), not a bare
    AttributeError: a family written for the argparse hooks learns what to change."""
    if name in _REPLACED:
        raise AttributeError(f"calflow.family.{name} was removed: {_REPLACED[name]} (docs/families.md)")
    raise AttributeError(f"module 'calflow.family' has no attribute {name!r}")
