"""Digests of calflow's own code, so the workflow reruns what a code change affects.

Snakemake does not track code inside an installed package; each rule carries in its
``params`` the digest of the code its ``calflow`` command runs. That code is derived, never
listed: the command's entry point (what :func:`calflow.cli.entry_point` says the
subcommand calls) and every calflow or family module it reaches through imports —
module-level imports and imports inside functions, relative imports, ``from x import y``
with ``y`` a submodule, ``importlib.import_module("...")`` and ``"module:attribute"``
strings (the core's own look-ups, such as its built-in rigs). Where the core looks a hook
up in the campaign's family (``family.step("identify")``, the family's plans, rigs,
reference sets...), :data:`FAMILY_HOOKS` names the hook, and the modules the family
declares for it join the closure. Third-party libraries are not followed (their version
is the environment's, ``workflow/envs``).

Each module is read statically (:mod:`ast`; nothing is imported but the families'
declarations) and counted by its normalised source: the syntax tree without docstrings
and comments, so a comment or a docstring changes no digest and reruns nothing, while any
change to the code does. A package brings its data files (templates, stylesheets,
schemas) too. Everything is cached per process: the workflow asks for many digests when
it reads the Snakefile.
"""

from __future__ import annotations

import ast
import hashlib
import importlib.util
from collections.abc import Iterable
from dataclasses import dataclass
from functools import cache
from pathlib import Path

from calflow import __version__

#: Where the core resolves a hook of a family at run time (an import no ``import`` statement
#: shows): core module, or ``module:function`` of an entry point → the ``Family`` fields it
#: resolves; ``"steps:NAME"`` is one step. The campaign's own family's hooks (the core looks
#: them up with ``family_of(robot)``); ``"*FIELD"``: every family's (the report's template
#: folders are searched together).
FAMILY_HOOKS: dict[str, tuple[str, ...]] = {
    "calflow.config": ("schemas", "steps:check"),
    "calflow.reference": ("reference",),
    "calflow.rigs.plugin": ("rigs",),
    "calflow.commands.common": ("rig_options",),
    "calflow.commands.acquire": ("plans",),
    "calflow.gcs.sensors": ("sensors",),
    "calflow.gcs.campaign_server": ("emulator",),
    "calflow.family_workflow": ("workflow", "studies"),
    "calflow.report.render": ("*templates", "steps:figures"),
    "calflow.report.catalogue": ("headline",),
    "calflow.lifecycle.history": ("history_entry",),
    "calflow.cli:cmd_identify": ("steps:identify",),
    "calflow.cli:cmd_metrics": ("steps:metrics",),
    "calflow.cli:cmd_summarise": ("steps:summarise",),
}

#: Files of a package that are data its code reads (templates, styles, schemas).
DATA_SUFFIXES = (".j2", ".css", ".yaml", ".yml", ".json")


@dataclass(frozen=True)
class Source:
    """One module's normalised source digest and the modules it may import."""

    path: Path
    package: bool
    digest: str
    imports: frozenset[str]
    functions: dict  # top-level function or class name → (imports, names it refers to)


# ---------------------------------------------------------------------------- packages


@cache
def family_packages() -> tuple[str, ...]:
    """The top-level packages whose modules count: calflow and every installed family's."""
    from importlib.metadata import entry_points

    from calflow.family import GROUP

    found = ["calflow"]
    for ep in entry_points(group=GROUP):
        top = ep.value.partition(":")[0].split(".")[0]
        if top not in found:
            found.append(top)
    return tuple(found)


@cache
def registrations() -> tuple[str, ...]:
    """The modules the families' entry points name: every command loads them all."""
    from importlib.metadata import entry_points

    from calflow.family import GROUP

    return tuple(sorted({ep.value.partition(":")[0] for ep in entry_points(group=GROUP)}))


@cache
def _root(top: str) -> Path | None:
    spec = importlib.util.find_spec(top)  # a top-level package: found, not imported
    if spec is None or not spec.submodule_search_locations:
        return None
    return Path(list(spec.submodule_search_locations)[0]).resolve()


@cache
def find(module: str) -> tuple[Path, bool] | None:
    """``(file, is_package)`` of a calflow or family module, or None (not one, or absent)."""
    parts = module.split(".")
    if parts[0] not in family_packages():
        return None
    root = _root(parts[0])
    if root is None:
        return None
    base = root.joinpath(*parts[1:])
    if (base / "__init__.py").is_file():
        return base / "__init__.py", True
    if len(parts) > 1 and base.with_suffix(".py").is_file():
        return base.with_suffix(".py"), False
    return None


# ---------------------------------------------------------------------------- one module


def _is_doc(stmt: ast.stmt) -> bool:
    return (
        isinstance(stmt, ast.Expr)
        and isinstance(stmt.value, ast.Constant)
        and isinstance(stmt.value.value, str)
    )


