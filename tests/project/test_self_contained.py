"""The repository is self-contained: what code, workflow, docs, config and reports say names
the concept, never a file outside the repository (the team's design notes) or a tracker's
issue number, which a newcomer with only the repository cannot follow."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCOPE = ("src", "workflow", "docs", "config", "README.md", "Snakefile", "Makefile", "pyproject.toml")
TEXT = {
    ".py",
    ".smk",
    ".md",
    ".rst",
    ".j2",
    ".html",
    ".yaml",
    ".yml",
    ".json",
    ".toml",
    ".cfg",
    ".txt",
    ".css",
    "",
}

# A GCS controller's single-character commands are written "#5", "#7" and "#24" (PI MS249E §8);
# they are the only "#<number>" that may appear. Hex colours ("#1f5fa8") and HTML character
# references ("&#8212;") are not numbers after a bare "#".
GCS_SINGLE_CHARACTER = {"5", "7", "24"}
PATTERNS = {
    "the team's design notes": re.compile(r"DESIGN\.md", re.IGNORECASE),
    "an issue number": re.compile(r"\bissues?\s*#?\s*\d+", re.IGNORECASE),
    "a pull-request number": re.compile(r"\b(?:PR|pull request)\s*#?\s*\d+", re.IGNORECASE),
    "the issue's own words": re.compile(r"\bthe issue's\b", re.IGNORECASE),
}
HASH_NUMBER = re.compile(r"(?<![&\w#])#(\d+)(?![\w.])")


def _files() -> list[Path]:
    out = []
    for name in SCOPE:
        p = ROOT / name
        paths = [p] if p.is_file() else sorted(q for q in p.rglob("*") if q.is_file())
        out += [q for q in paths if q.suffix in TEXT and "__pycache__" not in q.parts]
    return out


def offences(text: str) -> list[str]:
    """What in ``text`` points outside the repository, one entry per finding."""
    found = [f"{what}: {m.group(0)!r}" for what, rx in PATTERNS.items() for m in rx.finditer(text)]
    found += [
        f"an issue number: {m.group(0)!r}"
        for m in HASH_NUMBER.finditer(text)
        if m.group(1) not in GCS_SINGLE_CHARACTER
    ]
    return found


@pytest.mark.parametrize(
    "text",
    [
        "see DESIGN.md",
        "(issue 15)",
        "Issue 14: the budget",
        "after issues 14-16",
        "fixes #17",
        "(#15)",
        "issue #3",
        "PR 12 moved it",
        "the issue's targets",
    ],
)
def test_offences_are_found(text):
    assert offences(text), text


@pytest.mark.parametrize(
    "text",
    [
        "sends #24 (stop all)",
        "#5 (hex mask), #7",
        "color: #1f5fa8;",
        "&#8212;",
        "a tissue 3 mm",
        "Eq. (4.19)",
        "Table 4.7",
        "results/<campaign>/summary.json",
        "an issue with the rig",
    ],
)
def test_legitimate_text_passes(text):
    assert offences(text) == [], text


def test_the_scope_is_read():
    files = {p.relative_to(ROOT).as_posix() for p in _files()}
    assert "README.md" in files and "docs/architecture.md" in files
    assert any(f.startswith("src/calflow/") and f.endswith(".py") for f in files)
    assert any(f.startswith("workflow/rules/") for f in files)
    assert any(f.endswith(".j2") for f in files)


def test_nothing_points_outside_the_repository():
    problems = []
    for path in _files():
        for lineno, line in enumerate(path.read_text(encoding="utf-8", errors="replace").splitlines(), 1):
            problems += [f"{path.relative_to(ROOT)}:{lineno}: {o}" for o in offences(line)]
    assert problems == [], "name the concept instead:\n" + "\n".join(problems)
