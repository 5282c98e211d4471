"""A campaign's controller emulator: what a family declares, and the mains built from it.

A family describes its emulator once in an :class:`Emulator` — how it reads the campaign's
physics, how it builds the controller around them, the ``gcs`` rig's axes, sensor and link
settings, and the words of its banner — and gets from it the ``gcs`` rig options that drive a
running emulator (:meth:`Emulator.rig_options`), an emulator started for tests
(:meth:`Emulator.emulated_rig_options`) and the ``calflow emulate gcs`` main
(:meth:`Emulator.main`). The family's ``emulator`` hook names the :class:`Emulator` itself. The command-line side is
:func:`calflow.gcs.emulation.campaign_server.serve_campaign`.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from calflow.errors import CalflowError
from calflow.gcs.emulation.campaign_server import (
    link_options,
    load_campaign_arg,
    serve_campaign,
    start_emulated,
)
from calflow.gcs.emulation.emulator import Faults, GCSEmulator


def _gcs_section(options: dict[str, Any], campaign: Mapping[str, Any]) -> dict[str, Any]:
    return {"factory": "gcs", "options": options}


@dataclass(frozen=True)
class Emulator:
    """A family's campaign emulator.

    ``physics(campaign)`` reads the campaign's simulated physics (a ``TypeError`` or
    ``ValueError`` becomes one line naming the campaign's rig options);
    ``controller(physics, campaign, port, time_scale, faults)`` builds the unstarted
    :class:`GCSEmulator`; ``joint_axes(campaign)`` and ``sensor(campaign)`` are the ``gcs``
    rig's joint → axis map and sensor section, ``link`` its further
    :func:`~calflow.gcs.emulation.campaign_server.link_options` (scale, reference, poll, recorder);
    ``rig_section(options, campaign)`` the campaign ``rig:`` section the main prints.
    ``name`` prefixes errors (``emulate gcs``), ``title`` and ``axes`` make the banner
    (``axes`` may hold ``{axes}``: the controller's axis names), ``description`` the help.
    """

    name: str
    title: str
    axes: str
    description: str
    physics: Callable[[dict], Any]
    controller: Callable[[Any, dict, int, float, Faults | None], GCSEmulator]
    joint_axes: Callable[[Mapping[str, Any]], Mapping[str, str]]
    sensor: Callable[[Mapping[str, Any]], dict[str, Any]]
    link: Mapping[str, Any] = field(default_factory=dict)
    rig_section: Callable[[dict[str, Any], Mapping[str, Any]], dict[str, Any]] = _gcs_section
    time_scale: float = 100.0  # of the emulator :meth:`emulated_rig_options` starts
    prog: str = "calflow emulate gcs"

    def campaign_emulator(
        self,
        campaign: Mapping[str, Any] | str | Path,
        *,
        port: int = 0,
        time_scale: float = 1.0,
        faults: Faults | None = None,
    ) -> GCSEmulator:
        """An (unstarted) emulator of the campaign's stage."""
        c = load_campaign_arg(campaign)
        try:
            physics = self.physics(c)
        except (TypeError, ValueError) as exc:
            raise CalflowError(f"{self.name}: campaign rig options: {exc}") from None
        return self.controller(physics, c, port, time_scale, faults)

    def rig_options(
        self,
        address: tuple[str, int],
        campaign: Mapping[str, Any],
        *,
        time_scale: float = 1.0,
        timeout: float = 5.0,
        tries: int = 5,
        backoff_s: float = 0.2,
    ) -> dict[str, Any]:
        """Options of the ``gcs`` rig that drives a campaign emulator at ``address``."""
        return link_options(
            address,
            self.joint_axes(campaign),
            self.sensor(campaign),
            **self.link,
            time_scale=time_scale,
            timeout=timeout,
            tries=tries,
            backoff_s=backoff_s,
        )

    def emulated_rig_options(
        self,
        campaign: Mapping[str, Any] | str | Path,
        *,
        port: int = 0,
        time_scale: float | None = None,
        timeout: float = 1.0,
        tries: int = 5,
        backoff_s: float = 0.05,
        faults: Faults | None = None,
    ) -> tuple[GCSEmulator, dict[str, Any]]:
        """Start a campaign emulator; return it and the ``gcs`` rig options that drive it.

        For tests: the caller stops it (``emu.stop()``). The rig's ``time_scale`` equals the
        emulator's (by default the family's), so dwell and reported times are in simulation
        seconds; for a campaign file, the ``rig:`` section is :attr:`rig_section`."""
        return start_emulated(
            campaign,
            self.campaign_emulator,
            self.rig_options,
            port=port,
            time_scale=self.time_scale if time_scale is None else time_scale,
            timeout=timeout,
            tries=tries,
            backoff_s=backoff_s,
            faults=faults,
        )

    def banner(self, emu: GCSEmulator, campaign: Mapping[str, Any], time_scale: float) -> str:
        host, port = emu.address
        axes = self.axes.format(axes=", ".join(emu.controller.axes))
        return (
            f"{self.title} of campaign {campaign.get('name', '?')!r} on {host}:{port} "
            f"({axes}; time scale {time_scale:g})"
        )

    def main(
        self,
        argv: list[str] | None = None,
        stop_event: threading.Event | None = None,
        prog: str | None = None,
    ) -> int:
        """``calflow emulate gcs`` of a campaign: serve its stage until Ctrl-C or --duration."""
        return serve_campaign(
            argv,
            prog=prog or self.prog,
            stop_event=stop_event,
            description=self.description,
            start=lambda c, port, ts: self.campaign_emulator(c, port=port, time_scale=ts).start(),
            banner=self.banner,
            rig_section=lambda emu, c, ts: self.rig_section(
                self.rig_options(emu.address, c, time_scale=ts), c
            ),
        )
