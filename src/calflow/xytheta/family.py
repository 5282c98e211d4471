"""What the XYΘ family registers with the core (:class:`calflow.family.Family`).

Plans by name, the simulated rig and vision sensor, the steps of the workflow and the
family's own subcommands. Kept free of numerical imports: it is read by ``calflow --help``.
"""

from __future__ import annotations

import argparse

from calflow.family import Command, Family

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


def _acquire_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--luts", help="XY error tables for compensated square / random-points runs")
    p.add_argument(
        "--compensation",
        choices=["none", "linear", "cubic"],
        default="none",
        help="lookup-table compensation of the square / random-points runs (Sec. 4.4.2)",
    )
    p.add_argument("--export", help="a model's export folder, for --plan validation_export (docs/export.md)")


def _identify_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--luts", help="XY error tables (models with position_table)")
    p.add_argument("--base", help="base model (models with angle_table)")
    p.add_argument("--residuals", help="angle-residual run commanded through the base model")


def _characterise_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--campaign", required=True)
    p.add_argument("--x", required=True)
    p.add_argument("--y", required=True)
    p.add_argument("--out", required=True)


def _observability_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--campaign", required=True)
    p.add_argument("--out", required=True)


def _bench_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--campaign", required=True)
    p.add_argument("--out", required=True)
    p.add_argument("--throughput", help="where to write the decoder's throughput on this machine (JSON)")


def _budget_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--campaign", required=True)
    p.add_argument("--jobs", type=int, default=1, help="replays run in parallel (processes)")
    p.add_argument("--out", required=True)


def _export_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--campaign", required=True)
    p.add_argument(
        "--model", nargs="+", required=True, help="model files, results/<campaign>/models/<model>.nc"
    )
    p.add_argument(
        "--out", required=True, help="folder of the exports; each model's in <out>/<model file's stem>"
    )


def _export_verify_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--campaign", required=True)
    p.add_argument("--run", nargs="+", required=True, help="validation_export runs")
    p.add_argument(
        "--heldout", nargs="+", required=True, help="metrics of the models' in-process held-out runs"
    )
    p.add_argument("--out", nargs="+", required=True, help="one metrics file per --run, in the same order")


def _study(p: argparse.ArgumentParser) -> None:
    p.add_argument("--study", required=True, help="study file, config/studies/<name>.yaml")
    p.add_argument("--campaign-dir", default="config/campaigns", help="folder of the base campaign file")


def _point_arguments(p: argparse.ArgumentParser) -> None:
    _study(p)
    p.add_argument("--seed", required=True, help="seed N, or seeds FIRST-LAST run in this one job")
    p.add_argument("--noise", required=True, help="sensor noise (um), one of the study's noise_um")
    p.add_argument(
        "--poses", type=int, required=True, help="number of identification poses, one of the study's"
    )
    p.add_argument("--off-grid", action="store_true", help="allow noise/poses outside the study's grid")
    p.add_argument("--out", required=True)


def _aggregate_arguments(p: argparse.ArgumentParser) -> None:
    _study(p)
    p.add_argument("--points", nargs="+", required=True)
    p.add_argument("--partial", action="store_true", help="allow missing grid points")
    p.add_argument("--out", required=True)


def _page_arguments(p: argparse.ArgumentParser) -> None:
    _study(p)
    p.add_argument("--aggregate", required=True)
    p.add_argument("--out", required=True)


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
    acquire_arguments=_acquire_arguments,
    identify_arguments=_identify_arguments,
    commands=(
        Command(
            "characterise",
            "XY error tables from the characterisation sweeps (Sec. 4.4.1)",
            _characterise_arguments,
            f"{_C}:characterise",
        ),
        Command(
            "observability",
            "observability indices against the number of poses (Fig. 4.21)",
            _observability_arguments,
            f"{_C}:observability",
        ),
        Command(
            "error-budget",
            "replay the calibration with each rig effect off: the error budget (simulated rigs)",
            _budget_arguments,
            "calflow.xytheta.stage.error_budget:error_budget_command",
        ),
        Command(
            "instrument-bench",
            "the camera and decoder of a rig that reads through images, on rendered frames (report)",
            _bench_arguments,
            "calflow.xytheta.stage.bench:bench_command",
        ),
        Command(
            "design-study",
            "Cramér–Rao σ against poses and rig time, random against designed",
            _observability_arguments,
            "calflow.xytheta.design.study:study",
        ),
        Command(
            "export",
            "a model's controller files and bundle for users' code (docs/export.md)",
            _export_arguments,
            "calflow.xytheta.export.command:export",
        ),
        Command(
            "export-verify",
            "accuracy through the exported files beside the in-process model's",
            _export_verify_arguments,
            "calflow.xytheta.export.command:verify",
        ),
        Command(
            "mc-point",
            "one simulated campaign of a Monte-Carlo study (seed × noise × poses)",
            _point_arguments,
            f"{_S}:point",
        ),
        Command(
            "mc-aggregate",
            "aggregate the points of a Monte-Carlo study",
            _aggregate_arguments,
            f"{_S}:aggregate",
        ),
        Command("mc-report", "render the page of a Monte-Carlo study", _page_arguments, f"{_S}:page"),
    ),
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
