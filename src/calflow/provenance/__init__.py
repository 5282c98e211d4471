"""Digests of calflow's own code, so the workflow reruns what a code change affects.

Snakemake does not track code inside an installed package; each rule carries in its
``params`` the digest of the code its ``calflow`` command runs. That code is derived, never
listed: the command's entry point (the function its step declares,
:func:`calflow.steps.entry_point`) and every calflow or family module it reaches through imports —
module-level imports and imports inside functions, relative imports, ``from x import y``
with ``y`` a submodule, ``importlib.import_module("...")`` and ``"module:attribute"``
strings (the core's own look-ups, such as its built-in rigs). Where the core looks a hook
up in the campaign's family (``family.step("identify")``, the family's plans, rigs,
reference sets...), :data:`FAMILY_HOOKS` names the hook, and the modules the family
declares for it join the closure. Imports are followed from the functions that run
(:func:`closure`). Third-party libraries are not followed (their version is the
environment's, ``workflow/envs``).

Each module is read statically (:mod:`calflow.provenance.modules`; nothing is imported but
the families' declarations) and counted by its normalised source: the syntax tree without
docstrings and comments, so a comment or a docstring changes no digest and reruns nothing,
while any change to the code does. A package brings its data files (templates,
stylesheets, schemas) too. Everything is cached per process (the workflow asks for many
digests when it reads the Snakefile), normalised sources also between processes.
"""

from __future__ import annotations

import hashlib
from functools import cache

from calflow import __version__
from calflow.cache import cached_json
from calflow.provenance.modules import find, registrations, source, tree_fingerprint, under

#: Where the core resolves a hook of a family at run time (an import no ``import`` statement
#: shows): core module, or ``module:function`` of an entry point → the ``Family`` fields it
#: resolves; ``"steps:NAME"`` is one step. The campaign's own family's hooks (the core looks
#: them up with ``family_of(robot)``); ``"*FIELD"``: every family's (the report's template
#: folders are searched together).
FAMILY_HOOKS: dict[str, tuple[str, ...]] = {
    "calflow.configuration.config": ("schemas",),
    "calflow.configuration.campaign": ("steps:check",),
    "calflow.configuration.reference": ("reference",),
    "calflow.configuration.rig_factory": ("rigs",),
    "calflow.rigs.campaign_rig": ("rig_options",),
    "calflow.commands.acquire": ("plans",),
    "calflow.gcs.sensors": ("sensors",),
    "calflow.gcs.camera": ("sensors",),  # a family's registered camera (frame source)
    "calflow.gcs.emulation.campaign_server": ("emulator",),
    "calflow.family_workflow": ("workflow", "studies"),
    "calflow.report.render": ("*templates", "steps:figures"),
    "calflow.report.catalogue": ("headline",),
    "calflow.lifecycle.history": ("history_entry",),
    "calflow.family:option_check": ("*options",),
    "calflow.certificate.annotate": ("uncertainty",),
    "calflow.commands.campaign:identify": ("steps:identify",),
    "calflow.commands.campaign:metrics": ("steps:metrics",),
    "calflow.commands.campaign:summarise": ("steps:summarise",),
}

#: The modules that dispatch to a step's function rather than run it: the command line, and
#: the declarations that name each step's function (:mod:`calflow.steps`).
DISPATCH = frozenset({"calflow.cli", "calflow.steps", "calflow.steps.campaign", "calflow.steps.tools"})

# ---------------------------------------------------------------------------- closures


@cache
def _parents(name: str) -> tuple[str, ...]:
    """The packages above module ``name`` that are calflow or family packages (importing
    a module runs their ``__init__``)."""
    parts = name.split(".")
    return tuple(m for m in (".".join(parts[:i]) for i in range(1, len(parts))) if find(m) is not None)


def _target(module: str, name: str | None) -> tuple[str, str]:
    """What ``from module import name`` (``name`` None: ``import module``) enters:
    ``(module, function or class)``, ``(module, "")`` for another name (only the
    module's import-time code) or ``(submodule, "*")`` for all of a submodule."""
    if name is None:
        return module, "*"
    if find(f"{module}.{name}") is not None:
        return f"{module}.{name}", "*"
    return module, name


@cache
def hook_targets(hooks: tuple[str, ...], robot: str | None) -> tuple[tuple[str, str], ...]:
    """``(module, attribute)`` of what the families declare for ``hooks``
    (:data:`FAMILY_HOOKS`), for ``robot``'s family (every family when ``robot`` is None);
    a package (templates, schemas) with attribute ``""``."""
    from calflow.family import families, family_of

    found: set[str] = set()
    for hook in hooks:
        field, _, step = hook.lstrip("*").partition(":")
        for fam in families() if robot is None or hook.startswith("*") else (family_of(robot),):
            value = getattr(fam, field)
            if field == "steps":
                value = value.get(step)
            elif field in ("rigs", "plans"):
                value = [t for r, named in value.items() if robot in (None, r) for t in named.values()]
            elif isinstance(value, dict):
                value = list(value.values())
            found.update([value] if isinstance(value, str) else value or ())
    pairs = {tuple(t.partition(":")[::2]) for t in found}
    return tuple(sorted(p for p in pairs if find(p[0]) is not None))


