"""docs/families.md against the code: every path, module and ``module:attribute`` it names
exists, it documents every hook, field and step input of the contract, the rules globals are
the core's and all the family rules use, and the hexapod plug-in imports only the public core."""

from __future__ import annotations

import ast
import dataclasses
import re
from pathlib import Path

import pytest

from calflow.family import GROUP, Family
from calflow.family_contract import HOOKS, PUBLIC_CORE, RULE_GLOBALS, STEP_ARGS
from calflow.family_workflow import FamilyWorkflow
from calflow.hook_source import binding, locate

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "families.md"
PLUGIN = ROOT / "plugins" / "calflow-hexapod" / "src" / "calflow_hexapod"
PATH_ROOTS = (ROOT, ROOT / "src" / "calflow", PLUGIN.parent, PLUGIN.parents[1], ROOT / "docs")
GENERATED = ("results/", "reports/")  # written by a run, not in the repository
PACKAGES = ("calflow", "calflow_hexapod", "toystage")


def _spans() -> list[str]:
    """Inline code of the page (fenced blocks left out)."""
    text = re.sub(r"```.*?```", "", DOC.read_text(), flags=re.S)
    return re.findall(r"`([^`\n]+)`", text)


SPANS = _spans()


def _resolves(dotted: str) -> bool:
    """``pkg.module`` or ``pkg.module.attribute`` (or ``module:attribute``) names something."""
    if ":" in dotted:
        return not isinstance(binding(*dotted.split(":", 1)), str)
    if not isinstance(locate(dotted), str):
        return True
    module, _, attr = dotted.rpartition(".")
    return bool(module) and not isinstance(binding(module, attr), str)


@pytest.fixture(autouse=True)
def _tests_on_path(monkeypatch):
    monkeypatch.syspath_prepend(str(ROOT / "tests"))  # the toy family's package


def test_every_module_and_attribute_named_exists():
    pattern = rf"({'|'.join(PACKAGES)})(\.\w+)*(:\w+)?"
    named = [s for s in SPANS if re.fullmatch(pattern, s) and s != GROUP]
    assert len(named) > 20
    missing = [s for s in named if not _resolves(s)]
    assert missing == []


def test_every_path_named_exists():
    paths = [
        s
        for s in SPANS
        if re.fullmatch(r"[\w.\-]+(/[\w.\-]*)+", s) and not s.startswith(GENERATED) and "/" in s.rstrip("/")
    ]
    assert len(paths) > 10
    missing = [p for p in paths if not any((root / p).exists() for root in PATH_ROOTS)]
    assert missing == []
    links = re.findall(r"\]\(([\w.\-]+\.md)\)", DOC.read_text())
    assert [link for link in links if not (DOC.parent / link).is_file()] == []


def test_every_hook_field_and_step_input_is_documented():
    spans = set(SPANS)
    assert [h.call for h in HOOKS if h.call not in spans] == []
    assert [f.name for f in dataclasses.fields(Family) if f.name not in spans] == []
    for step, inputs in STEP_ARGS.items():
        assert f'steps["{step}"]' in spans and f"{step}(c, args)" in spans
        assert [a for a in inputs if a not in spans] == []
    methods = [n for n in vars(FamilyWorkflow) if not n.startswith("_")]
    assert [m for m in methods if m not in spans] == []
    assert [g for g in RULE_GLOBALS if g not in spans] == []


def test_the_public_core_is_documented_as_declared():
    text = DOC.read_text()
    for module, names in PUBLIC_CORE.items():
        row = next((r for r in text.splitlines() if r.startswith(f"| `{module}` |")), None)
        assert row is not None, f"docs/families.md: no row of the public core for {module}"
        assert re.findall(r"`([^`]+)`", row.split("|")[2]) == list(names), module


def test_every_public_core_name_exists():
    for module, names in PUBLIC_CORE.items():
        assert not isinstance(locate(module), str), module
        for name in names:
            if name != "*":
                assert _resolves(f"{module}:{name}") or _resolves(f"{module}.{name}"), f"{module}:{name}"


def _core_rules_names() -> set[str]:
    """What the core rules define: top-level functions and names, upper-case names in any
    block, and what they import."""
    text = "".join(
        p.read_text() for p in [ROOT / "Snakefile", *sorted((ROOT / "workflow/rules").glob("*.smk"))]
    )
    names = set(re.findall(r"^def (\w+)", text, re.M)) | set(
        re.findall(r"^([A-Za-z_]\w*)\s*=[^=]", text, re.M)
    )
    names |= set(re.findall(r"^\s+([A-Z][A-Z0-9_]+)\s*=[^=]", text, re.M))
    for m in re.finditer(r"^from [\w.]+ import (?:\(([^)]*)\)|([^\n(]+)$)", text, re.M):
        names |= {p.split(" as ")[-1].strip() for p in (m.group(1) or m.group(2)).split(",") if p.strip()}
    return names


def test_family_rules_use_only_the_declared_globals():
    core = _core_rules_names()
    assert set(RULE_GLOBALS) <= core
    files = [*(ROOT / "src/calflow").glob("*/rules/*.smk"), *PLUGIN.rglob("*.smk")]
    assert files
    for path in files:
        text = re.sub(r"#.*", "", path.read_text())
        own = set(re.findall(r"^\s*def (\w+)", text, re.M)) | set(
            re.findall(r"^\s*(\w+)\s*=[^=]", text, re.M)
        )
        own |= set(re.findall(r"\b(\w+)=", text)) | set(re.findall(r"\bfor (\w+) in\b", text))
        used = {n for n in core - own if re.search(rf"(?<![\w.]){n}\b", text)}
        assert used <= set(RULE_GLOBALS), (
            f"{path.name} uses {sorted(used - set(RULE_GLOBALS))} of the core rules"
        )


def _imports(path: Path) -> list[tuple[str, str]]:
    """``(module, name)`` of every calflow import in ``path``, anywhere in it (``name`` empty
    for ``import module``; a string ``importlib.import_module("calflow...")`` too)."""
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found += [(node.module, a.name) for a in node.names]
        elif isinstance(node, ast.Import):
            found += [(a.name, "") for a in node.names]
        elif isinstance(node, ast.Call) and getattr(node.func, "attr", "") == "import_module" and node.args:
            if isinstance(node.args[0], ast.Constant):
                found.append((str(node.args[0].value), ""))
    return [(m, n) for m, n in found if m == "calflow" or m.startswith("calflow.")]


def test_the_hexapod_imports_only_the_public_core():
    files = sorted(PLUGIN.rglob("*.py"))
    assert len(files) > 20
    outside = []
    for path in files:
        for module, name in _imports(path):
            allowed = PUBLIC_CORE.get(module, ())
            if not ("*" in allowed and not name.startswith("_") or name in allowed):
                outside.append(f"{path.relative_to(PLUGIN)}: {module}{':' + name if name else ''}")
    assert outside == []


def test_the_import_walk_sees_imports_inside_functions(tmp_path):
    f = tmp_path / "m.py"
    f.write_text("def g():\n    from calflow.configuration.config import load_yaml\n    import calflow.cli\n")
    assert _imports(f) == [("calflow.configuration.config", "load_yaml"), ("calflow.cli", "")]
