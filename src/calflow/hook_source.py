"""Reading a family's hooks from their source, without running it.

A hook is named ``"module:attribute"``; registering a family must not import its numerical
modules (``calflow --help`` and the Snakefile read the registry), so
:mod:`calflow.family_contract` asks this module what the attribute is: the module's file is
found on the file system (:func:`locate`, no parent package imported) and its top-level
bindings read from its syntax tree (:func:`binding`: a function and its parameters, a class,
a value, an object built by a call, a name imported from elsewhere, followed). Each file's
bindings are cached between processes by the hash of its source.
"""

from __future__ import annotations

import ast
import importlib
import importlib.util
import inspect
import os
from functools import cache
from pathlib import Path

# ones, required keyword-only names, takes *args, takes **kwargs)
Params = tuple[tuple[str, ...], int, tuple[str, ...], tuple[str, ...], bool, bool]


def from_signature(sig: inspect.Signature) -> Params:
    ps = list(sig.parameters.values())
    pos = [p for p in ps if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)]
    kwonly = [p for p in ps if p.kind == p.KEYWORD_ONLY]
    return (
        tuple(p.name for p in pos),
        sum(p.default is p.empty for p in pos),
        tuple(p.name for p in kwonly),
        tuple(p.name for p in kwonly if p.default is p.empty),
        any(p.kind == p.VAR_POSITIONAL for p in ps),
        any(p.kind == p.VAR_KEYWORD for p in ps),
    )


def _from_ast(args: ast.arguments, skip_self: bool = False) -> Params:
    pos = [a.arg for a in (*args.posonlyargs, *args.args)][1 if skip_self else 0 :]
    required = len(pos) - len(args.defaults)
    kwonly = tuple(a.arg for a in args.kwonlyargs)
    kw_required = tuple(a.arg for a, d in zip(args.kwonlyargs, args.kw_defaults) if d is None)
    return tuple(pos), max(required, 0), kwonly, kw_required, args.vararg is not None, args.kwarg is not None


def _bindings(tree: ast.Module) -> dict[str, list]:
    """Each top-level name of a module and what binds it last: ``["function", params]``,
    ``["class", params | None]``, ``["alias", name]``, ``["import", level, module, name]``,
    ``["object"]`` (built by a call) or ``["value"]``."""
    found: dict[str, list] = {}
    for node in _statements(tree.body):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            found[node.name] = ["function", _from_ast(node.args)]
        elif isinstance(node, ast.ClassDef):
            init = next(
                (n for n in node.body if isinstance(n, ast.FunctionDef) and n.name == "__init__"), None
            )
            found[node.name] = ["class", _from_ast(init.args, skip_self=True) if init else None]
        elif isinstance(node, (ast.Assign, ast.AnnAssign)) and node.value is not None:
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            for target in targets:
                found.update(_assigned(tree, target, node.value))
        elif isinstance(node, ast.ImportFrom):
            for alias in node.names:
                found[alias.asname or alias.name] = ["import", node.level, node.module or "", alias.name]
    return found


def _assigned(tree: ast.Module, target: ast.expr, value: ast.expr) -> list[tuple[str, list]]:
    """The names an assignment binds and what each is: ``a, b = f, g`` pairwise; a tuple
    target the source does not pair (``a, b = make()``) binds objects known once imported."""
    if isinstance(target, ast.Name):
        if isinstance(value, ast.Name):
            return [(target.id, ["alias", value.id])]
        if isinstance(value, ast.Call):
            return [(target.id, list(_made_by(tree, value)))]
        if isinstance(value, (ast.Attribute, ast.Subscript, ast.Lambda)):
            return [(target.id, ["object"])]
        return [(target.id, ["value"])]
    if isinstance(target, (ast.Tuple, ast.List)):
        if isinstance(value, (ast.Tuple, ast.List)) and len(value.elts) == len(target.elts):
            return [b for t, v in zip(target.elts, value.elts) for b in _assigned(tree, t, v)]
        return [(t.id, ["object"]) for t in target.elts if isinstance(t, ast.Name)]
    return []


def _statements(body: list[ast.stmt]) -> list[ast.stmt]:
    """The module's top-level statements, those inside its top-level ``try`` and ``if``
    blocks included (``try: __version__ = ... except ...: __version__ = ...``)."""
    out: list[ast.stmt] = []
    for node in body:
        if isinstance(node, ast.Try):
            blocks = [node.body, *(h.body for h in node.handlers), node.orelse, node.finalbody]
            out += [n for block in blocks for n in _statements(block)]
        elif isinstance(node, ast.If):
            out += _statements(node.body) + _statements(node.orelse)
        else:
            out.append(node)
    return out


