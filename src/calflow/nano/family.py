"""What the nanopositioning family registers with the core (:class:`calflow.family.Family`).

Plans by name for the 1-DoF (``stage1d``) and 2-DoF (``stage2d``) stages, their simulated
rigs and the steps of the workflow. Kept free of numerical imports: it is read by
``calflow --help``.
"""

from __future__ import annotations

import zlib

from calflow.family import Family

_P = "calflow.nano.plans.campaign"
_C = "calflow.nano.steps"


def rig_options(c: dict, factory: str, run_id: str, options: dict, start_s: float) -> dict:
    """Per-run rig options of the simulated stages: one world (room, slow drift) per
    campaign, independent noise per run, and the run's start in campaign time."""
    if factory == "simulated":
        options.setdefault("world_seed", c["seed"])
        options["seed"] = zlib.crc32(f"{c['seed']}:{run_id}".encode())
        options["start_offset_s"] = start_s
    elif factory == "gcs" and (options.get("sensor") or {}).get("factory") == "simulated_interferometer":
        sensor = dict(options["sensor"])  # the world behind the emulated controller: same rule
        sensor["options"] = {
            "world_seed": c["seed"],
            **(sensor.get("options") or {}),
            "seed": zlib.crc32(f"{c['seed']}:{run_id}:gcs".encode()),
            "start_offset_s": start_s,
        }
        options["sensor"] = sensor
    return options


FAMILY = Family(
    name="nano",
    robots=("stage1d", "stage2d"),
    rigs={
        "stage1d": {"simulated": "calflow.nano.stage.rig:nano1d"},
        "stage2d": {"simulated": "calflow.nano.stage.rig:nano2d"},
    },
    plans={
        "stage1d": {
            "training": f"{_P}:training_1d",
            "metrology": f"{_P}:metrology_1d",
            "validation": f"{_P}:validation_1d",
            "step_response": f"{_P}:step_response",
        },
        "stage2d": {
            "training": f"{_P}:training_2d",
            "validation": f"{_P}:validation_2d",
            "step_response": f"{_P}:step_response",
        },
    },
    rig_options="calflow.nano.family:rig_options",
    steps={
        "identify": f"{_C}:identify",
        "metrics": f"{_C}:metrics",
        "summarise": f"{_C}:summarise",
        "figures": "calflow.nano.report.figures:figures",
        "check": "calflow.nano.checks:check",
    },
    templates="calflow.nano.report",
    schemas="calflow.nano",
    sensors={"simulated_interferometer": "calflow.nano.stage.interferometer_sensor:simulated_interferometer"},
    options={
        "calflow.nano.stage.rig:nano1d": "calflow.nano.stage.rig:check_nano1d",
        "calflow.nano.stage.rig:nano2d": "calflow.nano.stage.rig:check_nano2d",
        "calflow.nano.stage.interferometer_sensor:simulated_interferometer": (
            "calflow.nano.stage.interferometer_sensor:check_sensor_options"
        ),
    },
    emulator="calflow.nano.stage.emulate:EMULATOR",
    joints={"stage1d": ("x",), "stage2d": ("x", "y")},
    reference={
        "thesis-sec5.3": "calflow.nano.report.reference:STAGE1D",
        "thesis-sec5.4": "calflow.nano.report.reference:STAGE2D",
    },
    headline="calflow.nano.report.headline:headline",
    modes={
        "no_calibration": "no calibration",
        "adaptive_kmz": "adaptive model (KMZ)",
        "single": "single model",
    },
    index_row="nano_index_row.html.j2",
    summary_sections={"metrics": "metrics", "model": "models", "run": "runs"},
    uncertainty="calflow.nano.certificate:measurements",
    # the figures a stage's specification may name: True when calflow gives their U
    certified={
        "stage1d": {
            **dict.fromkeys(
                ("accuracy_nm", "repeatability_nm", "E_nm", "A_nm", "B_nm", "M_nm", "R_nm"), True
            ),
            "max_accuracy_nm": False,
        },
        "stage2d": {"max_accuracy_nm": False},
    },
    rules=("calflow.nano", "rules/step_response.smk", "rules/validation.smk"),
    workflow="calflow.nano.plans.workflow:WORKFLOW",
    history_entry="calflow.nano.report.history:history_entry",
)
