"""The family contract: every hook a robot family gives the core, declared once.

A family (:class:`calflow.family.Family`) brings *contributions* of a few kinds — its rig, its
plans, its steps, its report, its certificate, its place in a stage's history, its workflow, its
subcommands — and each contribution names its hooks as ``"module:attribute"`` strings, imported
only when a command needs them. :data:`HOOKS` is the one table of those hooks: the field of
``Family`` that holds each, its kind, the parameters the core calls it with and what it returns.
:func:`check_family` checks a family against it when the registry loads it
(:func:`calflow.family.families`): a required hook missing, a ``"module:attribute"`` that names
no module or no attribute, a value where a function is expected, or a function whose
parameters are not the declared ones, is refused with one line naming the family, the hook and
what was expected. The check reads the hooks' source (:mod:`ast`), so registering a family
imports none of its numerical modules (``calflow --help`` and the Snakefile read the registry).

Every step hook has one calling convention, ``hook(c, args)``: ``c`` the loaded campaign (a
read-only mapping of its sections and its ``name``), ``args`` a :class:`calflow.step.Job`: the step's
inputs by name, read-only (:data:`STEP_ARGS`). The rest of the contract that is not a hook is here too:
the names a family's Snakemake rules may use (:data:`RULE_GLOBALS`), its template and schema
file names (:data:`TEMPLATE`, :data:`SCHEMA`), and the public core a family outside calflow
imports (:data:`PUBLIC_CORE`). docs/families.md describes all of it; a test checks the two agree.
"""

from __future__ import annotations

import importlib
import inspect
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from calflow.errors import CalflowError
from calflow.hook_source import Params, binding, from_signature, package_dir


class FamilyError(CalflowError):
    """A family that does not keep the contract, refused at registration (one line)."""


@dataclass(frozen=True)
class Hook:
    """One hook of the contract.

    ``name``: the hook (``steps.identify``, ``rig_options`` …); ``field``: the ``Family`` field
    that holds it; ``kind``: its contribution; ``params``: the positional parameters the core
    passes, by name (``None``: not a function — a value such as a dict or an object);
    ``keywords``: keyword arguments the core passes besides; ``options``: also takes the
    options of a campaign as keyword arguments (``factory(**options)``); ``shape``: ``one``
    (a ``"module:attr"``), ``by_name`` (name → ``"module:attr"``), ``by_robot`` (robot → name
    → ``"module:attr"``);
    ``label``: what the docs call it (``factory``, ``builder``); ``returns``: what the core
    expects back, in words.
    """

    name: str
    field: str
    kind: str
    params: tuple[str, ...] | None
    returns: str
    required: bool = False
    shape: str = "one"
    label: str = ""
    keywords: tuple[str, ...] = ()
    options: bool = False

    @property
    def call(self) -> str:
        """The hook's call as docs/families.md shows it: ``identify(c, args)``, ``factory(**options)``."""
        return self.expected(self.label or self.name.rpartition(".")[2])

    def expected(self, attr: str) -> str:
        """The hook's call as the core makes it, e.g. ``identify(c, args)``."""
        if self.params is None:
            return f"{attr} = <{self.returns}>"
        args = [*self.params, *(f"{k}=…" for k in self.keywords)] + (["**options"] if self.options else [])
        return f"{attr}({', '.join(args)})"


#: The contribution kinds, in the order docs/families.md describes them.
KINDS = ("rig", "plans", "steps", "report", "certificate", "lifecycle", "workflow", "commands")

