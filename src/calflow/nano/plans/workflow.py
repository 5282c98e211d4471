"""What the nanopositioning family answers the core Snakemake rules
(:class:`calflow.family_workflow.FamilyWorkflow`).

The nano step graph (Ch. 5): a training run → the stage's models (Sec. 5.2); a validation
run through every model; on the 1-DoF stage a metrology-room run (intrinsic accuracy); a
step-response run when enabled (ISO 9283 stabilisation). A replay campaign with
recordings analyses the runs it has recordings of. The validation and step-response rules
are in this family's ``rules/`` files.
"""

from __future__ import annotations

from calflow.configuration import layout
from calflow.family_workflow import FamilyWorkflow, recorded_runs


class NanoWorkflow(FamilyWorkflow):
    # the training plan records the Cramér-Rao bound of the model's parameters
    open_loop_runs = {"training": ("training", "model"), "metrology": "metrology"}
    metrics_runs = "validation|training|metrology"

    def models(self, c: dict) -> list[str]:
        return ["single", "adaptive_kmz"] if c["robot"] == "stage1d" else ["two_dof"]

    def results_of(self, c: dict) -> list[str]:
        name = c["name"]
        recorded = recorded_runs(c)

        def has(run: str) -> bool:
            return recorded is None or run in recorded

        files = []
        if has("training"):
            files += [layout.model(name, m) for m in self.models(c)]
            files += [layout.metrics(name, "training"), layout.run(name, "training")]
        if has("validation"):
            files.append(layout.metrics(name, "validation"))
            files.append(
                layout.run(name, "validation")
            )  # ISO 9283 vAP, AD/RD, drift; the error budget replays it
        if c["robot"] == "stage1d" and has("metrology"):
            files.append(layout.metrics(name, "metrology"))
            if not has("training"):  # the ISO 230-2 figures then come from the metrology run
                files.append(layout.run(name, "metrology"))
        if c["step_response"]["enabled"] and has("step_response"):  # ISO 9283 stabilisation time, overshoot
            files.append(layout.run(name, "step_response"))
        return files

    def summary_truth(self, c: dict) -> str | list[str]:
        """The validation run's truth, when the campaign has a validation run."""
        recorded = recorded_runs(c)
        if recorded is not None and "validation" not in recorded:
            return []
        return layout.truth(c["name"], "validation")

    def identify_inputs(self, c: dict, model: str) -> dict[str, str]:
        return {"run": layout.run(c["name"], "training")}

    def identify_sections(self, c: dict, model: str) -> list:
        return ["model"]


WORKFLOW = NanoWorkflow()
