"""The calflow and family modules, each read statically: where it is, its normalised
digest (the syntax tree without docstrings and comments, a package with its data files)
and, per function or class, what it may import and the names it refers to
(:mod:`calflow.provenance` follows them).

Nothing is imported but the families' declarations (entry points); each module is parsed
with :mod:`ast` once per process, and its normalised digest kept between processes under
the hash of its own bytes (never stale).
"""

from __future__ import annotations

import ast
import hashlib
import importlib.util
import os
from dataclasses import dataclass
from functools import cache
from pathlib import Path

from calflow.cache import cached_json

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


@cache
def tree_fingerprint() -> str:
    """SHA-256 over everything a code digest may depend on: the Python version, the families'
    entry points and the bytes of every calflow or family module with its package's data
    files. A few milliseconds (no parsing): the key under which whole digests are kept
    between processes (:func:`calflow.provenance.code_digest`), so one changed byte anywhere
    computes them all again."""
    import sys
    from importlib.metadata import entry_points

    from calflow.family import GROUP

    h = hashlib.sha256(f"tree v1 {sys.version_info[:2]}\n".encode())
    for ep in sorted(f"{ep.name}={ep.value}" for ep in entry_points(group=GROUP)):
        h.update(f"{ep}\n".encode())
    for module, (path, package) in sorted(_modules().items()):
        h.update(f"{module}\n".encode())
        h.update(path.read_bytes())
        if package:
            for data in _data_files(path.parent):
                h.update(data.relative_to(path.parent).as_posix().encode())
                h.update(data.read_bytes())
    return h.hexdigest()


def under(package: str) -> tuple[str, ...]:
    """Every calflow or family module of ``package`` and its subpackages, sorted."""
    return tuple(sorted(m for m in _modules() if m == package or m.startswith(f"{package}.")))


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


def scan(tree: ast.Module, module: str, package: bool, strings: bool) -> dict[str, tuple[list, list]]:
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


def _normalised(module: str, path: Path, package: bool, strings: bool) -> dict:
    """``{"digest", "functions"}`` of a module's source: computed, or read from the cache
    by the hash of the source itself."""
    import sys

    raw = path.read_bytes()
    key = hashlib.sha256(
        f"v3 {sys.version_info[:2]} {module} {package} {strings}\n".encode() + raw
    ).hexdigest()

    def compute() -> dict:
        tree = ast.parse(raw, str(path))
        scanned = scan(tree, module, package, strings)
        return {
            "digest": hashlib.sha256(ast.dump(tree).encode()).hexdigest(),
            "functions": {
                k: [sorted({tuple(x) for x in i}, key=str), sorted(set(n))] for k, (i, n) in scanned.items()
            },
        }

    return cached_json("provenance", key, compute)


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
