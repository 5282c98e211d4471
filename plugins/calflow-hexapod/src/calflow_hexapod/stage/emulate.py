"""A C-887-class GCS emulator serving a hexapod campaign's simulated hexapod.

``calflow emulate gcs --campaign config/campaigns/X.yaml --port 50000 [--time-scale 100]``
(through the family's ``emulator``) starts :class:`calflow.gcs.emulation.emulator.GCSEmulator` on
127.0.0.1 around a :class:`calflow_hexapod.stage.c887.HexapodController` — axes X Y Z (mm) and
U V W (degree), encoder-true ``POS?`` at the campaign's encoder resolution — and prints the
``rig:`` section that drives it with the ``gcs`` rig. The laser tracker is not served over
GCS: the rig's sensor ``simulated_tracker`` (the family registers it as the short name of
``calflow_hexapod.stage.sensor:simulated_tracker``) is the physical world
behind the controller (:mod:`calflow_hexapod.stage.sensor`), with the campaign's physics. So a
run through the emulator sees the simulated rig's physics with a controller's timing,
limits and faults (:class:`calflow.gcs.emulation.emulator.Faults`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from calflow.gcs.emulation.campaign_emulator import Emulator
from calflow.gcs.emulation.emulator import Faults, GCSEmulator
from calflow_hexapod.models.geometry import AXES
from calflow_hexapod.stage.c887 import AXIS_IDS, SCALE, HexapodController
from calflow_hexapod.stage.physics import HexapodTruth, truth_from_options
from calflow_hexapod.stage.run_options import simulated_physics

SENSOR = "simulated_tracker"  # the gcs rig's sensor, as the family registers it
SENSOR_TARGET = "calflow_hexapod.stage.sensor:simulated_tracker"
JOINT_AXES = dict(zip(AXES, AXIS_IDS))


def physics_options(campaign: Mapping[str, Any]) -> dict[str, Any]:
    """:class:`HexapodTruth` overrides of a campaign: the simulated rig's options, or the
    tracker sensor's options of a ``gcs`` rig (seed, stream, pivot and start removed; none
    for another sensor)."""
    return simulated_physics(dict(campaign)) or {}


def _controller(truth: HexapodTruth, c: dict, port: int, time_scale: float, faults: Faults | None):
    """The C-887 with the campaign's encoder resolution and travel velocities."""
    controller = HexapodController(
        time_scale=time_scale,
        resolution_um=truth.encoder_resolution_um,
        velocity_mm_s=truth.velocity_um_s / 1000.0,
        velocity_deg_s=truth.velocity_deg_s,
    )
    return GCSEmulator(port=port, faults=faults, controller=controller)


EMULATOR = Emulator(
    name="emulate gcs",
    title="C-887 GCS emulator",
    axes="axes X Y Z mm, U V W degree",
    description="Serve a campaign's simulated hexapod as a C-887-class PI GCS 2.0 controller on 127.0.0.1.",
    physics=lambda c: truth_from_options(physics_options(c)),
    controller=_controller,
    joint_axes=lambda c: JOINT_AXES,
    sensor=lambda c: {
        "factory": SENSOR,
        "options": {"seed": int(c.get("seed", 0)), "stream": "gcs", **physics_options(c)},
    },
    link={"scale": SCALE},
)
campaign_emulator = EMULATOR.campaign_emulator  # (campaign, *, port, time_scale, faults): unstarted
rig_options = EMULATOR.rig_options  # (address, campaign, *, time_scale, ...): the gcs rig's options
emulated_rig_options = EMULATOR.emulated_rig_options  # started, with its rig options (tests)
