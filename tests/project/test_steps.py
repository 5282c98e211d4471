"""Every step is declared once (calflow.step.Step) and everything else follows: the command line,
the rules' sections, provenance's entry points and docs/steps.md."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from calflow.cli import parser
from calflow.configuration import layout
from calflow.hook_source import binding
from calflow.step import ALL, STAMP, Option, Step
from calflow.steps import entry_point, options_of, step, steps
from calflow.steps.table import path_of, rules_running, table

ROOT = Path(__file__).resolve().parents[2]
NAMES = [s.name for s in steps()]


def test_docs_steps_md_is_the_generated_table():
    assert (ROOT / "docs" / "steps.md").read_text() == table(ROOT / "workflow"), (
        "docs/steps.md is stale: python -m calflow.steps.table > docs/steps.md"
    )


@pytest.mark.parametrize("name", NAMES)
def test_a_step_names_a_function_and_layout_paths(name):
    s = step(name)
    module, attr = s.run.split(":")
    assert binding(module, attr)[0] == "function", f"{name}: {s.run} is not a function"
    for f in (*s.inputs, *s.writes):
        assert callable(getattr(layout, f, None)) and path_of(f).startswith(("results/", "reports/"))


@pytest.mark.parametrize("name", NAMES)
def test_the_command_line_is_the_declaration(name):
    """Each declared option (and the families' additions) is on ``calflow <step>``, required
    where declared; a step that reads a campaign takes --sections."""
    sub = next(a for a in parser()._actions if a.dest == "command").choices[name]
    actions = {a.option_strings[0] if a.option_strings else a.dest: a for a in sub._actions}
    for o in options_of(name):
        assert o.name in actions, f"calflow {name}: {o.name} declared, not on the command line"
        if not o.positional:
            assert actions[o.name].required == o.required
    assert ("--sections" in actions) == step(name).reads_campaign


def test_every_rule_runs_a_declared_step():
    from calflow.family import families

    files = sorted((ROOT / "workflow" / "rules").glob("*.smk"))
    files += [Path(p) for f in families() for p in f.rules_files()]
    running = rules_running(files)
    assert {"acquire", "summarise", "certificate"} <= set(running)
    assert set(running) <= set(NAMES), set(running) - set(NAMES)


def test_entry_points_are_the_declared_functions():
    assert entry_point("summarise") == "calflow.commands.campaign:summarise"
    assert {s.name: entry_point(s.name) for s in steps()} == {s.name: s.run for s in steps()}


def test_sections_are_the_stamp_then_what_the_step_and_the_rule_read():
    s = Step("x", "a step", "m:f", (Option("--campaign"),), reads=("seed", "rig"))
    assert s.sections() == [*STAMP, "seed", "rig"]
    assert s.sections("rig", "xy_tests") == [*STAMP, "seed", "rig", "xy_tests"]
    assert step("summarise").sections() == [*STAMP, ALL]


@pytest.mark.parametrize(
    "bad, match",
    [
        (dict(run="no_colon"), "module:function"),
        (dict(options=(Option("--a"), Option("--a"))), "declared twice"),
    ],
)
def test_a_bad_declaration_is_refused(bad, match):
    with pytest.raises(ValueError, match=match):
        Step(**{"name": "x", "help": "h", "run": "m:f", **bad})


def test_a_bad_option_is_refused():
    with pytest.raises(ValueError, match="kind"):
        Option("--a", kind="number")
    with pytest.raises(ValueError, match="many"):
        Option("--a", many="2")


def test_no_step_is_named_twice():
    assert len(NAMES) == len(set(NAMES))
    assert re.fullmatch(r"[a-z][a-z0-9-]*", "|".join(NAMES).replace("|", "-"))