@cache
def _summary(path: str) -> dict[str, list]:
    """:func:`_bindings` of the module at ``path``: computed, or read from calflow's cache
    (:func:`calflow.cache.cached_json`) by the file's path, size and modification time, as
    Python keeps its bytecode, so registering the families parses no module twice."""
    import hashlib
    import sys

    from calflow.cache import cached_json

    st = os.stat(path)
    stamp = f"contract v5 {sys.version_info[:2]} {os.path.abspath(path)} {st.st_size} {st.st_mtime_ns}"
    key = hashlib.sha256(stamp.encode()).hexdigest()
    return cached_json("contract", key, lambda: _bindings(ast.parse(Path(path).read_bytes(), path)))


def _params(found: list | None) -> Params | None:
    """Params back from their JSON form (lists)."""
    if found is None:
        return None
    pos, required, kwonly, kw_required, varargs, varkw = found
    return tuple(pos), required, tuple(kwonly), tuple(kw_required), varargs, varkw


@cache
def locate(module: str) -> tuple[Path, bool] | str:
    """The source file of ``module`` and whether it is a package, found on the file system
    without importing it or its parent packages (a parent's ``__init__`` may be heavy); a
    string saying why when there is none."""
    parent, _, part = module.rpartition(".")
    if not parent:
        try:
            spec = importlib.util.find_spec(module)
        except (ImportError, ValueError) as exc:
            return f"module {module!r} cannot be found ({exc})"
        if spec is None:
            return f"no module {module!r}"
        if spec.submodule_search_locations:
            return Path(next(iter(spec.submodule_search_locations)), "__init__.py"), True
        return (Path(spec.origin), False) if spec.origin and spec.origin.endswith(".py") else "compiled"
    above = locate(parent)
    if isinstance(above, str) or not above[1]:
        return f"no module {module!r}"
    folder = os.path.dirname(above[0])
    if os.path.isfile(os.path.join(folder, part, "__init__.py")):
        return Path(folder, part, "__init__.py"), True
    if os.path.isfile(os.path.join(folder, f"{part}.py")):
        return Path(folder, f"{part}.py"), False
    return f"no module {module!r}"


def binding(module: str, attr: str, depth: int = 0) -> str | tuple[str, Params | None]:
    """What ``module:attr`` is, read from the module's source without running it:
    ``("function" | "class", params)``, ``("value", None)``, ``("object", None)`` (built by a
    call: unknown until imported), or a string saying why it does not resolve."""
    located = locate(module)
    if located == "compiled" or depth > 8:
        return _imported(module, attr)
    if isinstance(located, str):
        return located
    path, is_package = located
    package = module if is_package else module.rpartition(".")[0]
    what = _summary(str(path)).get(attr)
    if what is None:  # bound in a way the source does not show plainly (a, b = ..., a loop): ask Python
        return _imported(module, attr)
    if what[0] in ("function", "class"):
        return what[0], _params(what[1])
    if what[0] == "alias":
        return binding(module, what[1], depth + 1)
    if what[0] == "import":
        level, source, name = what[1:]
        base = package.split(".")[: len(package.split(".")) - level + 1] if level else []
        source = ".".join([*base, *([source] if source else [])])
        if not isinstance(locate(f"{source}.{name}"), str):
            return "value", None  # a submodule
        return binding(source, name, depth + 1)
    return what[0], None


def _imported(module: str, attr: str) -> str | tuple[str, Params | None]:
    """What ``module:attr`` is once the module is imported (the slow path: only for what the
    module's source does not bind plainly)."""
    try:
        obj = getattr(importlib.import_module(module), attr, None)
    except Exception as exc:  # the module fails on import: say so, in one line
        return (
            f"module {module!r} cannot be imported ({type(exc).__name__}: {str(exc).splitlines()[0][:120]})"
        )
    if obj is None:
        return f"module {module!r} has no attribute {attr!r}"
    if not callable(obj):
        return "value", None
    try:
        return ("class" if inspect.isclass(obj) else "function"), from_signature(inspect.signature(obj))
    except (TypeError, ValueError):  # a builtin without a signature
        return "object", None


def _made_by(tree: ast.Module, call: ast.Call) -> tuple[str, Params | None]:
    """What a call of a function of the same module returns when that function returns a
    function it defines (``characterisation_x = _characterisation("x")``); ``("object",
    None)`` — unknown until imported — otherwise."""
    if isinstance(call.func, ast.Name):
        maker = next(
            (n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name == call.func.id), None
        )
        if maker is not None:
            inner = {n.name: n for n in maker.body if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))}
            returned = [
                n.value.id for n in maker.body if isinstance(n, ast.Return) and isinstance(n.value, ast.Name)
            ]
            if len(returned) == 1 and returned[0] in inner:
                return "function", _from_ast(inner[returned[0]].args)
    return "object", None


def package_dir(package: str) -> Path | None:
    located = locate(package)
    if isinstance(located, str) or not located[1]:
        return None
    return located[0].parent
