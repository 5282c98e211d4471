"""Checks of a hexapod campaign beyond its JSON Schema, run when the campaign is loaded
(the family's ``check`` step, :func:`calflow.configuration.campaign.load`) — what would otherwise
fail in a job after earlier jobs ran. Each raises :class:`~calflow.errors.ConfigError`
naming the file, the key and what was expected:

* every model is a rung of the ladder (:data:`calflow_hexapod.models.ladder.LADDER`): its
  name, or its ``rung``; the designed plan's ``design.model`` too;
* a designed plan picks at most as many poses as it has candidates, and reads with some
  noise (the design weighs each pose by the reading's σ: with none at all it has no scale);
* the ISO 9283 poses lie inside the workspace with the stroke margin every validation
  keeps (:func:`calflow_hexapod.plans.poses.iso9283_commands`);
* the simulated payload compresses the legs by less than that margin: a model absorbs the
  compliance, and the commands it computes for targets near the edge of the workspace would
  leave it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from calflow.errors import ConfigError


def check(c, args) -> None:
    """The family's step hook ``check(c, args)`` (:mod:`calflow.family_contract`): the campaign
    ``c`` loaded from the file ``args.campaign``, checked beyond its schema (it resolves
    nothing: None)."""
    check_campaign(c, args.campaign)


def check_campaign(campaign: dict, path: Path) -> None:
    """Raise :class:`ConfigError` naming the file and key when the campaign cannot run."""
    from calflow_hexapod.models.ladder import LADDER

    models = campaign["models"]
    for name, spec in models.items():
        rung = spec.get("rung", name)
        if rung not in LADDER:
            raise ConfigError(
                f"{path}: key 'models.{name}': expected a model of the ladder ({', '.join(LADDER)}) "
                f"or one with 'rung: <one of them>', got {name!r}"
            )
    ident = campaign["identification"]
    if ident["plan"] == "optimal":
        _check_design(campaign, path, LADDER)
    _check_iso9283(campaign, path)
    _check_payload(campaign, path)


def _check_design(campaign: dict, path: Path, ladder: dict) -> None:
    from calflow_hexapod.plans.noise import noise_model

    ident = campaign["identification"]
    d = ident.get("design") or {}
    model = d.get("model", "geometric")
    if (campaign["models"].get(model) or {}).get("rung", model) not in ladder:
        raise ConfigError(
            f"{path}: key 'identification.design.model': expected one of the campaign's models "
            f"{sorted(campaign['models'])} or of the ladder ({', '.join(ladder)}), got {model!r}"
        )
    candidates, key = d.get("candidates", 2000), "identification.design.poses"
    poses = d.get("poses")
    if poses is None:
        poses, key = ident["poses"], "identification.poses"
    if poses > candidates:
        raise ConfigError(
            f"{path}: key '{key}': expected at most identification.design.candidates ({candidates}) "
            f"designed poses, got {poses}"
        )
    noise = noise_model(campaign)
    if noise is not None and not any(v > 0 for v in noise.values()):
        given = "noise" in d
        sim = "rig.options" if campaign["rig"]["factory"] == "simulated" else "rig.options.sensor.options"
        raise ConfigError(
            f"{path}: key '{'identification.design.noise' if given else sim}': expected "
            "a reading noise > 0 in position, angle or leg length (the design weighs each pose by "
            f"it), got {noise} {'as given' if given else 'from the simulated tracker and legs'}"
        )


def _check_iso9283(campaign: dict, path: Path) -> None:
    from calflow_hexapod.plans.poses import iso9283_commands

    s = campaign.get("iso9283")
    if not s:
        return
    try:
        iso9283_commands(float(s["fraction"]), s.get("orientation_deg", (0.0, 0.0, 0.0)))
    except ValueError as exc:
        key = "iso9283.orientation_deg" if "orientation_deg" in s else "iso9283.fraction"
        detail = str(exc).split(": ", 1)[-1]
        raise ConfigError(f"{path}: key '{key}': {detail}") from None


def _check_payload(campaign: dict, path: Path) -> None:
    from calflow_hexapod.models.geometry import H811_TRAVEL
    from calflow_hexapod.plans.poses import MARGIN_UM
    from calflow_hexapod.stage.physics import truth_from_options
    from calflow_hexapod.stage.run_options import simulated_physics

    physics = simulated_physics(campaign)
    if not physics or not {"payload_kg", "payload_com_um"} & set(physics):
        return
    truth = truth_from_options(physics)
    extremes = np.vstack([np.zeros(6), np.diag(H811_TRAVEL), -np.diag(H811_TRAVEL)])
    worst = float(np.abs(truth.compliance(extremes)).max())
    if worst > MARGIN_UM:
        where = "rig.options" if campaign["rig"]["factory"] == "simulated" else "rig.options.sensor.options"
        raise ConfigError(
            f"{path}: key '{where}.payload_kg': expected a payload the legs hold within the "
            f"{MARGIN_UM:g} µm of stroke the validation keeps free, got {physics.get('payload_kg')!r} kg "
            f"(the legs shorten by up to {worst:.4g} µm over the travel)"
        )
