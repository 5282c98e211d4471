"""The physics options of a campaign whose stage is simulated (kept free of numerical imports).

A campaign runs a simulated stage either directly (``rig: {factory: simulated, options}``)
or behind an emulated controller (``rig: {factory: gcs, options: {sensor: {factory: S,
options}}}``, S the family's simulated sensor, which carries the physics). Either way the
physics are the same options; :func:`simulated_options` finds them.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any


def simulated_options(
    campaign: Mapping[str, Any],
    sensors: Iterable[str],
    drop: Iterable[str] = ("seed", "stream"),
    run: str | None = None,
) -> dict[str, Any] | None:
    """The physics options of ``campaign``'s simulated stage: the ``simulated`` rig's options
    (with the run overrides ``rig.runs[run]``), or the options of a ``gcs`` rig's sensor when
    its factory is one of ``sensors``; without the keys ``drop`` (seeds, streams: a run's, not
    the stage's). None when the stage is behind a controller whose sensor is another."""
    rig = campaign.get("rig") or {}
    runs = rig.get("runs") or {}
    options = {**(rig.get("options") or {}), **((runs.get(run) or {}) if run is not None else {})}
    if rig.get("factory", "simulated") != "simulated":
        sensor = options.get("sensor") or {}
        if sensor.get("factory") not in tuple(sensors):
            return None
        options = dict(sensor.get("options") or {})
    drop = tuple(drop)
    return {k: v for k, v in options.items() if k not in drop}
