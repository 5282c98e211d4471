"""The linear stage's registration (:class:`calflow.family.Family`): light, no numerical import."""

from __future__ import annotations

from calflow.family import Family


def rig_options(c, factory, run_id, options, start_s):
    """Per-run rig options: the simulated stage's noise drawn from (seed, run)."""
    if factory == "simulated":
        options.setdefault("seed", c["seed"])
        options["stream"] = run_id
    return options


FAMILY = Family(
    name="linear",
    robots=("linear1d",),
    joints={"linear1d": ("x",)},
    rigs={"linear1d": {"simulated": "toystage.stage:linear_stage"}},
    options={"toystage.stage:linear_stage": "toystage.stage:check_options"},
    plans={
        "linear1d": {
            "identification": "toystage.plans:identification",
            "validation": "toystage.plans:validation",
        }
    },
    rig_options="toystage.family:rig_options",
    steps={
        "check": "toystage.steps:check",
        "identify": "toystage.steps:identify",
        "metrics": "toystage.steps:metrics",
        "summarise": "toystage.steps:summarise",
        "figures": "toystage.steps:figures",
    },
    templates="toystage",
    schemas="toystage",
    headline="toystage.steps:headline",
    summary_sections={"model": "models", "metrics": "metrics", "run": "runs"},
    workflow="toystage.workflow:WORKFLOW",
)
