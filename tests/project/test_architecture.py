"""The package's shape (issue: one package per robot family over a shared core).

Reads every module's imports, including those inside functions: a family imports the
core (and the controller layer ``calflow.gcs``) and never another family; the core and
``calflow.gcs`` never import a family; no import cycle between modules; no module over
~400 lines; ``calflow acquire`` does not branch on plan names.
"""

from __future__ import annotations

import ast
import functools
import re
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[2] / "src" / "calflow"
FAMILIES = ("xytheta", "nano")
MAX_LINES = 420  # "~400": a module that grows past this has split into two concepts


def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in PACKAGE.rglob("*.py")}


MODULES = _modules()


def _imports(name: str, path: Path) -> set[str]:
    """calflow modules ``name`` imports, anywhere in its body (resolved to modules)."""
    is_pkg = path.name == "__init__.py"
    package = name if is_pkg else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        targets = []
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            # `from pkg import submodule` imports the submodule; `from mod import name`, mod
            subs = [f"{mod}.{a.name}" for a in node.names if f"{mod}.{a.name}" in MODULES]
            targets = subs + ([mod] if len(subs) < len(node.names) else [])
        for t in targets:
            while t and t not in MODULES:
                t = t.rpartition(".")[0]
            if t.startswith("calflow") and t != name:
                found.add(t)
    return found


@functools.cache
def _graph() -> dict[str, set[str]]:
    """Each calflow module's calflow imports: parsed once, when the first test asks (not at
    import, which every pytest-xdist worker's collection would pay for)."""
    return {name: _imports(name, path) for name, path in MODULES.items()}


def _family(module: str) -> str | None:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 and parts[1] in FAMILIES else None


def test_the_families_exist():
    for fam in FAMILIES:
        assert f"calflow.{fam}" in MODULES
        assert f"calflow.{fam}.family" in MODULES


@pytest.mark.parametrize("module", sorted(MODULES))
def test_layers(module):
    own = _family(module)
    for dep in _graph()[module]:
        other = _family(dep)
        if own is None:
            assert other is None, f"core module {module} imports family module {dep}"
        else:
            assert other in (None, own), f"{module} (family {own}) imports {dep} (family {other})"


