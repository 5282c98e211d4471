"""Every step of calflow, where each is declared: the core's (:mod:`calflow.steps.campaign`,
:mod:`calflow.steps.tools`) and those the installed families add (``Family.commands``), each one
:class:`calflow.step.Step`.

The command line is built from them (:func:`calflow.cli.parser`), the workflow's rules look a
step up to hand a job its sections (``reads`` in workflow/rules/common.smk), provenance starts a
step's code digest at its function (:func:`entry_point`), and docs/steps.md is their table
(:mod:`calflow.steps.table`).
"""

from __future__ import annotations

from functools import cache

from calflow.errors import CalflowError
from calflow.step import Option, Step

__all__ = ["Option", "Step", "entry_point", "entry_points", "options_of", "step", "steps"]


def core() -> tuple[Step, ...]:
    """The core's steps, in the order ``calflow --help`` lists them."""
    from calflow.steps import campaign, tools

    return campaign.STEPS + tools.STEPS


@cache
def steps() -> tuple[Step, ...]:
    """Every step: the core's, then each installed family's (entry-point name order). A family's
    step named like another is refused in one line."""
    from calflow.family import families

    found = {s.name: s for s in core()}
    for fam in families():
        for s in fam.commands:
            if s.name in found:
                raise CalflowError(f"family {fam.name!r}: step {s.name!r}: expected a name no other step has")
            found[s.name] = s
    return tuple(found.values())


def step(name: str) -> Step:
    """The step ``calflow <name>`` runs; one line naming the known ones when there is none."""
    for s in steps():
        if s.name == name:
            return s
    raise CalflowError(
        f"calflow: no subcommand {name!r}; expected one of {', '.join(s.name for s in steps())}"
    )


def options_of(name: str) -> tuple[Option, ...]:
    """The options of core step ``name`` with those the installed families add to it
    (``Family.step_options``: the XYΘ family's ``--luts`` of ``calflow acquire``)."""
    from calflow.family import families

    return step(name).options + tuple(o for fam in families() for o in fam.step_options.get(name, ()))


def entry_points() -> dict[str, str]:
    """Step → the ``"module:function"`` it runs (what its rerun digest covers,
    :func:`calflow.provenance.code_digest`)."""
    return {s.name: s.run for s in steps()}


def entry_point(name: str) -> str:
    """``"module:function"`` that ``calflow <name>`` runs."""
    return step(name).run