def _module_name(node: ast.ImportFrom, here: str) -> str:
    if not node.level:
        return node.module or ""
    parts = here.split(".")
    return ".".join(parts[: len(parts) - node.level + 1] + ([node.module] if node.module else []))


def _scan(tree: ast.Module, module: str, package: bool, strings: bool) -> dict[str, tuple[list, list]]:
    """One pass over ``tree``: per top-level function or class (``""``: the rest of the
    module), the candidate modules it may import and the names it refers to; the
    docstrings (string statements) are removed on the way, since they document and do
    not run."""
    here = module if package else module.rpartition(".")[0]
    scanned: dict[str, tuple[list, list]] = {}
    tree.body = [s for s in tree.body if not _is_doc(s)] or [ast.Pass()]
    for stmt in tree.body:
        named = isinstance(stmt, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef))
        imports, names = scanned.setdefault(stmt.name if named else "", ([], []))
        stack = [stmt]
        while stack:
            node = stack.pop()
            kind = type(node)
            if kind in _BODIES:  # before its statements are read: a docstring names no import
                node.body = [s for s in node.body if not _is_doc(s)] or [ast.Pass()]
            stack.extend(ast.iter_child_nodes(node))
            if kind is ast.Name:
                if named:
                    names.append(node.id)
            elif kind is ast.Constant:
                value = node.value
                if strings and type(value) is str and ":" in value:
                    target, _, attr = value.partition(":")
                    if attr.isidentifier() and all(p.isidentifier() for p in target.split(".")):
                        imports.append(target)
            elif kind is ast.Import:
                imports.extend(alias.name for alias in node.names)
            elif kind is ast.ImportFrom:
                base = _module_name(node, here)
                imports.append(base)
                imports.extend(f"{base}.{alias.name}" for alias in node.names if alias.name != "*")
            elif kind is ast.Call:
                func, args = node.func, node.args
                if (
                    args
                    and getattr(func, "attr", getattr(func, "id", None)) == "import_module"
                    and isinstance(args[0], ast.Constant)
                    and isinstance(args[0].value, str)
                ):
                    imports.append(args[0].value)
    return scanned


_BODIES = (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)


def _cache_dir() -> Path | None:
    """Where normalised digests are kept between processes (content-addressed, so never
    stale): ``$CALFLOW_CACHE_DIR``, else ``$XDG_CACHE_HOME/calflow`` or ``~/.cache/calflow``;
    empty ``CALFLOW_CACHE_DIR``: none."""
    import os

    folder = os.environ.get("CALFLOW_CACHE_DIR")
    if folder is None:
        folder = os.path.join(os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "calflow")
    return Path(folder) / "provenance" if folder else None


def _normalised(module: str, path: Path, package: bool, strings: bool) -> dict:
    """``{"digest", "functions"}`` of a module's source: computed, or read from the cache
    by the hash of the source itself."""
    import json
    import os
    import sys

    raw = path.read_bytes()
    key = hashlib.sha256(
        f"v1 {sys.version_info[:2]} {module} {package} {strings}\n".encode() + raw
    ).hexdigest()
    folder = _cache_dir()
    cached = folder / f"{key}.json" if folder else None
    if cached is not None:
        try:
            return json.loads(cached.read_text())
        except (OSError, ValueError):
            pass
    tree = ast.parse(raw, str(path))
    scanned = _scan(tree, module, package, strings)
    found = {
        "digest": hashlib.sha256(ast.dump(tree).encode()).hexdigest(),
        "functions": {k: [sorted(set(i)), sorted(set(n))] for k, (i, n) in scanned.items()},
    }
    if cached is not None:
        try:
            folder.mkdir(parents=True, exist_ok=True)
            tmp = cached.with_suffix(f".{os.getpid()}.tmp")
            tmp.write_text(json.dumps(found))
            tmp.replace(cached)
        except OSError:  # a read-only home: computed again next time
            pass
    return found


@cache
def source(module: str) -> Source:
    """The normalised digest and imports of ``module`` (a calflow or family module)."""
    where = find(module)
    if where is None:
        raise ValueError(f"provenance: no calflow or family module {module!r}")
    path, package = where
    # The families' declarations name their hooks as strings; those are followed only
    # where the core resolves them (FAMILY_HOOKS), not as imports of the declaration.
    found = _normalised(module, path, package, strings=module not in registrations())
    functions = {k: (frozenset(i), frozenset(n)) for k, (i, n) in found["functions"].items()}
    functions.setdefault("", (frozenset(), frozenset()))
    imports = frozenset().union(*(i for i, _ in functions.values()))
    h = hashlib.sha256(found["digest"].encode())
    if package:  # the package's data: its folders that are no packages, recursively
        for data in _data_files(path.parent):
            h.update(data.relative_to(path.parent).as_posix().encode())
            h.update(data.read_bytes())
    return Source(path, package, h.hexdigest(), imports, functions)


