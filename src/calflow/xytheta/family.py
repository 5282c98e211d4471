"""What the XYΘ family registers with the core (:class:`calflow.family.Family`).

Plans by name, the simulated rig and vision sensor, the steps of the workflow and the
family's own subcommands. Kept free of numerical imports: it is read by ``calflow --help``.
"""

from __future__ import annotations

from calflow.family import Family
from calflow.step import CAMPAIGN, OUT, Option, Step

_P = "calflow.xytheta.plans.campaign"
_C = "calflow.xytheta.steps"
_S = "calflow.xytheta.studies.cli"


def rig_options(c: dict, factory: str, run_id: str, options: dict, start_s: float) -> dict:
    """Per-run rig options: the simulated rig draws its noise stream from (seed, run)."""
    if factory == "simulated":
        options.setdefault("seed", c["seed"])
        options["stream"] = run_id
    elif factory == "gcs":  # real stages; a simulated sensor gets its own noise per run
        sensor = dict(options.get("sensor") or {})
        if sensor.get("factory") == "simulated_vision":
            sensor["options"] = {"seed": c["seed"], **sensor.get("options", {}), "stream": run_id}
            options["sensor"] = sensor
        source = dict((sensor.get("options") or {}).get("source") or {})
        if sensor.get("factory") == "camera" and source.get("factory") == "simulated_camera":
            source["options"] = {"seed": c["seed"], **(source.get("options") or {}), "stream": run_id}
            options["sensor"] = {**sensor, "options": {**sensor["options"], "source": source}}
    return options


_CAMPAIGN = CAMPAIGN
_OUT = OUT

#: The options the family adds to the core's steps.
STEP_OPTIONS = {
    "acquire": (
        Option("--luts", "XY error tables for compensated square / random-points runs", "path"),
        Option(
            "--compensation",
            "lookup-table compensation of the square / random-points runs (Sec. 4.4.2)",
            default="none",
            choices=("none", "linear", "cubic"),
        ),
        Option("--export", "a model's export folder, for --plan validation_export (docs/export.md)", "path"),
    ),
    "identify": (
        Option("--luts", "XY error tables (models with position_table)", "path"),
        Option("--base", "base model (models with angle_table)", "path"),
        Option("--residuals", "angle-residual run commanded through the base model", "path"),
    ),
}

_STUDY = (
    Option("--study", "study file, config/studies/<name>.yaml", "path", required=True),
    Option("--campaign-dir", "folder of the base campaign file", "path", default="config/campaigns"),
)

# fmt: off
COMMANDS = (
    Step(
        "characterise",
        "XY error tables from the characterisation sweeps (Sec. 4.4.1)",
        f"{_C}:characterise",
        (_CAMPAIGN, Option("--x", required=True, kind="path"), Option("--y", required=True, kind="path"), _OUT),
        inputs=("run",),
        writes=("luts",),
    ),
    Step(
        "observability",
        "observability indices against the number of poses (Fig. 4.21)",
        f"{_C}:observability",
        (_CAMPAIGN, _OUT),
        reads=("seed", "identification", "observability"),
        writes=("metrics",),
    ),
    Step(
        "error-budget",
        "replay the calibration with each rig effect off: the error budget (simulated rigs)",
        "calflow.xytheta.stage.error_budget:error_budget_command",
        (_CAMPAIGN, Option("--jobs", "replays run in parallel (processes)", "int", default=1), _OUT),
        reads=(
            "seed", "rig", "characterisation", "identification", "angle_residuals", "models",
            "validation.heldout", "validation.dwell_s",
        ),
        writes=("truth",),
    ),
    Step(
        "instrument-bench",
        "the camera and decoder of a rig that reads through images, on rendered frames (report)",
        "calflow.xytheta.stage.bench:bench_command",
        (_CAMPAIGN, _OUT, Option("--throughput", "where to write the decoder's throughput on this machine (JSON)", "path")),
        reads=("rig", "seed", "identification.theta_deg"),
        writes=("metrics", "campaign"),
    ),
    Step(
        "design-study",
        "Cramér–Rao σ against poses and rig time, random against designed",
        "calflow.xytheta.design.study:study",
        (_CAMPAIGN, _OUT),
        reads=("seed", "rig", "identification", "models", "design_study"),
        writes=("metrics",),
    ),
    Step(
        "export",
        "a model's controller files and bundle for users' code (docs/export.md)",
        "calflow.xytheta.export.command:export",
        (
            _CAMPAIGN,
            Option("--model", "model files, results/<campaign>/models/<model>.nc", "path", required=True, many="+"),
            Option("--out", "folder of the exports; each model's in <out>/<model file's stem>", "path", required=True),
        ),
        inputs=("model",),
        writes=("campaign",),
    ),
    Step(
        "export-verify",
        "accuracy through the exported files beside the in-process model's",
        "calflow.xytheta.export.command:verify",
        (
            _CAMPAIGN,
            Option("--run", "validation_export runs", "path", required=True, many="+"),
            Option("--heldout", "metrics of the models' in-process held-out runs", "path", required=True, many="+"),
            Option("--out", "one metrics file per --run, in the same order", "path", required=True, many="+"),
        ),
        inputs=("run", "metrics"),
        writes=("metrics",),
    ),
    Step(
        "mc-point",
        "one simulated campaign of a Monte-Carlo study (seed × noise × poses)",
        f"{_S}:point",
        (
            *_STUDY,
            Option("--seed", "seed N, or seeds FIRST-LAST run in this one job", required=True),
            Option("--noise", "sensor noise, one of the study's noise_um", required=True, units="um"),
            Option("--poses", "number of identification poses, one of the study's", "int", required=True),
            Option("--off-grid", "allow noise/poses outside the study's grid", "flag"),
            _OUT,
        ),
        writes=("study_point",),
    ),
    Step(
        "mc-aggregate",
        "aggregate the points of a Monte-Carlo study",
        f"{_S}:aggregate",
        (
            *_STUDY,
            Option("--points", required=True, kind="path", many="+"),
            Option("--partial", "allow missing grid points", "flag"),
            _OUT,
        ),
        inputs=("study_point",),
        writes=("study",),
    ),
    Step(
        "mc-report",
        "render the page of a Monte-Carlo study",
        f"{_S}:page",
        (*_STUDY, Option("--aggregate", required=True, kind="path"), _OUT),
        inputs=("study",),
        writes=("study_page",),
    ),
)
# fmt: on