def test_no_import_cycle():
    """Tarjan's strongly connected components over the module graph; each must be one module."""
    index, low, stack, on, cycles = {}, {}, [], set(), []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in _graph()[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                cycles.append(sorted(comp))

    for v in sorted(_graph()):
        if v not in index:
            visit(v)
    assert cycles == []


@pytest.mark.parametrize("module", sorted(MODULES))
def test_module_size(module):
    n = len(MODULES[module].read_text().splitlines())
    assert n <= MAX_LINES, f"{module} has {n} lines"


def test_acquire_does_not_branch_on_plans():
    src = (PACKAGE / "commands" / "acquire.py").read_text()
    tree = ast.parse(src)
    for node in ast.walk(tree):
        if isinstance(node, ast.Compare):
            names = {n.attr for n in ast.walk(node) if isinstance(n, ast.Attribute)}
            assert "plan" not in names, f"calflow acquire compares args.plan (line {node.lineno})"


# ------------------------------------------------------------------ rooms inside a family
MAX_SIBLINGS = 13  # "~12": a folder that holds more has grown a concept of its own
# Rooms that analyse what a rig recorded; they never import the simulated stage (its truth
# is for tests and reports only).
ANALYSIS_ROOMS = ("models", "tables", "export")


def _room(module: str) -> str | None:
    parts = module.split(".")
    return parts[2] if len(parts) > 3 else None


@pytest.mark.parametrize("family", FAMILIES)
def test_rooms_stay_small(family):
    for folder in [PACKAGE / family, *(p for p in (PACKAGE / family).rglob("*") if p.is_dir())]:
        if folder.name in ("__pycache__", "templates"):
            continue
        entries = [
            p
            for p in folder.iterdir()
            if p.name != "__pycache__"
            and (p.suffix == ".py" or (p.is_dir() and (p / "__init__.py").is_file()))
        ]
        assert len(entries) <= MAX_SIBLINGS, f"{folder.relative_to(PACKAGE)} holds {len(entries)} modules"


@pytest.mark.parametrize("module", sorted(m for m in MODULES if _family(m) and _room(m) in ANALYSIS_ROOMS))
def test_analysis_never_imports_the_simulated_stage(module):
    stage = f"calflow.{_family(module)}.stage"
    for dep in _graph()[module]:
        assert not dep.startswith(stage), f"{module} (analysis) imports the simulated stage {dep}"


def test_rooms_are_packages_with_a_docstring():
    for family in FAMILIES:
        for init in (PACKAGE / family).rglob("__init__.py"):
            doc = ast.get_docstring(ast.parse(init.read_text()))
            assert doc, f"{init.relative_to(PACKAGE)} says nothing of what its room holds"


# ------------------------------------------------------------------ a core that names no family
ROOT = PACKAGE.parents[1]


def _family_names() -> set[str]:
    """The robot and family names of every installed family (calflow's own and plug-ins)."""
    from calflow.family import families

    return {name for fam in families() for name in (fam.name, *fam.robots)}


def _docstrings(tree: ast.AST) -> set[int]:
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
                found.add(id(body[0].value))
    return found


def _named_families(text: str, names: set[str]) -> list[str]:
    """Quoted robot names (``"xytheta"``) and ``calflow.<family>`` in ``text``."""
    alternatives = "|".join(map(re.escape, sorted(names)))
    pattern = re.compile(rf"""["']({alternatives})["']|calflow\.({alternatives})\b""")
    return [m.group(0) for m in pattern.finditer(text)]


@pytest.mark.parametrize("module", sorted(m for m in MODULES if _family(m) is None))
def test_core_modules_name_no_family(module):
    """A core module's code names no robot or family (its docstrings may, as examples): what
    differs between robots comes from the calflow.families registry."""
    names = _family_names()
    tree = ast.parse(MODULES[module].read_text())
    docs = _docstrings(tree)
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docs:
            # a D-SI unit's prefix (r"\nano\metre") names a unit, not a family
            words = set(re.findall(r"(?<![\\A-Za-z0-9_])[A-Za-z0-9_]+", node.value))
            assert not words & names, f"{module} line {node.lineno} names {sorted(words & names)}"
            assert not _named_families(node.value, names), f"{module} line {node.lineno} imports a family"


def _workflow_files() -> list[Path]:
    return [ROOT / "Snakefile", *sorted((ROOT / "workflow").rglob("*.smk")), *sorted(TEMPLATES.glob("*.j2"))]


TEMPLATES = PACKAGE / "report" / "templates"


@pytest.mark.parametrize("path", _workflow_files(), ids=lambda p: str(p.relative_to(ROOT)))
def test_core_rules_and_templates_name_no_family(path):
    """The core Snakemake rules and report templates name no robot outside comments: each
    family's own rules files and templates live in its package."""
    names = _family_names()
    for n, line in enumerate(path.read_text().splitlines(), 1):
        code = line.split("#", 1)[0] if path.suffix != ".j2" else re.sub(r"\{#.*?#\}", "", line)
        assert not _named_families(code, names), f"{path.name}:{n} names a family: {line.strip()}"


def test_families_register_what_the_core_asks():
    """Every installed family says what the core cannot know: its robots' joints and its rules."""
    from calflow.family import families

    for fam in families():
        for robot in fam.robots:
            assert fam.joints_of(robot), f"family {fam.name}: no joints for robot {robot}"
        for path in fam.rules_files():
            assert Path(path).is_file(), f"family {fam.name}: rules file {path} missing"
        assert fam.hooks().open_loop_runs or fam.rules, f"family {fam.name} adds no runs to the workflow"


def _family_sources() -> dict[str, list[Path]]:
    """Every installed family's Python files (the plug-in's too): the package of the module
    its ``calflow.families`` entry point names."""
    from importlib.metadata import entry_points
    from importlib.util import find_spec

    out = {}
    for ep in entry_points(group="calflow.families"):
        package = ep.module.rpartition(".")[0]
        spec = find_spec(package)
        assert spec is not None and spec.submodule_search_locations, f"family {ep.name}: no package {package}"
        out[ep.name] = [p for d in spec.submodule_search_locations for p in Path(d).rglob("*.py")]
    return out


@pytest.mark.parametrize("word", ["argparse", "Namespace"])
def test_no_family_knows_the_command_line_parser(word):
    """A family's steps take typed inputs (calflow.step.Job), not an argparse Namespace: the
    words appear in no family's code, the plug-in's included."""
    sources = _family_sources()
    assert {"xytheta", "nano", "hexapod"} <= set(sources)
    found = [
        f"{p}:{i}"
        for files in sources.values()
        for p in files
        for i, line in enumerate(p.read_text().splitlines(), 1)
        if word in line
    ]
    assert not found, f"{word!r} in a family's code: {', '.join(found[:5])}"
