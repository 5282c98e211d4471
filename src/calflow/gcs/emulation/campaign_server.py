"""Serving a campaign's stages from a controller emulator until Ctrl-C or ``--duration``.

The command-line side shared by the families' campaign emulators (the XYΘ family's C-863 one,
the nano family's E-727-class one, a plug-in family's), and ``calflow emulate gcs``, which
serves a campaign with the emulator of its robot family (:func:`emulate_command`):
arguments ``--campaign``, ``--port``, ``--time-scale``, ``--duration``, checked in one line
each; the emulator's address and the campaign ``rig:`` section that drives it are printed.
"""

from __future__ import annotations

import argparse
import math
import threading
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from calflow.errors import CalflowError
from calflow.gcs.emulation.emulator import GCSEmulator


def _plain(value: Any) -> Any:
    """A campaign's values as plain dicts and lists (for YAML's safe dumper)."""
    from calflow.configuration.campaign import thaw

    return thaw(value)


def load_campaign_arg(campaign: Mapping[str, Any] | str | Path) -> dict:
    """A campaign given as a file (loaded and checked) or as a mapping (copied)."""
    if isinstance(campaign, (str, Path)):
        from calflow.configuration.campaign import load as load_campaign

        return load_campaign(campaign)
    return dict(campaign)


def link_options(
    address: tuple[str, int],
    axes: Mapping[str, Any],
    sensor: Mapping[str, Any],
    *,
    time_scale: float,
    timeout: float,
    tries: int,
    backoff_s: float,
    scale: Mapping[str, float] | None = None,
    reference: bool = True,
    poll_s: float | None = None,
    recorder: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """Options of the ``gcs`` rig (:mod:`calflow.gcs.rig`) that drive the controller at
    ``address``: its joint ↔ axis map, the link's timeout and reconnection, the emulator's
    ``time_scale`` (so dwell and reported times are in simulation seconds), the sensor that
    reads the stage; ``scale``, ``poll_s`` and ``recorder`` when the family needs them."""
    out: dict[str, Any] = {
        "axes": dict(axes),
        "host": address[0],
        "port": int(address[1]),
        "timeout": timeout,
    }
    if scale is not None:
        out["scale"] = dict(scale)
    out.update(time_scale=time_scale, reference=reference)
    if poll_s is not None:
        out["poll_s"] = poll_s
    out["reconnect"] = {"tries": tries, "backoff_s": backoff_s}
    if recorder is not None:
        out["recorder"] = dict(recorder)
    out["sensor"] = dict(sensor)
    return out


def start_emulated(
    campaign: Mapping[str, Any] | str | Path,
    start: Callable[..., GCSEmulator],
    rig_options: Callable[..., dict[str, Any]],
    *,
    port: int,
    time_scale: float,
    timeout: float,
    tries: int,
    backoff_s: float,
    faults=None,
) -> tuple[GCSEmulator, dict[str, Any]]:
    """A family's campaign emulator started (``start(campaign, port=, time_scale=, faults=)``)
    and the ``gcs`` rig options that drive it (``rig_options(address, campaign, ...)``) with
    the emulator's time scale. For tests: the caller stops it (``emu.stop()``)."""
    c = load_campaign_arg(campaign)
    emu = start(c, port=port, time_scale=time_scale, faults=faults).start()
    return emu, rig_options(
        emu.address, c, time_scale=time_scale, timeout=timeout, tries=tries, backoff_s=backoff_s
    )


def _parser(prog: str, description: str) -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog=prog, description=description)
    p.add_argument("--campaign", required=True, help="config/campaigns/<name>.yaml")
    p.add_argument("--port", type=int, default=50000, help="TCP port (0 = any free port)")
    p.add_argument("--time-scale", type=float, default=1.0, help="simulation speed-up factor")
    p.add_argument("--duration", type=float, default=None, help="stop after S seconds")
    return p


def serve_campaign(
    argv: list[str] | None,
    *,
    prog: str,
    description: str,
    start: Callable[[dict, int, float], GCSEmulator],
    banner: Callable[[GCSEmulator, dict, float], str],
    rig_section: Callable[[GCSEmulator, dict, float], dict],
    stop_event: threading.Event | None = None,
) -> int:
    """Parse the arguments, start the emulator (``start(campaign, port, time_scale)``),
    print ``banner`` and the ``rig:`` section, serve until Ctrl-C, ``stop_event`` or
    ``--duration`` seconds."""
    import yaml

    a = _parser(prog, description).parse_args(argv)
    who = prog.removeprefix("calflow ").removeprefix("python -m ")
    if not 0 <= a.port <= 65535:
        raise CalflowError(f"{who}: --port: expected a TCP port 0-65535 (0 = any free port), got {a.port}")
    if not (a.time_scale > 0 and math.isfinite(a.time_scale)):
        raise CalflowError(f"{who}: --time-scale: expected a value > 0 (finite), got {a.time_scale}")
    c = load_campaign_arg(a.campaign)
    try:
        emu = start(c, a.port, a.time_scale)
    except OSError as exc:
        raise CalflowError(f"{who}: --port {a.port}: cannot listen ({exc.strerror})") from None
    stop_event = stop_event or threading.Event()
    deadline = math.inf if a.duration is None else time.monotonic() + a.duration
    try:
        print(banner(emu, c, a.time_scale), flush=True)
        print(
            "campaign rig section for it:\n"
            + yaml.safe_dump(_plain({"rig": rig_section(emu, c, a.time_scale)}), sort_keys=False),
            flush=True,
        )
        while not stop_event.is_set() and (left := deadline - time.monotonic()) > 0:
            stop_event.wait(min(0.5, left))
    except KeyboardInterrupt:
        pass
    finally:
        emu.stop()
    return 0


def emulate_command(args) -> int:
    """``calflow emulate gcs --campaign FILE ...``: the controller emulator of the campaign's
    robot family (its ``emulator``: the C-863 one for ``xytheta``, the E-727-class one for
    ``stage1d``/``stage2d``), given the arguments after ``gcs``."""
    from calflow.family import family_of
    from calflow.family_contract import built_of

    argv = list(args.rest)
    known = _parser(
        "calflow emulate gcs",
        "Serve a campaign's stages as a PI GCS 2.0 controller on 127.0.0.1 "
        "(docs/gcs.md), with the emulator the campaign's robot family registers.",
    ).parse_args(argv)
    c = load_campaign_arg(known.campaign)
    robot = c.get("robot")
    fam = family_of(str(robot))
    if fam.emulator is None:
        raise CalflowError(
            f"calflow emulate gcs: {known.campaign}: robot {robot!r} (family {fam.name}) has no "
            "controller emulator"
        )
    return built_of(fam, "emulator").main(argv, prog="calflow emulate gcs")
