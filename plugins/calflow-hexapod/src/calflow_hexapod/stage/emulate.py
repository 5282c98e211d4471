"""A C-887-class GCS emulator serving a hexapod campaign's simulated hexapod.

``calflow emulate gcs --campaign config/campaigns/X.yaml --port 50000 [--time-scale 100]``
(through the family's ``emulator``) starts :class:`calflow.gcs.emulator.GCSEmulator` on
127.0.0.1 around a :class:`calflow_hexapod.stage.c887.HexapodController` — axes X Y Z (mm) and
U V W (degree), encoder-true ``POS?`` at the campaign's encoder resolution — and prints the
``rig:`` section that drives it with the ``gcs`` rig. The laser tracker is not served over
GCS: the rig's sensor ``simulated_tracker`` (the family registers it as the short name of
``calflow_hexapod.stage.sensor:simulated_tracker``) is the physical world
behind the controller (:mod:`calflow_hexapod.stage.sensor`), with the campaign's physics. So a
run through the emulator sees the simulated rig's physics with a controller's timing,
limits and faults (:class:`calflow.gcs.emulator.Faults`).
"""

from __future__ import annotations

import threading
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from calflow.errors import CalflowError
from calflow.gcs.campaign_server import link_options, load_campaign_arg, serve_campaign, start_emulated
from calflow.gcs.emulator import Faults, GCSEmulator
from calflow_hexapod.models.geometry import AXES
from calflow_hexapod.stage.c887 import AXIS_IDS, SCALE, HexapodController
from calflow_hexapod.stage.physics import truth_from_options
from calflow_hexapod.stage.run_options import simulated_physics

SENSOR = "simulated_tracker"  # the gcs rig's sensor, as the family registers it
SENSOR_TARGET = "calflow_hexapod.stage.sensor:simulated_tracker"
JOINT_AXES = dict(zip(AXES, AXIS_IDS))


def physics_options(campaign: Mapping[str, Any]) -> dict[str, Any]:
    """:class:`HexapodTruth` overrides of a campaign: the simulated rig's options, or the
    tracker sensor's options of a ``gcs`` rig (seed, stream, pivot and start removed; none
    for another sensor)."""
    return simulated_physics(dict(campaign)) or {}


def campaign_emulator(
    campaign: Mapping[str, Any] | str | Path,
    *,
    port: int = 0,
    time_scale: float = 1.0,
    faults: Faults | None = None,
) -> GCSEmulator:
    """An (unstarted) emulator of the campaign's hexapod: the C-887 with the campaign's encoder
    resolution and travel velocities."""
    c = load_campaign_arg(campaign)
    try:
        truth = truth_from_options(physics_options(c))
    except (TypeError, ValueError) as exc:
        raise CalflowError(f"emulate gcs: campaign rig options: {exc}") from None
    controller = HexapodController(
        time_scale=time_scale,
        resolution_um=truth.encoder_resolution_um,
        velocity_mm_s=truth.velocity_um_s / 1000.0,
        velocity_deg_s=truth.velocity_deg_s,
    )
    return GCSEmulator(port=port, faults=faults, controller=controller)


def rig_options(
    address: tuple[str, int],
    campaign: Mapping[str, Any],
    *,
    time_scale: float = 1.0,
    timeout: float = 5.0,
    tries: int = 5,
    backoff_s: float = 0.2,
) -> dict[str, Any]:
    """Options of the ``gcs`` rig that drives a campaign emulator at ``address``."""
    sensor = {
        "factory": SENSOR,
        "options": {"seed": int(campaign.get("seed", 0)), "stream": "gcs", **physics_options(campaign)},
    }
    return link_options(
        address,
        JOINT_AXES,
        sensor,
        scale=SCALE,
        time_scale=time_scale,
        timeout=timeout,
        tries=tries,
        backoff_s=backoff_s,
    )


def emulated_rig_options(
    campaign: Mapping[str, Any] | str | Path,
    *,
    port: int = 0,
    time_scale: float = 100.0,
    timeout: float = 1.0,
    tries: int = 5,
    backoff_s: float = 0.05,
    faults: Faults | None = None,
) -> tuple[GCSEmulator, dict[str, Any]]:
    """Start a campaign emulator; return it and the ``gcs`` rig options that drive it (for
    tests: the caller stops it). The rig's ``time_scale`` equals the emulator's."""
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


def emulate_main(
    argv: list[str] | None = None,
    stop_event: threading.Event | None = None,
    prog: str = "calflow emulate gcs",
) -> int:
    """``calflow emulate gcs`` of a hexapod campaign: serve its C-887 until Ctrl-C or --duration."""

    def banner(emu: GCSEmulator, c: dict, time_scale: float) -> str:
        host, port = emu.address
        return (
            f"C-887 GCS emulator of campaign {c.get('name', '?')!r} on {host}:{port} "
            f"(axes X Y Z mm, U V W degree; time scale {time_scale:g})"
        )

    return serve_campaign(
        argv,
        prog=prog,
        stop_event=stop_event,
        description="Serve a campaign's simulated hexapod as a C-887-class PI GCS 2.0 controller on 127.0.0.1.",
        start=lambda c, port, ts: campaign_emulator(c, port=port, time_scale=ts).start(),
        banner=banner,
        rig_section=lambda emu, c, ts: {
            "factory": "gcs",
            "options": rig_options(emu.address, c, time_scale=ts),
        },
    )


if __name__ == "__main__":
    raise SystemExit(emulate_main())
