"""Checks of a nano campaign beyond its JSON Schema: the simulated stage as it has aged."""

from __future__ import annotations

from pathlib import Path

from calflow.errors import ConfigError, OptionError


def check_campaign(campaign: dict, path: Path) -> None:
    """Resolve ``rig.options.aging`` of a simulated stage for the campaign's ``start`` into
    the rig's options (:func:`calflow.nano.stage.aging.resolve`), once, here: the rig, the
    error budget's replays and the designed plans all read these options. Raises
    :class:`ConfigError` naming the file and key."""
    rig = campaign["rig"]
    if rig["factory"] != "simulated":
        return
    from calflow.nano.stage.aging import resolve
    from calflow.nano.stage.options import _COMMON
    from calflow.nano.stage.rig import Nano1DRig, Nano2DRig

    cls = {"stage1d": Nano1DRig, "stage2d": Nano2DRig}[campaign["robot"]]
    for run, extra in (rig.get("runs") or {}).items():
        if "aging" in (extra or {}):
            raise ConfigError(
                f"{path}: key 'rig.runs.{run}.aging': expected ageing in rig.options only "
                "(a stage ages once per campaign, not per run)"
            )
    options = rig.get("options") or {}
    try:
        aged = resolve(options, campaign["start"], {**_COMMON, **cls._EXTRA}, cls._AXIS)
    except OptionError as exc:
        raise ConfigError(exc.at(path, "rig.options")) from None
    if aged != options:
        rig["options"] = aged