FAMILY = Family(
    name="xytheta",
    robots=("xytheta",),
    rigs={"xytheta": {"simulated": "calflow.xytheta.stage.rig:simulated_xytheta"}},
    plans={
        "xytheta": {
            name: f"{_P}:{name}"
            for name in (
                "identification",
                "validation",
                "validation_heldout",
                "characterisation_x",
                "characterisation_y",
                "angle_residuals",
                "square",
                "random_points",
            )
        }
        | {
            "validation_export": "calflow.xytheta.export.verification:validation_export",
            "interim_check": "calflow.xytheta.plans.interim:interim_check",
            "as_found": "calflow.xytheta.plans.as_found:as_found",
        }
    },
    rig_options="calflow.xytheta.family:rig_options",
    steps={
        "identify": f"{_C}:identify",
        "metrics": f"{_C}:metrics",
        "summarise": "calflow.xytheta.report.summary:summarise",
        "figures": "calflow.xytheta.report.figures:figures",
        "check": "calflow.xytheta.checks:check",
    },
    templates="calflow.xytheta.report",
    schemas="calflow.xytheta",
    history_entry="calflow.xytheta.report.history:history_entry",
    step_options=STEP_OPTIONS,
    commands=COMMANDS,
    sensors={  # of the gcs rig; simulated_camera is a frame source of its camera sensor (gcs.camera)
        "simulated_vision": "calflow.xytheta.stage.vision_sensor:simulated_vision",
        "simulated_camera": "calflow.xytheta.stage.vision_sensor:simulated_camera",
    },
    options={
        "calflow.xytheta.stage.rig:simulated_xytheta": "calflow.xytheta.stage.physics:check_options",
        "calflow.xytheta.stage.vision_sensor:simulated_vision": "calflow.xytheta.stage.physics:check_options",
    },
    emulator="calflow.xytheta.stage.emulate:EMULATOR",
    joints={"xytheta": ("x", "y", "theta")},
    reference={"thesis-ch4": "calflow.xytheta.report.reference:XYTHETA"},
    headline="calflow.xytheta.report.headline:headline",
    index_row="xytheta_index_row.html.j2",
    uncertainty="calflow.xytheta.report.certificate:measurements",
    # the figures a stage's specification may name: True when calflow gives their U
    certified={
        "xytheta": {
            **dict.fromkeys(
                ("accuracy_um", "repeatability_um", "E_um", "A_um", "B_um", "M_um", "R_um"), True
            ),
            "cv_rms_um": False,
        }
    },
    summary_sections={
        "model": "models",
        "metrics:validation": "reference_targets",
        "metrics:validation_heldout": "heldout",
        "metrics:square": "xy_tests",
        "metrics:random_points": "xy_tests",
        "metrics:observability": "observability",
        "metrics:design_study": "design_study",
        "metrics:validation_export": "export",
        "metrics:as_found": "as_found",
        "run:as_found": "as_found_runs",
        "metrics:instrument": "instrument",
        "luts": "characterisation",
        "run:characterisation_x": "iso230_2",
        "run:characterisation_y": "iso230_2",
        "run:validation_heldout": "heldout_runs",
        "run:identification": "training_runs",
        "run:angle_residuals": "training_runs",
    },
    rules=(
        "calflow.xytheta",
        "rules/common.smk",
        "rules/acquire.smk",
        "rules/characterise.smk",
        "rules/validation.smk",
        "rules/export.smk",
        "rules/interim.smk",
        "rules/as_found.smk",
        "rules/montecarlo.smk",
    ),
    workflow="calflow.xytheta.plans.workflow:WORKFLOW",
    studies="calflow.xytheta.studies.montecarlo:load_study",
)
