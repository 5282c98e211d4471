"""What the linear stage answers the core rules: two open-loop runs, one model, one scored run."""

from __future__ import annotations

from calflow.configuration import layout
from calflow.family_workflow import FamilyWorkflow


class LinearWorkflow(FamilyWorkflow):
    open_loop_runs = {"identification": "identification", "validation": "validation"}
    metrics_runs = "validation"

    def models(self, c) -> list[str]:
        return ["linear"]

    def results_of(self, c) -> list[str]:
        name = c["name"]
        return [
            layout.model(name, "linear"),
            layout.metrics(name, "validation"),
            layout.run(name, "validation"),
        ]

    def identify_inputs(self, c, model: str) -> dict[str, str]:
        return {"run": layout.run(c["name"], "identification")}

    def identify_sections(self, c, model: str) -> list:
        return ["identification"]


WORKFLOW = LinearWorkflow()
