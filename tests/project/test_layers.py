"""The layers of docs/architecture.md are the package's: every room listed, in an order its
imports follow, none importing a room above it, no two in an import cycle."""

from __future__ import annotations

import ast
import re
from collections import defaultdict
from functools import cache
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGE = ROOT / "src" / "calflow"
DOC = (ROOT / "docs" / "architecture.md").read_text()
SECTION = DOC[DOC.index("## Layers and their import rules") :]
SECTION = SECTION[: SECTION.index("\n## ", 1)]


def _documented_rooms() -> list[str]:
    rows = re.findall(r"^\| [a-z ]+ \| (`[^|]+`) \| [^|]+ \|$", SECTION, re.M)
    return [name for row in rows for name in re.findall(r"`(\w+)`", row)]


def _rooms() -> set[str]:
    return {
        p.stem if p.suffix == ".py" else p.name
        for p in PACKAGE.iterdir()
        if (p.suffix == ".py" and p.stem not in ("__init__", "__main__")) or (p / "__init__.py").is_file()
    }


def _imports(path: Path, package: str) -> list[tuple[str, int]]:
    """Every calflow module ``path`` imports (inside functions too), with its line."""
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out += [(a.name, node.lineno) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module or ""
            out.append((module, node.lineno))
            if module == "calflow":  # from calflow import errors
                out += [(f"calflow.{a.name}", node.lineno) for a in node.names]
    return [(m, line) for m, line in out if m.startswith("calflow.")]


@cache
def room_imports() -> dict[tuple[str, str], list[str]]:
    """(room, room it imports) → where, for every pair of different rooms."""
    rooms, edges = _rooms(), defaultdict(list)
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        module = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        package = module if parts[-1] == "__init__" else module.rpartition(".")[0]
        here = module.split(".")[1] if "." in module else None
        for target, line in _imports(path, package):
            there = target.split(".")[1]
            if here and here in rooms and there in rooms and there != here:
                edges[(here, there)].append(f"{path.relative_to(PACKAGE)}:{line}")
    return edges


ORDER = {room: i for i, room in enumerate(_documented_rooms())}


def test_the_table_lists_every_room_once():
    listed = _documented_rooms()
    assert len(listed) == len(set(listed)), "a room is listed twice"
    assert set(listed) == _rooms(), (
        f"docs/architecture.md lists rooms that are not there: {sorted(set(listed) - _rooms())}; "
        f"rooms it does not list: {sorted(_rooms() - set(listed))}"
    )


def up_edges() -> dict[tuple[str, str], list[str]]:
    return {(a, b): w for (a, b), w in room_imports().items() if ORDER[b] > ORDER[a]}


def test_no_import_points_up():
    found = up_edges()
    assert not found, "imports up the layers of docs/architecture.md: " + "; ".join(
        f"{a} -> {b} ({', '.join(w[:3])})" for (a, b), w in sorted(found.items())
    )


def cycles(edges) -> list[list[str]]:
    """The strongly connected components of more than one room of the graph ``edges``: rooms
    that import each other, directly or through others (scipy's, an oracle not written here)."""
    import numpy as np
    from scipy.sparse import coo_array
    from scipy.sparse.csgraph import connected_components

    rooms = sorted({r for e in edges for r in e})
    index = {r: i for i, r in enumerate(rooms)}
    rows, cols = zip(*[(index[a], index[b]) for a, b in edges], strict=True) if edges else ((), ())
    graph = coo_array((np.ones(len(rows)), (rows, cols)), shape=(len(rooms), len(rooms)))
    _, label = connected_components(graph, directed=True, connection="strong")
    groups = defaultdict(list)
    for room, k in zip(rooms, label, strict=True):
        groups[k].append(room)
    return sorted(g for g in groups.values() if len(g) > 1)


def test_cycles_finds_rooms_that_import_each_other_through_others():
    assert cycles([("a", "b"), ("b", "c"), ("c", "a"), ("c", "d")]) == [["a", "b", "c"]]
    assert cycles([("a", "b"), ("b", "c"), ("a", "c")]) == []


def test_no_two_rooms_are_in_an_import_cycle():
    """0 of the package's rooms in a cycle: each can be read knowing only the rooms below it."""
    found = cycles(list(room_imports()))
    assert not found, "rooms that import each other: " + "; ".join(
        " <-> ".join(g)
        + " ("
        + ", ".join(
            f"{a} -> {b}: {room_imports()[(a, b)][0]}" for a in g for b in g if (a, b) in room_imports()
        )
        + ")"
        for g in found
    )


def test_the_families_are_on_top():
    families = {"xytheta", "nano"}
    assert max(ORDER[r] for r in ORDER if r not in families) < min(ORDER[f] for f in families)
    assert not [e for e in room_imports() if e[1] in families and e[0] not in families]


@pytest.mark.parametrize("name", sorted(set(re.findall(r"`(calflow(?:\.\w+)+)", DOC))))
def test_every_module_and_name_the_page_cites_exists(name):
    """A page that names ``calflow.config.py`` after it moved sends a newcomer nowhere."""
    import importlib
    from importlib.metadata import entry_points

    if entry_points(group=name):  # an entry-point group (calflow.families), not a module
        return
    module, attr = name, None
    while True:
        try:
            found = importlib.import_module(module)
            break
        except ModuleNotFoundError:
            module, _, tail = module.rpartition(".")
            attr = tail if attr is None else f"{tail}.{attr}"
            assert module, f"docs/architecture.md cites {name}, which does not import"
    for part in (attr or "").split(".") if attr else ():
        assert hasattr(found, part), f"docs/architecture.md cites {name}: {found.__name__} has no {part}"
        found = getattr(found, part)


@pytest.mark.parametrize(
    "question, function",
    [
        ("AP's and RP's expanded uncertainty U", "calflow.metrics.uncertainty_iso.iso9283_uncertainty"),
        ("a stage's history rebuilt", "calflow.lifecycle.history.build"),
        ("the decoder turning a frame's phases and code into x", "calflow.instruments.pattern.decode.decode"),
    ],
)
def test_a_newcomer_finds_the_code_from_readme_in_three_files(question, function):
    """README.md links to the table of docs/architecture.md, whose row names the module that
    holds the function: three files opened (README, the page, the module)."""
    import importlib
    import inspect

    readme = (ROOT / "README.md").read_text()
    assert "docs/architecture.md#where-to-find-it" in readme
    table = DOC[DOC.index("## Where to find it") :]
    table = table[: table.index("\n## ", 1)]
    row = next((r for r in table.splitlines() if r.startswith(f"| {question}")), None)
    assert row is not None and f"`{function}" in row, f"no row for {question!r} naming {function}"
    module, _, name = function.rpartition(".")
    found = getattr(importlib.import_module(module), name)
    assert inspect.isfunction(found) and found.__module__ == module, (
        f"{function} is defined in {found.__module__}, another file than the one the table names"
    )
