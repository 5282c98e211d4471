"""What the XYΘ family answers the core Snakemake rules (:class:`calflow.family_workflow.FamilyWorkflow`).

The XYΘ step graph (Ch. 4): characterisation sweeps → XY tables (Sec. 4.4.1);
identification run → Models I–V (Sec. 4.5), Models IV/V from an angle-residual run on their
base model; validation through each model on reference and held-out targets; the square and
random-points tests with and without table compensation (Sec. 4.4.2); the export of each
model and its closed-loop check. The rules of the steps the core does not have are in this
family's ``rules/`` files.

An interim-check campaign (key ``interim_check``) has another graph: its run through the
reference calibration's exported bundle (``rules/interim.smk``) → its metrics → the summary
with the SPRT decision (reading the reference's export check and runs) → the report; it
identifies no model.
"""

from __future__ import annotations

from calflow.configuration import layout
from calflow.family_workflow import FamilyWorkflow, replayed_runs


class XYThetaWorkflow(FamilyWorkflow):
    open_loop_runs = {
        # the plan records the Cramér-Rao bound of each model's parameters
        "identification": ("identification", "models"),
        "characterisation_x": "characterisation",
        "characterisation_y": "characterisation",
    }
    metrics_runs = (
        "validation_[A-Za-z0-9_]+|(square|random_points)_(none|linear|cubic)|interim_check|as_found"
    )

    def models(self, c: dict) -> list[str]:
        return [] if "interim_check" in c else list(c["models"])

    def all_runs(self, c: dict) -> list[str]:
        """Every run a calibration acquires (its rig time): those of its summary, and the
        reference-target validation and export runs of each model."""
        name = c["name"]
        runs = {f for f in self.results_of(c) if f.startswith(layout.campaign(name, "runs") + "/")}
        kinds = ("export",) if c["validation"].get("targets") == [] else ("validation", "export")
        runs.update(layout.run(name, f"{k}_{m}") for m in self.models(c) for k in kinds)
        tests = c["xy_tests"]["compensation"]
        runs.update(layout.run(name, f"{t}_{k}") for t in ("square", "random_points") for k in tests)
        return sorted(runs)

    def needs(self, c: dict) -> list[tuple[str, str, list[str]]]:
        """An interim check reads its reference's export (the bundle it runs), the export's
        closed-loop check (its H0) and the reference's runs (its rig time); a recalibration
        measured as found, the export of the calibration whose compensation the stage ran."""
        if c.get("as_found"):  # a recalibration measured through the bundle in use
            return [("as_found.reference", c["as_found"]["reference"], [as_found_export(c)])]
        if "interim_check" not in c:
            return []
        check = c["interim_check"]
        ref = check["reference"]
        files = [interim_export(c), interim_reference_run(c), *check["resolved"]["runs"]]
        return [("interim_check.reference", ref, list(dict.fromkeys(files)))]

    def results_of(self, c: dict) -> list[str]:
        if "interim_check" in c:  # its run and metrics, and the reference's runs (resolved at load)
            name, runs = c["name"], c["interim_check"]["resolved"]["runs"]
            return [layout.run(name, "interim_check"), layout.metrics(name, "interim_check"), *runs]
        name, models = c["name"], self.models(c)
        files = [layout.model(name, m) for m in models]
        if c["validation"].get("targets") != []:  # [] : held-out validation only
            files += [layout.metrics(name, f"validation_{m}") for m in models]
        files += [layout.metrics(name, f"validation_heldout_{m}") for m in models]
        files += [layout.run(name, f"validation_heldout_{m}") for m in models]
        files.append(layout.run(name, "identification"))
        files += [
            layout.run(name, f"angle_residuals_{s['base']}") for s in c["models"].values() if "base" in s
        ]
        if c["observability"]["study"]:
            files.append(layout.metrics(name, "observability"))
        if "design_study" in c:  # opt-in
            files.append(layout.metrics(name, "design_study"))
        tests = c["xy_tests"]["compensation"]
        if tests or any(spec.get("position_table") for spec in c["models"].values()):
            files.append(layout.luts(name))
            files += [layout.run(name, f"characterisation_{a}") for a in "xy"]  # ISO 230-2
        files += [layout.metrics(name, f"{t}_{k}") for t in ("square", "random_points") for k in tests]
        if c.get("as_found"):  # the compensation in use, before the recalibration (plans/as_found.py)
            files += [layout.run(name, "as_found"), layout.metrics(name, "as_found")]
        if self.reads_images(c):  # the camera and decoder on the bench (report)
            files.append(layout.metrics(name, "instrument"))
        return files + self.export_results(c)

    @staticmethod
    def reads_images(c: dict) -> bool:
        """The simulated rig reads its vision sensor through rendered frames (stage.images)."""
        return (
            c["rig"]["factory"] == "simulated" and (c["rig"].get("options") or {}).get("sensor") == "images"
        )

    def export_results(self, c: dict) -> list[str]:
        """The export metrics the summary draws on: every model; on a replayed rig, those whose
        export run was recorded (run id ``export_<model>``)."""
        models = self.models(c)
        if c["rig"]["factory"] == "replay":
            recorded = replayed_runs(c)
            models = [m for m in models if f"export_{m}" in recorded]
        return [layout.metrics(c["name"], f"export_{m}") for m in models]

    def summary_truth(self, c: dict) -> str:
        if "interim_check" in c:
            return layout.truth(c["name"], "interim_check")
        return layout.truth(c["name"], "identification")

    def budget_files(self, c: dict) -> list[str]:
        """The error budget's replays: simulated rigs with ``validation.heldout.error_budget``,
        or that read their sensor through images (the replay with the noise-model sensor)."""
        if "interim_check" in c or c["rig"]["factory"] != "simulated":
            return []
        if not (c["validation"]["heldout"]["error_budget"] or self.reads_images(c)):
            return []
        return [layout.truth(c["name"], "error_budget")]

    def report_files(self, c: dict) -> list[str]:
        """The summary's files and the identification poses (the report's pose figure), and
        the decoder's throughput of an images rig (not in the summary: no two runs share it);
        an interim check has no identification."""
        if "interim_check" in c:
            return self.results_of(c)
        files = self.results_of(c) + [layout.run(c["name"], "identification")]
        if self.reads_images(c):  # the decoder's throughput on the machine that ran the bench
            files.append(layout.campaign(c["name"], "benchmarks", "instrument_throughput.json"))
        return files

    def acquire_inputs(self, c: dict, run: str) -> dict[str, str]:
        """The XY tables a designed identification plan reads for its discrepancy kernel (the
        as-found run goes first by its rule's priority, not as an input: the open-loop runs
        do not read it)."""
        return self._luts(c, run)

    def _luts(self, c: dict, run: str) -> dict[str, str]:
        if run != "identification":
            return {}
        d = c["identification"].get("design") or {}
        given = d.get("discrepancy") or {}
        if c["identification"].get("plan") != "optimal" or d.get("criterion") != "discrepancy":
            return {}
        if given.get("amplitude_um") is not None and given.get("length") is not None:
            return {}
        return {"luts": layout.luts(c["name"])}

    def identify_inputs(self, c: dict, model: str) -> dict[str, str]:
        name, spec = c["name"], c["models"][model]
        if "base" in spec:
            return {
                "base": layout.model(name, spec["base"]),
                "residuals": layout.run(name, f"angle_residuals_{spec['base']}"),
                "run": layout.run(name, "identification"),
            }
        inputs = {"run": layout.run(name, "identification")}
        if spec.get("position_table"):
            inputs["luts"] = layout.luts(name)
        return inputs

    def identify_sections(self, c: dict, model: str) -> list:
        return ["seed", "identification", f"models.{model}"] + (
            ["angle_residuals"] if "base" in c["models"][model] else []
        )


def interim_export(c: dict) -> str:
    """An interim check's bundle: its reference's export manifest."""
    return layout.campaign(c["interim_check"]["reference"], "export", "manifest.json")


def as_found_export(c: dict) -> str:
    """The export manifest of the calibration whose compensation the stage ran (``as_found``)."""
    return layout.campaign(c["as_found"]["reference"], "export", "manifest.json")


def interim_reference_run(c: dict) -> str:
    """An interim check's H0: the reference's closed-loop check of the model's bundle."""
    check = c["interim_check"]
    return layout.run(check["reference"], f"export_{check['model']}")


WORKFLOW = XYThetaWorkflow()