#: Every hook, declared once: name, Family field, kind, parameters (None: a value), what it
#: returns, required, shape, the name the docs call it by, keywords, takes **options.
# fmt: off
HOOKS: tuple[Hook, ...] = (
    # rig: what the family's robots are driven and measured with
    Hook("rigs", "rigs", "rig", (), "a Rig (calflow.rigs.protocol)", True, "by_robot", "factory", options=True),
    Hook("rig_options", "rig_options", "rig", ("c", "factory", "run_id", "options", "start_s"), "the run's options", True),
    Hook("options", "options", "rig", (), "the checked options; OptionError naming one", False, "by_name", "check", options=True),
    Hook("sensors", "sensors", "rig", (), "a sensor of the gcs rig", False, "by_name", "factory", options=True),
    Hook("emulator", "emulator", "rig", None, "a calflow.gcs.emulation.campaign_emulator.Emulator"),
    # plans: what a run commands
    Hook("plans", "plans", "plans", ("c", "args"), "a calflow.plan.Acquisition", True, "by_robot", "builder"),
    # steps: one calling convention, hook(c, args)
    Hook("steps.check", "steps", "steps", ("c", "args"), "a calflow.configuration.campaign.Resolution or None; ConfigError naming file and key"),
    Hook("steps.identify", "steps", "steps", ("c", "args"), "None; writes args.out", True),
    Hook("steps.metrics", "steps", "steps", ("c", "args"), "None; writes args.out", True),
    Hook("steps.summarise", "steps", "steps", ("c", "args"), "the summary, a JSON-able dict", True),
    Hook("steps.figures", "steps", "steps", ("c", "args"), "(figures, notes)", True),
    # report
    Hook("headline", "headline", "report", ("summary",), "{label, key, unit} or None"),
    Hook("reference", "reference", "report", None, "a dict of published values with a source", False, "by_name"),
    # certificate
    Hook("uncertainty", "uncertainty", "certificate", ("campaign", "files"), "list[calflow.certificate.Measurement]"),
    # lifecycle
    Hook("history_entry", "history_entry", "lifecycle", ("summary",), "{model: {parameters, correlation, accuracy_um}}"),
    # workflow
    Hook("workflow", "workflow", "workflow", None, "a calflow.family_workflow.FamilyWorkflow"),
    Hook("studies", "studies", "workflow", ("path", "campaign_dir"), "the study, a dict"),
    # commands: calflow <name>
    Hook("commands.run", "commands", "commands", ("args",), "exit status or None"),
)
# fmt: on

#: The inputs each step hook finds on ``args`` (besides the subcommand's own options).
STEP_ARGS: Mapping[str, tuple[str, ...]] = {
    "check": ("campaign",),  # the campaign file (a Path), for the error's file name
    "identify": ("campaign", "model_name", "run", "out"),  # + the family's step_options["identify"]
    "metrics": ("campaign", "run", "out"),
    "summarise": ("campaign", "files", "truth"),  # truth: the rig's truth and error budget, or None
    "figures": ("summary", "inputs"),  # inputs: calflow.report.figures.Inputs of the result files
}

#: The report template of a robot in its family's ``templates`` package (``templates/`` folder).
TEMPLATE = "{robot}.html.j2"
#: The campaign schema of a robot in its family's ``schemas`` package (``schemas/`` folder).
SCHEMA = "campaign-{robot}.schema.yaml"

#: What a family's rules files may use of the core rules (``workflow/rules/common.smk``, read
#: before them); a test checks they use nothing else of the core's.
RULE_GLOBALS = (
    "CAMPAIGN",  # campaign name -> the loaded campaign, of the run's campaigns
    "CAMPAIGN_DIR",  # the folder of the campaign files
    "STUDY",  # study name -> the loaded study, of the run's studies
    "CONDA_ENV",  # the environment file, an absolute path
    "REPORT_DIR",  # the captions of report() outputs
    "campaign_file",  # wildcards -> the campaign's file
    "reads",  # **reads(step, *sections): the sections a job is handed (its step's, then these), and its rerun digest
    "rig_slots",  # wildcards -> the rig's resource slots (one run at a time per real rig)
    "models_of",  # models_of(campaign): the models it identifies
    "code_digest",  # code_digest(command, robot): the digest of a subcommand's code
    "digest",  # digest(obj): SHA-256 of its canonical JSON
    "layout",  # calflow.configuration.layout: every path under results/ and reports/
)

