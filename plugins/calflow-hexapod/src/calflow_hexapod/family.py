"""What the hexapod family registers with calflow (:class:`calflow.family.Family`).

Registered by this distribution's entry point (``[project.entry-points."calflow.families"]``
``hexapod = "calflow_hexapod.family:FAMILY"``); calflow's core never names it. Kept free of
numerical imports: ``calflow --help`` reads it.
"""

from __future__ import annotations

from calflow.family import Family
from calflow.step import CAMPAIGN, OUT, Option, Step

_P = "calflow_hexapod.plans.campaign"
_S = "calflow_hexapod.steps"


_CAMPAIGN = CAMPAIGN

#: This family's own steps (``calflow hexapod-export``, ``calflow hexapod-error-budget``).
COMMANDS = (
    Step(
        "hexapod-export",
        "a hexapod model's identified geometry as a bundle for users' code (bundle.json, geometry.nc)",
        "calflow_hexapod.export.verification:export_command",
        (
            _CAMPAIGN,
            Option("--model", "an identified hexapod model (models/M.nc)", "path", required=True),
            Option("--out", "the model's export folder (bundle.json is written last)", "path", required=True),
        ),
        inputs=("model",),
        writes=("campaign",),
    ),
    Step(
        "hexapod-error-budget",
        "replay a simulated hexapod's calibration with each rig effect off: the error budget",
        "calflow_hexapod.stage.error_budget:error_budget_command",
        (_CAMPAIGN, OUT),
        reads=("seed", "rig", "identification", "models", "validation"),
        writes=("truth",),
    ),
)


FAMILY = Family(
    name="hexapod",
    robots=("hexapod",),
    joints={"hexapod": ("x", "y", "z", "u", "v", "w")},
    # U, V, W: rotations about the x, y, z axes (C-887 convention, calflow_hexapod.models.geometry)
    axes={
        "u": ("degree", "rotation U about x"),
        "v": ("degree", "rotation V about y"),
        "w": ("degree", "rotation W about z"),
    },
    rigs={"hexapod": {"simulated": "calflow_hexapod.stage.rig:simulated_hexapod"}},
    plans={
        "hexapod": {
            "identification": f"{_P}:identification",
            "validation_heldout": f"{_P}:validation_heldout",
            "iso9283": f"{_P}:iso9283",
            "validation_export": "calflow_hexapod.export.verification:validation_export",
        }
    },
    rig_options="calflow_hexapod.stage.run_options:rig_options",
    step_options={
        "acquire": (
            Option("--bundle", "a hexapod model's export folder, for --plan validation_export", "path"),
        )
    },
    steps={
        "check": "calflow_hexapod.checks:check",
        "identify": f"{_S}:identify",
        "metrics": f"{_S}:metrics",
        "summarise": "calflow_hexapod.report.summary:summarise",
        "figures": "calflow_hexapod.report.figures:figures",
    },
    templates="calflow_hexapod.report",
    schemas="calflow_hexapod",
    index_row="hexapod_index_row.html.j2",
    headline="calflow_hexapod.report.headline:headline",
    summary_sections={
        "model": "models",
        "metrics:validation_heldout": "heldout",
        "metrics:iso9283": "iso9283",
        "metrics:validation_export": "export",
        "run:identification": "identification",
        "run:validation_heldout": "heldout_runs",
    },
    uncertainty="calflow_hexapod.certificate:measurements",
    # the figures a stage's specification may name: True when calflow gives their U
    certified={
        "hexapod": {
            "accuracy_um": True,
            "repeatability_um": True,
            **{f"{k}_{a}_deg": False for k in ("accuracy", "repeatability") for a in "uvw"},
        }
    },
    rules=("calflow_hexapod", "rules/hexapod.smk"),
    workflow="calflow_hexapod.workflow:WORKFLOW",
    commands=COMMANDS,
    sensors={"simulated_tracker": "calflow_hexapod.stage.sensor:simulated_tracker"},
    options={
        "calflow_hexapod.stage.rig:simulated_hexapod": "calflow_hexapod.stage.physics:check_options",
        "calflow_hexapod.stage.sensor:simulated_tracker": "calflow_hexapod.stage.sensor:check_tracker_options",
    },
    emulator="calflow_hexapod.stage.emulate:EMULATOR",
)