@cache
def closure(target: str, robot: str | None = None) -> tuple[str, ...]:
    """Every calflow or family module that entry point ``target`` (``"module:function"``)
    reaches through imports, for campaigns of ``robot``, sorted.

    Followed from the functions that run: a module's import-time code always, and of its
    functions and classes those imported (``from m import f``), looked up
    (``"m:f"``, a family hook) or named by code already reached; a whole module where it
    is imported as one (``import m``, ``from package import module``). The command line's
    ``main`` builds every subcommand's parser and runs only the one of ``target``; every
    family's declaration is loaded by each command. A module reached at all counts whole
    in the digest."""
    pair = tuple(target.partition(":")[::2])
    if find(pair[0]) is None:
        raise ValueError(f"provenance: entry point {target!r} is not in a calflow or family module")
    seen, entered = _base(robot)
    seen, entered = set(seen), set(entered)
    _walk([pair], robot, _targets() - {pair}, seen, entered)
    return tuple(sorted(entered))


@cache
def _targets() -> frozenset[tuple[str, str]]:
    """``(module, function)`` of every subcommand's entry point."""
    from calflow.steps import entry_points

    return frozenset(tuple(t.partition(":")[::2]) for t in entry_points().values())


@cache
def _base(robot: str | None) -> tuple[frozenset, frozenset]:
    """What every command reaches (seen ``(module, key)``, modules): the command line's
    ``main`` and every family's declaration, no subcommand's own function."""
    start = [("calflow.cli", "main")] + [(m, "") for m in registrations()]
    seen: set[tuple[str, str]] = set()
    entered: set[str] = set()
    _walk(start, robot, _targets(), seen, entered)
    return frozenset(seen), frozenset(entered)


def _walk(todo: list, robot: str | None, others: frozenset, seen: set, entered: set) -> None:
    """Enter everything reachable from ``todo`` (``(module, key)``), adding to ``seen``
    and ``entered``; the command line does not dispatch to ``others``."""
    while todo:
        item = todo.pop()
        if item in seen:
            continue
        seen.add(item)
        module, key = item
        nxt = list(_next(module, key))
        if module not in entered:
            entered.add(module)
            nxt += hook_targets(FAMILY_HOOKS.get(module, ()), robot)
        nxt += hook_targets(FAMILY_HOOKS.get(f"{module}:{key}", ()), robot)
        if module in DISPATCH:  # the other subcommands: dispatched to, not run
            nxt = [i for i in nxt if i not in others]
        todo += [i for i in nxt if i not in seen]


@cache
def _next(module: str, key: str) -> tuple[tuple[str, str], ...]:
    """What entering ``key`` of ``module`` enters next (family hooks aside): the module's
    import-time code and its packages', and what ``key`` imports or names."""
    functions = source(module).functions
    found = [(p, "") for p in _parents(module)] + [(module, "")]
    if key == "*":
        found += [(module, k) for k in functions]
    elif key in functions:  # else a name bound on import (a constant, a re-export)
        imports, names = functions[key]
        found += [_target(m, n) for m, n in imports]
        found += [(module, n) for n in names if n in functions]
    return tuple(i for i in found if find(i[0]) is not None)


@cache
def code_digest(command: str, robot: str | None = None) -> str:
    """SHA-256 over calflow's version and the normalised source of every module ``calflow
    <command>`` reaches for campaigns of ``robot`` (:func:`closure` of the command's entry
    point, :func:`calflow.steps.entry_point`). ``robot`` None: a command over every family's
    campaigns (``calflow index``)."""

    def compute() -> dict:
        from calflow.steps import entry_point

        return {"digest": module_digest(*closure(entry_point(command), robot))}

    # kept between processes under the fingerprint of the whole tree (a no-op rerun of the
    # workflow asks for every step's digest; walking the closures again costs ~0.3 s)
    key = hashlib.sha256(f"code digest v1 {__version__} {command!r} {robot!r} {tree_fingerprint()}".encode())
    return cached_json("digests", key.hexdigest(), compute)["digest"]


@cache
def module_digest(*modules: str) -> str:
    """SHA-256 over calflow's version and the normalised source of ``modules`` (each once,
    with its package's data files), in the order given."""
    h = hashlib.sha256(__version__.encode())
    for module in modules:
        h.update(module.encode())
        h.update(source(module).digest.encode())
    return h.hexdigest()


def package_digest(*packages: str) -> str:
    """:func:`module_digest` of every module of ``packages`` and their subpackages (an
    instrument's whole code, recorded beside what it measured)."""
    return module_digest(*(m for p in packages for m in under(p)))
