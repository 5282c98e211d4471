"""docs/steps.md: the table of every step of calflow and its families in this distribution —
what it reads, what it writes, the workflow rule that runs it and the function it runs — made
from the steps' declarations and the rules files, never written by hand::

    python -m calflow.steps.table > docs/steps.md

(``tests/project/test_steps.py`` fails when the page is not what this prints.)
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

from calflow.configuration import layout
from calflow.step import ALL, Step

HEAD = """# Steps

Every `calflow` subcommand is one step, declared once (`calflow.step.Step`): the campaign keys it
reads, the files it reads and writes (paths of `calflow.configuration.layout`), its options and the
function it runs. The command line (`calflow <step> --help`), the sections a workflow job is handed
and digested (`reads(step)` in `workflow/rules/common.smk`) and the code its rerun digest covers
follow from that declaration. The core's steps are declared in `calflow.steps.campaign` and
`calflow.steps.tools`, a family's in its `Family.commands` ([families.md](families.md)).

Every step that reads a campaign reads its `robot` and `start` too.
A rule may add what one job reads besides (the plan of the run it acquires). This page is
generated: `python -m calflow.steps.table > docs/steps.md`.

A new step is one declaration and one function: a `Step` (in `calflow.steps`, or a family's
`commands`) naming `"module:function"`, and that function, `run(job)`, reading its options
from the `calflow.step.Job` it is handed (`job.out`, `job.run`; its campaign through
`calflow.configuration.handed.campaign_of(job)`). `calflow <step> --help` shows it at once; a
rule runs it with `params: **reads("<step>")` and `--sections {params.sections:q}` in its
shell, and reruns when a key it declares or the code it reaches changes
(`tests/families/test_new_step.py` does exactly this from a family written in the test).

| step | reads | writes | rule | runs |
|---|---|---|---|---|
"""


def path_of(name: str) -> str:
    """The path pattern of layout function ``name``, from its docstring (``results/<campaign>/…``)."""
    doc = getattr(layout, name).__doc__ or ""
    found = re.findall(r"``((?:results|reports)/[^`]*)``", doc)
    if not found:
        raise ValueError(f"calflow.configuration.layout.{name}: its docstring names no path")
    return found[0]


def rules_running(rules_files: list[Path]) -> dict[str, list[str]]:
    """Step → the rules whose shell runs ``calflow <step>``, in the files' order."""
    found: dict[str, list[str]] = {}
    for path in rules_files:
        for block in re.split(r"^(?=rule \w+:)", path.read_text(), flags=re.M):
            rule = re.match(r"rule (\w+):", block)
            for name in re.findall(r'"calflow ([a-z][a-z0-9-]*)\b', block) if rule else ():
                found.setdefault(name, []).append(rule.group(1))
    return found


def _cell(items: list[str]) -> str:
    return "<br>".join(i.replace("|", "\\|") for i in items) or "–"


def row(s: Step, rules: list[str]) -> str:
    keys = ["the whole campaign" if k == ALL else f"`{k}`" for k in s.reads]
    reads = [f"campaign: {', '.join(keys)}"] if keys else []
    reads += [s.reads_per_job] if s.reads_per_job else []
    reads += [f"`{path_of(n)}`" for n in s.inputs]
    writes = [f"`{path_of(n)}`" for n in s.writes]
    return (
        f"| `{s.name}` | {_cell(reads)} | {_cell(writes)} | {_cell([f'`{r}`' for r in rules])} | `{s.run}` |"
    )


def table(workflow: Path) -> str:
    """docs/steps.md: the steps of calflow's core and of its own families, with the rules of
    ``workflow/rules`` and of those families."""
    from calflow.family import families
    from calflow.steps import steps

    own = [f for f in families() if all(s.run.startswith("calflow.") for s in f.commands)]
    files = sorted((workflow / "rules").glob("*.smk")) + [Path(p) for f in own for p in f.rules_files()]
    running = rules_running(files)
    listed = [s for s in steps() if s.run.startswith("calflow.")]
    return HEAD + "\n".join(row(s, running.get(s.name, [])) for s in listed) + "\n"


if __name__ == "__main__":
    sys.stdout.write(table(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("workflow")))
