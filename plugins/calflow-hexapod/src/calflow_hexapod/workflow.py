"""What the hexapod family answers calflow's core rules (:class:`calflow.family_workflow.FamilyWorkflow`).

The hexapod's step graph: an identification run (random or designed poses, the core's
``acquire`` rule) → each model of the ladder (``models``: nominal, offsets, geometric, scale,
thermal; the core's ``identify`` rule) → held-out validation through each model's inverse on
targets no identification saw (the core's ``validation_heldout`` rule) and, when the campaign
has an ``iso9283`` section, the five ISO 9283 poses through each model (this package's
``rules/hexapod.smk``) → the metrics of each (ISO 9283 AP/RP for position and orientation);
each model exported as a bundle and the held-out targets commanded again through the bundle's
Compensator (``rules/hexapod.smk``, run ``closed_loop_<model>``) → the summary and the report.
"""

from __future__ import annotations

from calflow.configuration import layout
from calflow.family_workflow import FamilyWorkflow


class HexapodWorkflow(FamilyWorkflow):
    # a designed plan is designed for a model's free parameters
    open_loop_runs = {"identification": ("identification", "models")}
    metrics_runs = "validation_heldout_[A-Za-z0-9_]+|iso9283_[A-Za-z0-9_]+|closed_loop_[A-Za-z0-9_]+"

    def models(self, c: dict) -> list[str]:
        return list(c["models"])

    def results_of(self, c: dict) -> list[str]:
        name, models = c["name"], self.models(c)
        files = [layout.model(name, m) for m in models]
        files += [layout.metrics(name, f"validation_heldout_{m}") for m in models]
        files += [layout.run(name, f"validation_heldout_{m}") for m in models]  # the U of AP, RP
        files += [layout.metrics(name, f"closed_loop_{m}") for m in models]
        if "iso9283" in c:
            files += [layout.metrics(name, f"iso9283_{m}") for m in models]
        files.append(layout.run(name, "identification"))
        return files

    def budget_files(self, c: dict) -> list[str]:
        """The error budget's replays: simulated rigs with ``validation.heldout.error_budget``."""
        if c["rig"]["factory"] != "simulated" or not c["validation"]["heldout"].get("error_budget"):
            return []
        return [layout.truth(c["name"], "hexapod_error_budget")]

    def identify_inputs(self, c: dict, model: str) -> dict[str, str]:
        return {"run": layout.run(c["name"], "identification")}

    def identify_sections(self, c: dict, model: str) -> list:
        # a designed plan's poses are weighed by the noise of a reading, which the simulated
        # rig's tracker gives unless identification.design.noise does
        return ["seed", "identification", f"models.{model}", "rig"]


WORKFLOW = HexapodWorkflow()
