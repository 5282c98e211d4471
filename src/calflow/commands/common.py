"""Helpers shared by the subcommands: campaign loading, metadata, rigs."""

from __future__ import annotations

import shlex
import sys
import zlib

from calflow import __version__
from calflow.config import campaign_digest, load_campaign
from calflow.data.runs import RunMetadata


def campaign(path: str) -> dict:
    return load_campaign(path)


def meta(c: dict, source: str, plan: str, model: str | None = None) -> RunMetadata:
    return RunMetadata(
        campaign=c["name"], robot=c["robot"], source=source, plan=plan,
        config_sha256=campaign_digest(c), start=c["start"], model=model,
        history=f"calflow {__version__}: {' '.join(shlex.quote(a) for a in sys.argv[1:])}",
    )


def open_rig(c: dict, run_id: str, start_s: float = 0.0):
    """The campaign's rig for run ``run_id``; returns (rig, source)."""
    from calflow.rigs import load_rig

    rig_cfg = c["rig"]
    options = {**rig_cfg.get("options", {}), **rig_cfg.get("runs", {}).get(run_id, {})}
    if rig_cfg["factory"] == "simulated" and c["robot"] == "xytheta":
        options.setdefault("seed", c["seed"])
        options["stream"] = run_id
    elif rig_cfg["factory"] == "simulated":
        # one world (room, slow drift) per campaign; independent noise per run
        options.setdefault("world_seed", c["seed"])
        options["seed"] = zlib.crc32(f"{c['seed']}:{run_id}".encode())
        options["start_offset_s"] = start_s
    elif rig_cfg["factory"] == "replay":
        options["stream"] = run_id
    elif rig_cfg["factory"] == "gcs":  # real stages; a simulated sensor gets its own noise per run
        sensor = dict(options.get("sensor") or {})
        if sensor.get("factory") == "simulated_vision":
            sensor["options"] = {"seed": c["seed"], **sensor.get("options", {}), "stream": run_id}
            options["sensor"] = sensor
    return load_rig(rig_cfg["factory"], c["robot"], options)


def pairs(items: list[str] | None, flag: str) -> dict[str, str]:
    """Parse NAME=PATH arguments."""
    from calflow.errors import CalflowError

    out = {}
    for item in items or []:
        name, sep, path = item.partition("=")
        if not sep:
            raise CalflowError(f"calflow: {flag}: expected NAME=PATH, got {item!r}")
        out[name] = path
    return out