#: What a family outside calflow imports from the core: module → the public names it may import
#: (``"*"``: every public name of the module). docs/families.md, "The public core", lists them;
#: a test walks the hexapod plug-in's imports against it. Everything else is calflow's own.
PUBLIC_CORE: Mapping[str, tuple[str, ...]] = {
    "calflow": ("__version__",),
    "calflow.configuration": ("layout",),
    "calflow.family": ("Family",),
    "calflow.step": ("Option", "Step", "CAMPAIGN", "OUT"),
    "calflow.family_contract": ("*",),
    "calflow.family_workflow": ("FamilyWorkflow",),
    "calflow.configuration.layout": ("*",),
    "calflow.errors": ("*",),
    "calflow.plan": ("Plan", "Acquisition"),
    "calflow.commands.common": ("campaign", "campaign_of", "meta"),
    "calflow.data.io": (
        "open_dataset",
        "write_dataset",
        "write_json",
        "write_text",
        "output_folder",
        "jsonable",
        "sha256_file",
    ),
    "calflow.data.runs": ("RunMetadata",),
    "calflow.summary_routing": ("route", "summary_head"),
    "calflow.configuration.reference": ("declared",),
    "calflow.certificate": ("Measurement",),
    "calflow.metrics.uncertainty": ("Term",),
    "calflow.metrics.iso9283": ("iso9283",),
    "calflow.metrics.iso9283_orientation": ("iso9283_orientation",),
    "calflow.identification": ("design", "gauss_newton"),
    "calflow.identification.design": ("*",),
    "calflow.identification.gauss_newton": ("*",),
    "calflow.identification.diagnostics": ("identifiability",),
    "calflow.identification.robust": ("Robust", "mad_sigma", "outliers"),
    "calflow.report.figures": ("new_figure", "finish", "guarded"),
    "calflow.rigs.thermal": ("LagBank", "room_profile"),
    "calflow.gcs.emulation.axis": ("AxisConfig", "SimAxis"),
    "calflow.gcs.emulation.controller": ("EmulatedController", "GCSCommandError"),
    "calflow.gcs.emulation.emulator": ("GCSEmulator", "Faults"),
    "calflow.gcs.emulation.campaign_server": (
        "load_campaign_arg",
        "link_options",
        "serve_campaign",
        "start_emulated",
    ),
    "calflow.rigs.simulated.effects": ("Effect", "Effects", "SwitchedTruth"),
    "calflow.rigs.simulated.checks": ("Bounds", "check_physics"),
    "calflow.rigs.simulated.campaign": ("simulated_options",),
    "calflow.rigs.simulated.commands": ("joint_commands",),
    "calflow.rigs.simulated.budget": (
        "Replays",
        "budget_command",
        "decompose",
        "effects_of",
        "require_simulated",
    ),
    "calflow.data.bundle": ("provenance", "read_bundle", "write_bundle", "Compensator"),
    "calflow.gcs.emulation.campaign_emulator": ("Emulator",),
}


def hook(name: str) -> Hook:
    """The declared hook ``name``."""
    return next(h for h in HOOKS if h.name == name)


def _targets(h: Hook, value: Any) -> list[tuple[str, Any]]:
    """``(where, target)`` of each hook a family field holds."""
    if h.field == "steps":
        step = h.name.split(".", 1)[1]
        return [(h.name, value[step])] if step in value else []
    if h.field == "commands":
        part = h.name.split(".", 1)[1]
        return [(f"commands.{c.name}.{part}", getattr(c, part)) for c in value]
    if h.shape == "by_robot":
        return [(f"{h.name}.{r}.{n}", t) for r, named in value.items() for n, t in named.items()]
    if h.shape == "by_name":
        return [(f"{h.name}.{n}", t) for n, t in value.items()]
    return [] if value is None else [(h.name, value)]


def check_family(fam: Any) -> None:
    """Refuse ``fam`` unless it keeps the contract; one line naming the family, hook and what
    was expected (:class:`FamilyError`)."""
    name = getattr(fam, "name", "?")

    def refuse(where: str, what: str) -> None:
        raise FamilyError(f"family {name!r}: hook {where}: {what}")

    _check_steps(fam, refuse)
    for h in HOOKS:
        value = getattr(fam, h.field)
        targets = _targets(h, value)
        if h.required and not targets:
            refuse(h.name, f"missing; expected {h.call} -> {h.returns}")
        for where, target in targets:
            _check_target(where, target, h, refuse)
    for robot in fam.robots:
        if robot not in fam.rigs or robot not in fam.plans:
            refuse("rigs/plans", f"expected a rig and plans for robot {robot!r}")
    for factory in (t for rigs in fam.rigs.values() for t in rigs.values()):
        if factory not in fam.options:
            refuse("options", f"expected the option check of rig factory {factory!r} (options[factory])")
    _check_files(fam, refuse)


def _check_steps(fam: Any, refuse) -> None:
    """The family's own steps are :class:`calflow.step.Step` s, and what it adds to the core's
    steps are :class:`calflow.step.Option` s of a core step."""
    from calflow.step import Option, Step

    for s in fam.commands:
        if not isinstance(s, Step):
            refuse("commands", f"expected a calflow.step.Step, got {s!r}")
    known = {"acquire", "identify"}
    for name, options in fam.step_options.items():
        if name not in known:
            refuse(f"step_options.{name}", f"expected options of one of {sorted(known)}")
        for o in options:
            if not isinstance(o, Option):
                refuse(f"step_options.{name}", f"expected calflow.step.Option s, got {o!r}")


