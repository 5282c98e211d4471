"""Checks of a nano campaign beyond its JSON Schema: the simulated stage as it has aged."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from calflow.configuration.campaign import Resolution
from calflow.errors import ConfigError, OptionError

_SENSOR = "simulated_interferometer"  # the simulated world behind an emulated GCS controller


def check(c, args) -> Resolution | None:
    """The family's step hook ``check(c, args)`` (:mod:`calflow.family_contract`): the campaign
    ``c`` loaded from the file ``args.campaign``, checked beyond its schema; returns what it
    resolves."""
    return check_campaign(c, args.campaign)


def check_campaign(campaign: Mapping, path: Path) -> Resolution | None:
    """Resolve ``aging`` of a simulated stage (``rig.options``, or the options of a ``gcs``
    rig's ``simulated_interferometer`` sensor) for the campaign's ``start`` into the rig's
    options (:func:`calflow.nano.stage.aging.resolve`), once, here: the rig, the error
    budget's replays and the designed plans all read these options. Returns the rig section
    so resolved (:class:`~calflow.configuration.campaign.Resolution`), or None; changes nothing. Raises
    :class:`ConfigError` naming the file and key."""
    _check_design(campaign, path)
    rig = campaign["rig"]
    for run, extra in (rig.get("runs") or {}).items():
        if "aging" in (extra or {}):
            raise ConfigError(
                f"{path}: key 'rig.runs.{run}.aging': expected ageing in rig.options only "
                "(a stage ages once per campaign, not per run)"
            )
    options = rig.get("options") or {}
    sensor = options.get("sensor") if isinstance(options.get("sensor"), dict) else {}
    if rig["factory"] == "simulated":
        where = "rig.options"
    elif rig["factory"] == "gcs" and sensor.get("factory") == _SENSOR:
        where = "rig.options.sensor.options"
        options = sensor.get("options") or {}
    else:
        return None
    from calflow.nano.stage.aging import resolve
    from calflow.nano.stage.options import _COMMON
    from calflow.nano.stage.rig import Nano1DRig, Nano2DRig

    cls = {"stage1d": Nano1DRig, "stage2d": Nano2DRig}[campaign["robot"]]
    try:
        aged = resolve(options, campaign["start"], {**_COMMON, **cls._EXTRA}, cls._AXIS)
    except OptionError as exc:
        raise ConfigError(exc.at(path, where)) from None
    if "aging" in options:  # the stage as aged by the campaign's start is a stage the rig can be
        from calflow.nano.stage.interferometer_sensor import check_sensor_options
        from calflow.nano.stage.rig import check_nano1d, check_nano2d

        check = {"stage1d": check_nano1d, "stage2d": check_nano2d}[campaign["robot"]]
        try:
            (check if rig["factory"] == "simulated" else check_sensor_options)(**aged)
        except OptionError as exc:
            raise ConfigError(
                f"{path}: key '{where}.aging': expected ageing that leaves a stage the rig can be at "
                f"the campaign's start ({campaign['start']}); aged, option {exc.option!r}: expected "
                f"{exc.expected}, got {exc.value!r}"
            ) from None
    if aged == options:
        return None
    if rig["factory"] == "simulated":
        return Resolution(rig={**rig, "options": aged})
    return Resolution(rig={**rig, "options": {**rig["options"], "sensor": {**sensor, "options": aged}}})


def _check_design(campaign: dict, path: Path) -> None:
    """A designed training plan picks at most as many positions as its candidate grid holds."""
    t = campaign.get("training") or {}
    if t.get("plan") != "optimal" or not (t.get("design") or {}).get("positions"):
        return
    from calflow.nano.plans.design import candidates
    from calflow.nano.plans.designed import _stroke

    lo, hi = _stroke(campaign)
    n, pool = t["design"]["positions"], len(candidates(lo, hi, float(t["design"]["candidate_step_um"])))
    if n > pool:
        raise ConfigError(
            f"{path}: key 'training.design.positions': expected at most the {pool} candidate positions "
            f"of training.design.candidate_step_um ({t['design']['candidate_step_um']:g} µm) over the "
            f"stroke, got {n}"
        )
