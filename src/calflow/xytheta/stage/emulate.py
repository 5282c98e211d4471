"""A GCS emulator serving the simulated stages of a campaign (docs/gcs.md, "Emulating a campaign").

``calflow emulate gcs --campaign config/campaigns/X.yaml --port 50000 [--time-scale 100]``
starts :class:`calflow.gcs.emulation.emulator.GCSEmulator` on 127.0.0.1 with one axis per joint of
the campaign's XYΘ robot and prints the ``rig:`` section that drives it with the ``gcs``
rig. The model is deliberately simple:

* axes ``1``, ``2`` (X, Y) are M-111-like lead-screw stages in **mm** in the campaign's
  joint coordinates (Table 4.1's 15 mm travel from 0, soft limits -0.5 to 15 mm: the plans'
  approach and compensated moves reach -0.15 mm; reference switch at mid-travel; 1.5 mm/s,
  need FRF); axis ``3`` (Θ) is a rotation stage in **degree** (±30°, 10°/s, absolute);
* ``POS?`` answers what the controller's encoder measures: the trajectory position,
  quantised to the encoder's resolution (``ENCODER_UM``, the 50 nm of Table 4.1 for X and
  Y). Like a real controller's, it cannot see the errors only an external sensor sees —
  lead screw, backlash, coupling, scale, straightness, the Θ stage's angle errors;
* the vision sensor is not served over GCS: the rig's built-in ``simulated_vision`` sensor
  (:mod:`calflow.xytheta.stage.vision_sensor`) is the physical world: read at those encoder
  positions, it puts the carriages where the simulated physics
  (:class:`calflow.xytheta.stage.physics.XYThetaTruth`) puts them — lead screw and lost
  motion of the approach, coupling, scale, straightness, Θ errors, runout, yaw — and adds
  stage repeatability, noise, decoding errors and drift.

So a run through the emulator sees the same physics as the simulated rig, with the
stages' timing, limits and faults of a controller (the emulator's ``faults``).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from calflow.errors import CalflowError
from calflow.gcs.emulation.axis import AxisConfig
from calflow.gcs.emulation.campaign_emulator import Emulator
from calflow.gcs.emulation.emulator import EmulatedController, Faults, GCSEmulator
from calflow.rigs.simulated.campaign import simulated_options
from calflow.xytheta.stage.rig import XYThetaTruth
from calflow.xytheta.stage.vision_sensor import truth_from_options

JOINT_AXES = {"x": "1", "y": "2", "theta": "3"}
SCALE = {"x": 1000.0, "y": 1000.0, "theta": 1.0}  # µm or degree per controller unit
AXIS_CONFIGS = {
    "1": AxisConfig(tmn=-0.5, tmx=15.0, ref_position=7.5, velocity=1.5, max_velocity=2.0, accel=10.0),
    "2": AxisConfig(tmn=-0.5, tmx=15.0, ref_position=7.5, velocity=1.5, max_velocity=2.0, accel=10.0),
    "3": AxisConfig(
        tmn=-30.0, tmx=30.0, velocity=10.0, max_velocity=20.0, accel=100.0, needs_reference=False
    ),
}


ENCODER_UM = {"x": 0.05, "y": 0.05, "theta": 0.0}  # Table 4.1: 50 nm resolution; Θ: < 1.1 µ° (Table 4.2)


class StagePhysics:
    """``true_position`` hook of the emulator: what each axis's encoder reads (module doc)."""

    def __init__(self, truth: XYThetaTruth) -> None:
        self.truth = truth
        self.controller: EmulatedController | None = None  # set by :func:`campaign_emulator`

    def __call__(self, axis: str, commanded: float) -> float:
        joint = next(j for j, a in JOINT_AXES.items() if a == axis)
        q = commanded * SCALE[joint]
        res = ENCODER_UM[joint]
        if res > 0:
            q = round(q / res) * res
        return float(q) / SCALE[joint]


def physics_options(campaign: Mapping[str, Any]) -> dict[str, Any]:
    """:class:`XYThetaTruth` overrides of a campaign: the simulated rig's options, or the
    ``simulated_vision`` sensor options of a ``gcs`` rig, or its ``camera`` sensor's
    ``simulated_camera`` options (then ``sensor: images``); seed and stream removed."""
    if campaign.get("robot", "xytheta") != "xytheta":
        raise CalflowError(
            f"emulate gcs: robot {campaign.get('robot')!r}: only xytheta campaigns "
            "have simulated stages to serve"
        )
    options = simulated_options(campaign, ("simulated_vision",))
    if options is None:  # another sensor: an emulated camera's physics, read through images
        sensor = (campaign["rig"].get("options") or {}).get("sensor") or {}
        source = (
            (sensor.get("options") or {}).get("source") or {} if sensor.get("factory") == "camera" else {}
        )
        camera = source.get("factory") == "simulated_camera"
        options = {**(source.get("options") or {}), "sensor": "images"} if camera else {}
    return {k: v for k, v in options.items() if k not in ("seed", "stream")}


def _controller(physics: StagePhysics, c: dict, port: int, time_scale: float, faults: Faults | None):
    emu = GCSEmulator(
        axes=dict(AXIS_CONFIGS), port=port, faults=faults, time_scale=time_scale, true_position=physics
    )
    physics.controller = emu.controller
    return emu


def _sensor(campaign: Mapping[str, Any]) -> dict[str, Any]:
    physics = physics_options(campaign)
    sensor = {
        "factory": "simulated_vision",
        "options": {"seed": int(campaign.get("seed", 0)), "stream": "gcs", **physics},
    }
    if physics.get("sensor") == "images":  # the pattern seen by an emulated camera and decoded
        source = {k: v for k, v in physics.items() if k != "sensor"}
        source = {"seed": int(campaign.get("seed", 0)), "stream": "gcs", **source}
        sensor = {
            "factory": "camera",
            "options": {"source": {"factory": "simulated_camera", "options": source}},
        }
    return sensor


EMULATOR = Emulator(
    name="emulate gcs",
    title="GCS emulator",
    axes="axes 1=x mm, 2=y mm, 3=theta degree",
    description="Serve a campaign's simulated XYΘ stages as a PI GCS 2.0 controller on "
    "127.0.0.1 (docs/gcs.md).",
    physics=lambda c: StagePhysics(truth_from_options(physics_options(c))),
    controller=_controller,
    joint_axes=lambda c: JOINT_AXES,
    sensor=_sensor,
    link={"scale": SCALE},
)
campaign_emulator = EMULATOR.campaign_emulator  # (campaign, *, port, time_scale, faults): unstarted
rig_options = EMULATOR.rig_options  # (address, campaign, *, time_scale, ...): the gcs rig's options
emulated_rig_options = EMULATOR.emulated_rig_options  # started, with its rig options (tests)
