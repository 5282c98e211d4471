"""A piezo controller emulator serving a nano campaign's stage (docs/gcs.md, "Emulating a
nano campaign").

``calflow emulate gcs --campaign config/campaigns/nano1d-thesis.yaml --port 50000
--time-scale 1000`` (or ``python -m calflow.nano.stage.emulate ...``) starts an E-727-class controller emulation (:mod:`calflow.gcs.emulation.piezo`)
on 127.0.0.1 with one closed-loop axis per joint of the campaign's stage (``1`` = x,
``2`` = y; µm, 0 to the stroke with the simulated rig's margins) and prints the ``rig:``
section that drives it with the ``gcs`` rig:

* ``POS?`` and the data recorder answer the controller's capacitive sensor: the position
  the servo holds, with sensor noise; the stage's nonlinearity, hysteresis and drift are
  not visible to it, as on the real controller;
* the interferometer and the thermocouples are the ``simulated_interferometer`` sensor
  (:mod:`calflow.nano.stage.interferometer_sensor`): the campaign's simulated rig physics moved
  to the controller's positions and read at the rig's times (high-rate dwells: at the
  data recorder's points).

A step follows the closed loop of the campaign's physics (the simulated rig's
``step_natural_hz``, ``step_damping``: the second-order step the interferometer sees too, so
the data recorder's record of a move and the interferometer's agree); ``ONT?`` turns true
once the position has stayed within 10 nm for ``rise_time_s``, so a move takes about as long
as on the simulated rig.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from calflow.errors import CalflowError
from calflow.gcs.emulation.campaign_emulator import Emulator
from calflow.gcs.emulation.piezo import PiezoAxisConfig, piezo_emulator
from calflow.rigs.simulated.campaign import simulated_options

STAGES = {"stage1d": "nano1d", "stage2d": "nano2d"}
JOINT_AXES = {"x": "1", "y": "2"}
RATE_HZ = 10.0  # data recorder rate of the high-rate dwells (the simulated rig's default)
SENSOR = "simulated_interferometer"


def stage_of(campaign: Mapping[str, Any]) -> str:
    robot = campaign.get("robot")
    if robot not in STAGES:
        raise CalflowError(f"emulate piezo: robot {robot!r}: expected one of {', '.join(STAGES)}")
    return STAGES[robot]


def physics_options(campaign: Mapping[str, Any], run: str | None = None) -> dict[str, Any]:
    """The simulated rig's options of a campaign (its ``simulated`` rig options and run
    overrides, or its ``simulated_interferometer`` sensor options), seeds removed."""
    drop = ("seed", "world_seed", "start_offset_s", "stage")
    return simulated_options(campaign, (SENSOR,), drop, run) or {}


def axis_configs(campaign: Mapping[str, Any]) -> dict[str, PiezoAxisConfig]:
    """One piezo axis per joint, over the simulated rig's command range (µm)."""
    from calflow.nano.stage import rig as nano_rig

    stage = stage_of(campaign)
    probe = getattr(nano_rig, stage)(**physics_options(campaign))
    o = probe.options
    natural = float(o["step_natural_hz"])  # 0: an ideal step, a 0.1 ms first order here
    return {
        JOINT_AXES[j]: PiezoAxisConfig(
            tmn=-float(o["stroke_margin_um"]),
            tmx=float(o["stroke_um"] + o["stroke_margin_um"]),
            natural_hz=natural,
            damping=float(o["step_damping"]),
            servo_tau=1e-4,
            settle_window=0.01,
            settle_time=float(o["rise_time_s"]),
        )
        for j in probe.joints
    }


def _sensor(campaign: Mapping[str, Any], run: str | None = None) -> dict[str, Any]:
    return {"factory": SENSOR, "options": {"stage": stage_of(campaign), **physics_options(campaign, run)}}


def campaign_rig(options: Mapping[str, Any], campaign: Mapping[str, Any]) -> dict[str, Any]:
    """The campaign ``rig:`` section for the ``gcs`` rig ``options``: the campaign's run
    overrides (``rig.runs``, e.g. the metrology room) become overrides of the sensor."""
    runs = (campaign.get("rig") or {}).get("runs") or {}
    return {
        "factory": "gcs",
        "options": dict(options),
        **({"runs": {r: {"sensor": _sensor(campaign, r)} for r in runs}} if runs else {}),
    }


EMULATOR = Emulator(
    name="emulate piezo",
    title="E-727-class emulator",
    axes="axes {axes}, um",
    description="Serve a nano campaign's stage as an E-727-class PI GCS 2.0 controller on "
    "127.0.0.1 (docs/gcs.md).",
    physics=axis_configs,
    controller=lambda axes, c, port, time_scale, faults: piezo_emulator(
        axes, port=port, time_scale=time_scale, faults=faults, seed=int(c.get("seed", 0))
    ),
    joint_axes=lambda c: {j: JOINT_AXES[j] for j in (("x",) if stage_of(c) == "nano1d" else ("x", "y"))},
    sensor=_sensor,
    link={"reference": False, "poll_s": 0.002, "recorder": {"rate_hz": RATE_HZ}},
    rig_section=campaign_rig,
    time_scale=1000.0,
    prog="python -m calflow.nano.stage.emulate",
)
#: started, with its ``gcs`` rig options (for a campaign file's ``rig:`` section: :func:`campaign_rig`);
#: the caller stops it
emulated_rig_options = EMULATOR.emulated_rig_options


if __name__ == "__main__":
    raise SystemExit(EMULATOR.main())
