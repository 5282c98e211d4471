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
import os
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
    """One module's normalised source digest, and per top-level function or class (``""``:
    what runs on import) what it may import and the names it refers to."""

    path: Path
    package: bool
    digest: str
    functions: dict[str, tuple[tuple[tuple[str, str | None], ...], frozenset[str]]]


# ---------------------------------------------------------------------------- packages


@cache
def registrations() -> tuple[str, ...]:
    """The modules the families' entry points name: every command loads them all."""
    from importlib.metadata import entry_points

    from calflow.family import GROUP

    return tuple(sorted({ep.value.partition(":")[0] for ep in entry_points(group=GROUP)}))


@cache
def family_packages() -> tuple[str, ...]:
    """The top-level packages whose modules count: calflow and every installed family's."""
    return tuple(dict.fromkeys(["calflow", *(m.split(".")[0] for m in registrations())]))


@cache
def _modules() -> dict[str, tuple[Path, bool]]:
    """Every module of :func:`family_packages` → ``(file, is_package)``, from one walk of
    each package's folders (packages: folders with an ``__init__.py``)."""
    found: dict[str, tuple[Path, bool]] = {}
    for top in family_packages():
        spec = importlib.util.find_spec(top)  # a top-level package: found, not imported
        if spec is None or not spec.submodule_search_locations:
            continue
        root = list(spec.submodule_search_locations)[0]
        for folder, subfolders, files in os.walk(root):
            if "__init__.py" not in files:
                subfolders[:] = []
                continue
            rel = os.path.relpath(folder, root)
            package = top if rel == "." else f"{top}.{rel.replace(os.sep, '.')}"
            found[package] = (Path(folder, "__init__.py"), True)
            for name in files:
                if name.endswith(".py") and name != "__init__.py":
                    found[f"{package}.{name[:-3]}"] = (Path(folder, name), False)
    return found


def find(module: str) -> tuple[Path, bool] | None:
    """``(file, is_package)`` of a calflow or family module, or None (not one, or absent)."""
    return _modules().get(module)


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
    """One pass over ``tree``: per top-level function or class (``""``: what runs when the
    module is imported: its other statements, decorators, default values, base classes
    and class-level statements), what it may import — ``[module, name]`` for ``from
    module import name`` or a ``"module:name"`` look-up, ``[module, None]`` for a whole
    module — and the names it refers to. Docstrings (string statements) are removed on
    the way: they document, they do not run."""
    here = module if package else module.rpartition(".")[0]
    scanned: dict[str, tuple[list, list]] = {}
    tree.body = [s for s in tree.body if not _is_doc(s)] or [ast.Pass()]
    for stmt in tree.body:
        if isinstance(stmt, _BODIES):
            parts = [(stmt.name, [stmt]), ("", _on_import(stmt))]
        else:
            parts = [("", [stmt])]
        for key, nodes in parts:
            imports, names = scanned.setdefault(key, ([], []))
            looked_up = imports
            if not key and isinstance(stmt, (ast.Assign, ast.AnnAssign)):
                # a table of "module:name" strings is looked up by the code that reads it
                targets = stmt.targets if isinstance(stmt, ast.Assign) else [stmt.target]
                if len(targets) == 1 and isinstance(targets[0], ast.Name):
                    looked_up = scanned.setdefault(targets[0].id, ([], []))[0]
            _visit(nodes, here, strings, imports, names, looked_up)
    return scanned


def _on_import(stmt: ast.stmt) -> list[ast.AST]:
    """The parts of a function or class definition that run when its module is imported."""
    found: list[ast.AST] = list(stmt.decorator_list)
    if isinstance(stmt, ast.ClassDef):
        found += stmt.bases + stmt.keywords
        found += [s for s in stmt.body if not isinstance(s, _BODIES)]
        for s in stmt.body:
            if isinstance(s, _BODIES):
                found += _on_import(s)
    else:
        found += stmt.args.defaults + [d for d in stmt.args.kw_defaults if d is not None]
    return found


def _visit(
    nodes: list[ast.AST], here: str, strings: bool, imports: list, names: list, looked_up: list
) -> None:
    stack = list(nodes)
    while stack:
        node = stack.pop()
        kind = type(node)
        if kind in _BODIES:  # before its statements are read: a docstring names no import
            node.body = [s for s in node.body if not _is_doc(s)] or [ast.Pass()]
        stack.extend(ast.iter_child_nodes(node))
        if kind is ast.Name:
            names.append(node.id)
        elif kind is ast.Constant:
            value = node.value
            if strings and type(value) is str and ":" in value:
                target, _, attr = value.partition(":")
                if attr.isidentifier() and all(p.isidentifier() for p in target.split(".")):
                    looked_up.append([target, attr])
        elif kind is ast.Import:
            imports.extend([alias.name, None] for alias in node.names)
        elif kind is ast.ImportFrom:
            base = _module_name(node, here)
            imports.extend([base, None if alias.name == "*" else alias.name] for alias in node.names)
        elif kind is ast.Call:
            func, args = node.func, node.args
            if (
                args
                and getattr(func, "attr", getattr(func, "id", None)) == "import_module"
                and isinstance(args[0], ast.Constant)
                and isinstance(args[0].value, str)
            ):
                imports.append([args[0].value, None])


_BODIES = (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)


@cache
def _cache_dir() -> Path | None:
    """Where normalised digests are kept between processes (content-addressed, so never
    stale): ``$CALFLOW_CACHE_DIR``, else ``$XDG_CACHE_HOME/calflow`` or ``~/.cache/calflow``;
    empty ``CALFLOW_CACHE_DIR``: none."""
    folder = os.environ.get("CALFLOW_CACHE_DIR")
    if folder is None:
        folder = os.path.join(os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "calflow")
    return Path(folder) / "provenance" if folder else None


def _normalised(module: str, path: Path, package: bool, strings: bool) -> dict:
    """``{"digest", "functions"}`` of a module's source: computed, or read from the cache
    by the hash of the source itself."""
    import json
    import sys

    raw = path.read_bytes()
    key = hashlib.sha256(
        f"v3 {sys.version_info[:2]} {module} {package} {strings}\n".encode() + raw
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
        "functions": {
            k: [sorted({tuple(x) for x in i}, key=str), sorted(set(n))] for k, (i, n) in scanned.items()
        },
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
    functions = {k: (tuple(map(tuple, i)), frozenset(n)) for k, (i, n) in found["functions"].items()}
    functions.setdefault("", ((), frozenset()))
    h = hashlib.sha256(found["digest"].encode())
    if package:  # the package's data: its folders that are no packages, recursively
        for data in _data_files(path.parent):
            h.update(data.relative_to(path.parent).as_posix().encode())
            h.update(data.read_bytes())
    return Source(path, package, h.hexdigest(), functions)


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
    from calflow.cli import entry_points

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
        if module == "calflow.cli":  # the other subcommands: dispatched to, not run
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
