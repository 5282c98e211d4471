"""A piezo controller emulator serving a nano campaign's stage (docs/gcs.md, "Emulating a
nano campaign").

``calflow emulate gcs --campaign config/campaigns/nano1d-thesis.yaml --port 50000
--time-scale 1000`` (or ``python -m calflow.nano.stage.emulate ...``) starts an E-727-class controller emulation (:mod:`calflow.gcs.piezo`)
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

import threading
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from calflow.errors import CalflowError
from calflow.gcs.campaign_server import link_options, load_campaign_arg, serve_campaign, start_emulated
from calflow.gcs.emulator import Faults, GCSEmulator
from calflow.gcs.piezo import PiezoAxisConfig, piezo_emulator

STAGES = {"stage1d": "nano1d", "stage2d": "nano2d"}
JOINT_AXES = {"x": "1", "y": "2"}
RATE_HZ = 10.0  # data recorder rate of the high-rate dwells (the simulated rig's default)


_load = load_campaign_arg


def stage_of(campaign: Mapping[str, Any]) -> str:
    robot = campaign.get("robot")
    if robot not in STAGES:
        raise CalflowError(f"emulate piezo: robot {robot!r}: expected one of {', '.join(STAGES)}")
    return STAGES[robot]


def physics_options(campaign: Mapping[str, Any], run: str | None = None) -> dict[str, Any]:
    """The simulated rig's options of a campaign (its ``simulated`` rig options and run
    overrides, or its ``simulated_interferometer`` sensor options), seeds removed."""
    rig = campaign.get("rig") or {}
    options = {**(rig.get("options") or {}), **((rig.get("runs") or {}).get(run) or {})}
    if rig.get("factory", "simulated") != "simulated":
        sensor = options.get("sensor") or {}
        options = (
            dict(sensor.get("options") or {}) if sensor.get("factory") == "simulated_interferometer" else {}
        )
    return {k: v for k, v in options.items() if k not in ("seed", "world_seed", "start_offset_s", "stage")}


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


def campaign_emulator(
    campaign: Mapping[str, Any] | str | Path,
    *,
    port: int = 0,
    time_scale: float = 1.0,
    faults: Faults | None = None,
) -> GCSEmulator:
    """An (unstarted) E-727-class emulator with the campaign's stage axes."""
    c = _load(campaign)
    try:
        axes = axis_configs(c)
    except (TypeError, ValueError) as exc:
        raise CalflowError(f"emulate piezo: campaign rig options: {exc}") from None
    return piezo_emulator(axes, port=port, time_scale=time_scale, faults=faults, seed=int(c.get("seed", 0)))


def rig_options(
    address: tuple[str, int],
    campaign: Mapping[str, Any],
    *,
    time_scale: float = 1.0,
    timeout: float = 5.0,
    tries: int = 5,
    backoff_s: float = 0.2,
) -> dict[str, Any]:
    """Options of the ``gcs`` rig that drives a nano campaign emulator at ``address``."""
    joints = ("x",) if stage_of(campaign) == "nano1d" else ("x", "y")
    return link_options(
        address,
        {j: JOINT_AXES[j] for j in joints},
        _sensor(campaign),
        reference=False,
        poll_s=0.002,
        recorder={"rate_hz": RATE_HZ},
        time_scale=time_scale,
        timeout=timeout,
        tries=tries,
        backoff_s=backoff_s,
    )


def _sensor(campaign: Mapping[str, Any], run: str | None = None) -> dict[str, Any]:
    return {
        "factory": "simulated_interferometer",
        "options": {"stage": stage_of(campaign), **physics_options(campaign, run)},
    }


def campaign_rig(options: Mapping[str, Any], campaign: Mapping[str, Any]) -> dict[str, Any]:
    """The campaign ``rig:`` section for the ``gcs`` rig ``options``: the campaign's run
    overrides (``rig.runs``, e.g. the metrology room) become overrides of the sensor."""
    runs = (campaign.get("rig") or {}).get("runs") or {}
    return {
        "factory": "gcs",
        "options": dict(options),
        **({"runs": {r: {"sensor": _sensor(campaign, r)} for r in runs}} if runs else {}),
    }


def emulated_rig_options(
    campaign: Mapping[str, Any] | str | Path,
    *,
    port: int = 0,
    time_scale: float = 1000.0,
    timeout: float = 1.0,
    tries: int = 5,
    backoff_s: float = 0.05,
    faults: Faults | None = None,
) -> tuple[GCSEmulator, dict[str, Any]]:
    """Start a nano campaign emulator; return it and the ``gcs`` rig options (for a campaign
    file: :func:`campaign_rig`). The caller stops it."""
    return start_emulated(
        campaign,
        campaign_emulator,
        rig_options,
        port=port,
        time_scale=time_scale,
        timeout=timeout,
        tries=tries,
        backoff_s=backoff_s,
        faults=faults,
    )


def main(
    argv: list[str] | None = None,
    stop_event: threading.Event | None = None,
    prog: str = "python -m calflow.nano.stage.emulate",
) -> int:
    """``calflow emulate gcs`` of a nano campaign (or ``python -m calflow.nano.stage.emulate``):
    serve its stage until Ctrl-C or --duration."""

    def banner(emu: GCSEmulator, c: dict, time_scale: float) -> str:
        host, port = emu.address
        return (
            f"E-727-class emulator of campaign {c.get('name', '?')!r} on {host}:{port} "
            f"(axes {', '.join(emu.controller.axes)}, um; time scale {time_scale:g})"
        )

    return serve_campaign(
        argv,
        prog=prog,
        stop_event=stop_event,
        description="Serve a nano campaign's stage as an E-727-class PI GCS 2.0 controller on "
        "127.0.0.1 (docs/gcs.md).",
        start=lambda c, port, ts: campaign_emulator(c, port=port, time_scale=ts).start(),
        banner=banner,
        rig_section=lambda emu, c, ts: campaign_rig(rig_options(emu.address, c, time_scale=ts), c),
    )


if __name__ == "__main__":
    raise SystemExit(main())
