"""What the nanopositioning family registers with the core (:class:`calflow.family.Family`).

Plans by name for the 1-DoF (``stage1d``) and 2-DoF (``stage2d``) stages, their simulated
rigs and the steps of the workflow. Kept free of numerical imports: it is read by
``calflow --help``.
"""

from __future__ import annotations

import zlib

from calflow.family import Family

_P = "calflow.nano.campaign_plans"
_C = "calflow.nano.commands"


def rig_options(c: dict, factory: str, run_id: str, options: dict, start_s: float) -> dict:
    """Per-run rig options of the simulated stages: one world (room, slow drift) per
    campaign, independent noise per run, and the run's start in campaign time."""
    if factory == "simulated":
        options.setdefault("world_seed", c["seed"])
        options["seed"] = zlib.crc32(f"{c['seed']}:{run_id}".encode())
        options["start_offset_s"] = start_s
    elif factory == "gcs" and (options.get("sensor") or {}).get("factory") == "simulated_interferometer":
        sensor = dict(options["sensor"])  # the world behind the emulated controller: same rule
        sensor["options"] = {"world_seed": c["seed"], **(sensor.get("options") or {}),
                             "seed": zlib.crc32(f"{c['seed']}:{run_id}:gcs".encode()),
                             "start_offset_s": start_s}
        options["sensor"] = sensor
    return options


_CORE = ("calflow.data", "calflow.config", "calflow.commands", "calflow.plan", "calflow.family")
_MODELS = ("calflow.nano.model", "calflow.nano.models", "calflow.nano.thermal_model", "calflow.nano.kmz",
           "calflow.stepwise")

FAMILY = Family(
    name="nano",
    robots=("stage1d", "stage2d"),
    rigs={"stage1d": {"simulated": "calflow.nano.rig:nano1d"}, "stage2d": {"simulated": "calflow.nano.rig:nano2d"}},
    plans={
        "stage1d": {"training": f"{_P}:training_1d", "metrology": f"{_P}:metrology_1d",
                    "validation": f"{_P}:validation_1d", "step_response": f"{_P}:step_response"},
        "stage2d": {"training": f"{_P}:training_2d", "validation": f"{_P}:validation_2d",
                    "step_response": f"{_P}:step_response"},
    },
    rig_options="calflow.nano.family:rig_options",
    steps={
        "identify": f"{_C}:identify",
        "metrics": f"{_C}:metrics",
        "summarise": f"{_C}:summarise",
        "figures": "calflow.nano.figures:build",
    },
    templates="calflow.nano",
    sensors={"simulated_interferometer": "calflow.nano.interferometer_sensor:simulated_interferometer"},
    emulator="calflow.nano.emulate:main",
    modules={
        "acquire": _CORE + _MODELS + ("calflow.acquisition", "calflow.rigs", "calflow.gcs", "calflow.nano.plans",
                                      "calflow.nano.campaign_plans", "calflow.identification.design",
                                      "calflow.nano.design", "calflow.nano.design_plan", "calflow.nano.rig", "calflow.nano.rig_options",
                                      "calflow.nano.rig_records",
                                      "calflow.nano.piezo", "calflow.nano.interferometer", "calflow.nano.thermal_network",
                                      "calflow.nano.controllers", "calflow.nano.family",
                                      "calflow.nano.interferometer_sensor"),
        "identify": _CORE + _MODELS + ("calflow.nano.commands",),
        "metrics": _CORE + ("calflow.metrics", "calflow.nano.evaluation", "calflow.nano.commands"),
        "summarise": _CORE + _MODELS + ("calflow.reference", "calflow.uncertainty", "calflow.metrics",
                                        "calflow.nano.evaluation", "calflow.nano.summary", "calflow.nano.commands",
                                        "calflow.nano.error_budget", "calflow.nano.ordering", "calflow.nano.rig",
                                        "calflow.nano.rig_records", "calflow.nano.stabilisation_summary",
                                        "calflow.nano.iso9283_summary", "calflow.identification.design",
                                        "calflow.nano.design", "calflow.nano.design_plan", "calflow.nano.plans",
                                        "calflow.nano.rig_options", "calflow.nano.piezo", "calflow.nano.interferometer",
                                        "calflow.nano.thermal_network", "calflow.rigs"),
        "report": _CORE + ("calflow.report", "calflow.nano.figures", "calflow.nano.templates"),
    },
)