def _check_target(where: str, target: Any, h: Hook, refuse) -> None:
    if not isinstance(target, str) or target.count(":") != 1 or not all(target.split(":")):
        refuse(where, f"expected a 'module:attribute' string, got {target!r}")
    module, attr = target.split(":")
    found = binding(module, attr)
    if isinstance(found, str):
        refuse(where, f"{target!r}: {found}")
    kind, params = found
    if h.params is None:
        if kind == "function":
            refuse(where, f"{target!r}: expected {h.returns}, got a function")
        if h.name in _BUILT:
            _check_built(where, target, _BUILT[h.name], refuse)
        return
    if kind == "value":
        refuse(where, f"{target!r}: expected a callable {h.call}, got a value that is not callable")
    if params is None:  # built at import (a call's result): the object itself tells
        obj = getattr(importlib.import_module(module), attr)
        if not callable(obj):
            refuse(where, f"{target!r}: expected a callable {h.call}, got {type(obj).__name__}")
        try:
            params = from_signature(inspect.signature(obj))
        except (TypeError, ValueError):
            return
    problem = _mismatch(params, h)
    if problem:
        refuse(where, f"{target!r}: expected {h.call}, got {problem}")


#: The hooks that name an object built in its module (a class's instance), and its class.
_BUILT = {
    "workflow": "calflow.family_workflow.FamilyWorkflow",
    "emulator": "calflow.gcs.emulation.campaign_emulator.Emulator",
}


def _check_built(where: str, target: str, cls: str, refuse) -> None:
    """The workflow and the emulator are objects built in their modules: read, not imported,
    here; their type is checked when they are first used (:func:`built_of`)."""
    module, attr = target.split(":")
    if binding(module, attr)[0] != "object":
        refuse(where, f"{target!r}: expected an instance of a {cls}")


def workflow_of(fam: Any) -> Any:
    """The family's :class:`~calflow.family_workflow.FamilyWorkflow`, its type checked."""
    return built_of(fam, "workflow", "calflow.family_workflow:DEFAULT")


def built_of(fam: Any, name: str, default: str | None = None) -> Any:
    """The object a family's hook ``name`` names (one of :data:`_BUILT`), imported and its type
    checked (by its classes' names: the class's module imports the registry, not the other way
    round); :class:`FamilyError` in one line for another type."""
    module, attr = (getattr(fam, name) or default).split(":")
    obj = getattr(importlib.import_module(module), attr)
    if _BUILT[name] not in {f"{k.__module__}.{k.__qualname__}" for k in type(obj).__mro__}:
        raise FamilyError(
            f"family {fam.name!r}: hook {name}: {getattr(fam, name)!r}: expected a "
            f"{_BUILT[name]}, got {type(obj).__name__}"
        )
    return obj


# A function's parameters: (positional names, how many are required, names of the keyword-only
def _mismatch(params: Params, h: Hook) -> str | None:
    """Why a function with ``params`` cannot be called as ``h`` declares; None when it can."""
    pos, required, kwonly, kw_required, varargs, varkw = params
    n = len(h.params)
    shown = f"({', '.join([*pos, *(['*args'] if varargs else []), *kwonly] + (['**kw'] if varkw else []))})"
    if required > n or (len(pos) < n and not varargs):
        return f"{shown}: takes {required if required > n else len(pos)} positional parameters, the core passes {n}"
    if tuple(pos[:n]) != h.params[: len(pos[:n])]:
        return f"{shown}: parameters named {list(pos[:n])}, expected {list(h.params)}"
    passed = set(h.keywords)
    missing = [k for k in h.keywords if k not in (*pos[n:], *kwonly) and not varkw]
    if missing:
        return f"{shown}: no parameter {missing[0]!r}"
    if any(k not in passed for k in kw_required):
        return f"{shown}: keyword-only parameters the core does not pass"
    if h.options and not (varkw or pos[n:] or kwonly):
        return f"{shown}: takes no options as keyword arguments"
    return None


def _check_files(fam: Any, refuse) -> None:
    """The files a family names: its robots' templates and schemas, its index row, its rules."""
    templates = package_dir(fam.templates)
    if templates is None:
        refuse("templates", f"expected a package with a templates/ folder, got {fam.templates!r}")
    for robot in fam.robots:
        if not (templates / "templates" / TEMPLATE.format(robot=robot)).is_file():
            refuse("templates", f"expected {fam.templates}/templates/{TEMPLATE.format(robot=robot)}")
    if fam.index_row and not (templates / "templates" / fam.index_row).is_file():
        refuse("index_row", f"expected {fam.templates}/templates/{fam.index_row}")
    if fam.schemas:
        schemas = package_dir(fam.schemas)
        for robot in fam.robots:
            if schemas is None or not (schemas / "schemas" / SCHEMA.format(robot=robot)).is_file():
                refuse("schemas", f"expected {fam.schemas}/schemas/{SCHEMA.format(robot=robot)}")
    if fam.rules:
        package, *names = fam.rules
        folder = package_dir(package)
        for rules in names:
            if folder is None or not (folder / rules).is_file():
                refuse("rules", f"expected the rules file {package}/{rules}")