def _data_files(folder: Path) -> list[Path]:
    found = []
    for p in sorted(folder.iterdir()):
        if p.is_file() and p.suffix in DATA_SUFFIXES:
            found.append(p)
        elif p.is_dir() and p.name != "__pycache__" and not (p / "__init__.py").exists():
            found.extend(_data_files(p))
    return found


# ---------------------------------------------------------------------------- closures


@cache
def _known(name: str) -> tuple[str, ...]:
    """``name`` and its parent packages (importing a module runs its packages'
    ``__init__``), if it is a calflow or family module; else nothing."""
    if find(name) is None:
        return ()
    parts = name.split(".")
    return tuple(m for m in (".".join(parts[:i]) for i in range(1, len(parts) + 1)) if find(m) is not None)


def _modules(names: Iterable[str]) -> set[str]:
    return {m for name in names for m in _known(name)}


@cache
def hook_targets(hooks: tuple[str, ...], robot: str | None) -> frozenset[str]:
    """The modules the families declare for ``hooks`` (:data:`FAMILY_HOOKS`), for
    ``robot``'s family (every family when ``robot`` is None)."""
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
            found.update(t.partition(":")[0] for t in ([value] if isinstance(value, str) else value or ()))
    return frozenset(_modules(found))


@cache
def _edges(module: str, robot: str | None) -> frozenset[str]:
    """The calflow or family modules ``module`` may import (all of its code), and those of
    the family hooks it resolves."""
    return frozenset(_modules(source(module).imports)) | hook_targets(FAMILY_HOOKS.get(module, ()), robot)


def _entry(target: str, robot: str | None) -> set[str]:
    """The modules an entry point ``module:function`` imports first: its module's top level
    and the functions of its module it calls (its own closure is walked from there); the
    command line that dispatches to it (``calflow.cli:main``, which builds the parser of
    every subcommand but runs only this one); every family's declaration (each command
    loads them all)."""
    from calflow.cli import entry_points

    module, _, function = target.partition(":")
    found = {module, *registrations()}
    if not function:
        return _modules(found) | _edges(module, robot)
    found |= _functions(
        "calflow.cli",
        "main",
        robot,
        exclude={t.partition(":")[2] for t in entry_points().values() if t.startswith("calflow.cli:")},
    )
    return _modules(found | _functions(module, function, robot))


def _functions(
    module: str, function: str, robot: str | None, exclude: frozenset | set = frozenset()
) -> set[str]:
    """What ``function`` of ``module`` and the functions of that module it names import
    (the module's top level too), and the family hooks they resolve."""
    found: set[str] = set()
    functions = source(module).functions
    todo, seen = [function, ""], set(exclude)
    while todo:
        name = todo.pop()
        if name in seen or name not in functions:
            continue
        seen.add(name)
        imports, names = functions[name]
        found |= imports
        todo.extend(names)
        found |= hook_targets(FAMILY_HOOKS.get(f"{module}:{name}", ()), robot)
    return _modules(found)


@cache
def closure(target: str, robot: str | None = None) -> tuple[str, ...]:
    """Every calflow or family module entry point ``target`` (``"module:function"``, or a
    module) reaches through imports, for campaigns of ``robot``, sorted. The entry point's
    module is included whole; of it, only the functions the entry point calls bring their
    imports."""
    module = target.partition(":")[0]
    # The entry point's module, and the command line, are followed from the functions that
    # run (the command line's ``main`` builds every subcommand's parser, runs only one).
    seen = {module, "calflow.cli"}
    todo = list(_entry(target, robot) - seen)
    while todo:
        name = todo.pop()
        if name not in seen:
            seen.add(name)
            todo.extend(_edges(name, robot) - seen)
    return tuple(sorted(seen))


@cache
def code_digest(command: str, robot: str | None = None) -> str:
    """SHA-256 over calflow's version and the normalised source of every module ``calflow
    <command>`` reaches for campaigns of ``robot`` (:func:`closure` of the command's entry
    point, :func:`calflow.cli.entry_point`). ``robot`` None: a command over every family's
    campaigns (``calflow index``)."""
    from calflow.cli import entry_point

    return module_digest(*closure(entry_point(command), robot))


@cache
def module_digest(*modules: str) -> str:
    """SHA-256 over calflow's version and the normalised source of ``modules`` (each once,
    with its package's data files), in the order given."""
    h = hashlib.sha256(__version__.encode())
    for module in modules:
        h.update(module.encode())
        h.update(source(module).digest.encode())
    return h.hexdigest()
