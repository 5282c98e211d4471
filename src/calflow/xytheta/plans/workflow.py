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

from calflow.family_workflow import FamilyWorkflow, replayed_runs


class XYThetaWorkflow(FamilyWorkflow):
    open_loop_runs = {
        "identification": "identification",
        "characterisation_x": "characterisation",
        "characterisation_y": "characterisation",
    }
    metrics_runs = "validation_[A-Za-z0-9_]+|(square|random_points)_(none|linear|cubic)|interim_check"

    def models(self, c: dict) -> list[str]:
        return [] if "interim_check" in c else list(c["models"])

    def all_runs(self, c: dict) -> list[str]:
        """Every run a calibration acquires (its rig time): those of its summary, and the
        reference-target validation and export runs of each model."""
        base = f"results/{c['name']}"
        runs = {f for f in self.results_of(c) if f.startswith(f"{base}/runs/")}
        kinds = ("export",) if c["validation"].get("targets") == [] else ("validation", "export")
        runs.update(f"{base}/runs/{k}_{m}.nc" for m in self.models(c) for k in kinds)
        tests = c["xy_tests"]["compensation"]
        runs.update(f"{base}/runs/{t}_{k}.nc" for t in ("square", "random_points") for k in tests)
        return sorted(runs)

    def results_of(self, c: dict) -> list[str]:
        if "interim_check" in c:  # its run and metrics, and the reference's runs (resolved at load)
            base = f"results/{c['name']}"
            runs = c["interim_check"]["resolved"]["runs"]
            return [f"{base}/runs/interim_check.nc", f"{base}/metrics/interim_check.nc", *runs]
        base = f"results/{c['name']}"
        models = self.models(c)
        files = [f"{base}/models/{m}.nc" for m in models]
        if c["validation"].get("targets") != []:  # [] : held-out validation only
            files += [f"{base}/metrics/validation_{m}.nc" for m in models]
        files += [f"{base}/metrics/validation_heldout_{m}.nc" for m in models]
        files += [f"{base}/runs/validation_heldout_{m}.nc" for m in models]
        files.append(f"{base}/runs/identification.nc")
        files += [f"{base}/runs/angle_residuals_{s['base']}.nc" for s in c["models"].values() if "base" in s]
        if c["observability"]["study"]:
            files.append(f"{base}/metrics/observability.nc")
        if "design_study" in c:  # opt-in
            files.append(f"{base}/metrics/design_study.nc")
        tests = c["xy_tests"]["compensation"]
        if tests or any(spec.get("position_table") for spec in c["models"].values()):
            files.append(f"{base}/luts/position.nc")
            files += [f"{base}/runs/characterisation_{a}.nc" for a in "xy"]  # ISO 230-2
        files += [f"{base}/metrics/{t}_{k}.nc" for t in ("square", "random_points") for k in tests]
        if self.reads_images(c):  # the camera and decoder on the bench (report)
            files.append(f"{base}/metrics/instrument.nc")
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
        return [f"results/{c['name']}/metrics/export_{m}.nc" for m in models]

    def summary_truth(self, c: dict) -> str:
        if "interim_check" in c:
            return f"results/{c['name']}/truth/interim_check.json"
        return f"results/{c['name']}/truth/identification.json"

    def budget_files(self, c: dict) -> list[str]:
        """The error budget's replays: simulated rigs with ``validation.heldout.error_budget``,
        or that read their sensor through images (the replay with the noise-model sensor)."""
        if "interim_check" in c or c["rig"]["factory"] != "simulated":
            return []
        if not (c["validation"]["heldout"]["error_budget"] or self.reads_images(c)):
            return []
        return [f"results/{c['name']}/truth/error_budget.json"]

    def report_files(self, c: dict) -> list[str]:
        """The summary's files and the identification poses (the report's pose figure), and
        the decoder's throughput of an images rig (not in the summary: no two runs share it);
        an interim check has no identification."""
        if "interim_check" in c:
            return self.results_of(c)
        files = self.results_of(c) + [f"results/{c['name']}/runs/identification.nc"]
        if self.reads_images(c):  # the decoder's throughput on the machine that ran the bench
            files.append(f"results/{c['name']}/benchmarks/instrument_throughput.json")
        return files

    def acquire_inputs(self, c: dict, run: str) -> dict[str, str]:
        """The XY tables a designed identification plan reads for its discrepancy kernel."""
        if run != "identification":
            return {}
        d = c["identification"].get("design") or {}
        given = d.get("discrepancy") or {}
        if c["identification"].get("plan") != "optimal" or d.get("criterion") != "discrepancy":
            return {}
        if given.get("amplitude_um") is not None and given.get("length") is not None:
            return {}
        return {"luts": f"results/{c['name']}/luts/position.nc"}

    def identify_inputs(self, c: dict, model: str) -> dict[str, str]:
        base = f"results/{c['name']}"
        spec = c["models"][model]
        if "base" in spec:
            return {
                "base": f"{base}/models/{spec['base']}.nc",
                "residuals": f"{base}/runs/angle_residuals_{spec['base']}.nc",
                "run": f"{base}/runs/identification.nc",
            }
        inputs = {"run": f"{base}/runs/identification.nc"}
        if spec.get("position_table"):
            inputs["luts"] = f"{base}/luts/position.nc"
        return inputs

    def acquire_modules(self, c: dict) -> tuple[str, ...]:
        """The camera model and decoder when the simulated rig reads through images."""
        if self.reads_images(c):
            return (
                "calflow.instruments.pattern",
                "calflow.instruments.readings",
                "calflow.xytheta.stage.images",
            )
        return super().acquire_modules(c)

    def identify_sections(self, c: dict, model: str) -> list:
        spec = c["models"][model]
        sections = [c["seed"], c["identification"], spec]
        if "base" in spec:
            sections.append(c["angle_residuals"])
        return sections


WORKFLOW = XYThetaWorkflow()
