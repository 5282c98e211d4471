"""Checks of an XYΘ campaign beyond its JSON Schema: the model table and the table strokes."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from calflow.configuration.campaign import Campaign, Interim, Resolution
from calflow.errors import ConfigError, OptionError


def check(c, args) -> Resolution | None:
    """The family's step hook ``check(c, args)`` (:mod:`calflow.family_contract`): the campaign
    ``c`` loaded from the file ``args.campaign``, checked beyond its schema; returns what it
    resolves."""
    return check_campaign(c, args.campaign)


def check_campaign(campaign: Mapping, path: Path) -> Resolution | None:
    """Raise :class:`ConfigError` naming the file and key when the campaign is inconsistent;
    return what the check resolves (:class:`~calflow.configuration.campaign.Resolution`: the simulated
    stage as it has aged by the campaign's start, an interim check's reference), changing
    nothing."""
    rig = None
    if campaign["rig"]["factory"] == "simulated":  # the stage as it has aged by the campaign's start
        from calflow.xytheta.stage.aging import resolve
        from calflow.xytheta.stage.physics import XYThetaTruth

        options = campaign["rig"].get("options") or {}
        try:
            rig = {**campaign["rig"], "options": resolve(options, campaign["start"], XYThetaTruth())}
        except OptionError as exc:
            raise ConfigError(exc.at(path, "rig.options")) from None
        campaign = {**campaign, "rig": rig}  # the later checks see the stage as aged
    if "as_found" in campaign:  # the compensation in use, measured before the recalibration
        from calflow.xytheta.plans.as_found import check

        check(campaign, Path(path))
    if "interim_check" in campaign:
        interim, ref = _check_interim(campaign, Path(path))
        from calflow.xytheta.plans.interim_load import check_rig_time, check_tolerance

        section = {**campaign["interim_check"], "dwell_s": interim.dwell_s}
        resolved = {**campaign, "models": {}, "interim_check": section}
        check_tolerance(resolved, Path(path))
        check_rig_time(resolved, Path(path), ref)
        return Resolution(rig=rig, models={}, interim=interim, reference=ref)
    if "models" not in campaign:
        raise ConfigError(
            f"{path}: key 'models': missing, it is required (the models to identify), unless the "
            "campaign is an interim_check"
        )
    _check_models(campaign["models"], path)
    _check_design(campaign, path)
    _check_recordings(campaign, path)
    if any(spec.get("position_table") for spec in campaign["models"].values()):
        ident, char = campaign["identification"], campaign["characterisation"]
        for axis in ("x", "y"):
            if ident[f"{axis}_um"][1] > char[f"{axis}_stop_um"]:
                raise ConfigError(
                    f"{path}: key 'identification.{axis}_um': expected poses within the characterised stroke "
                    f"(characterisation.{axis}_stop_um = {char[f'{axis}_stop_um']}) for the position tables, "
                    f"got up to {ident[f'{axis}_um'][1]}"
                )
    return Resolution(rig=rig) if rig is not None else None


def _check_recordings(campaign: dict, path: Path) -> None:
    """A replay's recordings (a mapping run id -> recording) are of runs the campaign acquires:
    a misspelt run id would be a recording nothing reads, beside a run with none."""
    recordings = (campaign["rig"].get("options") or {}).get("recordings")
    if campaign["rig"]["factory"] != "replay" or not isinstance(recordings, dict):
        return
    from calflow.xytheta.plans.workflow import XYThetaWorkflow

    runs = {Path(f).stem for f in XYThetaWorkflow().all_runs({**campaign, "name": Path(path).stem})}
    for run in recordings:
        if run not in runs:
            raise ConfigError(
                f"{path}: key 'rig.options.recordings.{run}': expected a run this campaign acquires "
                f"(one of {', '.join(sorted(runs))}), got {run!r}"
            )


def _check_models(models: dict, path: Path) -> None:
    """Each model is identified (``free``) or built on another (``base`` + ``angle_table``)."""
    for name, spec in models.items():
        if ("free" in spec) == ("base" in spec):
            raise ConfigError(
                f"{path}: key 'models.{name}': expected either 'free' (identified) or "
                "'base' with 'angle_table: true' (post-calibration), not both or neither"
            )
        if "base" in spec:
            base = spec["base"]
            if base not in models:
                raise ConfigError(
                    f"{path}: key 'models.{name}.base': expected one of {sorted(models)}, got {base!r}"
                )
            if "base" in models[base]:
                raise ConfigError(
                    f"{path}: key 'models.{name}.base': model {base!r} has a base itself; "
                    "expected an identified model"
                )
            if not spec.get("angle_table"):
                raise ConfigError(
                    f"{path}: key 'models.{name}.angle_table': expected true for a model with a base"
                )


def _check_design(campaign: dict, path: Path) -> None:
    """The designed plan maximises the information of an identified model, under a known noise model."""
    ident = campaign["identification"]
    d = ident["design"]
    spec = campaign["models"].get(d["model"])
    if ident["plan"] == "optimal" or "design_study" in campaign:
        if spec is None or "free" not in spec:
            usable = sorted(k for k, s in campaign["models"].items() if "free" in s)
            raise ConfigError(
                f"{path}: key 'identification.design.model': expected an identified model "
                f"(one of {usable}), got {d['model']!r}"
            )
        given = d["noise_um"]
        if campaign["rig"]["factory"] != "simulated" and (
            given.get("pose") is None or given.get("frame") is None
        ):
            raise ConfigError(
                f"{path}: key 'identification.design.noise_um': expected pose and frame (um) "
                "for a rig other than the simulated one"
            )
        if d.get("poses") is not None and d["poses"] > d["candidates"]:
            raise ConfigError(
                f"{path}: key 'identification.design.poses': expected at most design.candidates "
                f"({d['candidates']}), got {d['poses']}"
            )


def _check_interim(campaign: Mapping, path: Path) -> tuple[Interim, Campaign]:
    """An interim check identifies nothing; its reference is an earlier calibration of the same
    stage and robot, in the same folder, that identifies ``interim_check.model``. Resolved
    here, as the rig's ageing is: the reference's identification workspace (where the check's
    targets are chosen), every run of the reference (its rig time) and the dwell (the
    reference's validation dwell unless given); returned with the reference."""
    from calflow.configuration.campaign import load
    from calflow.lifecycle.stages import check_after, check_reference
    from calflow.xytheta.plans.workflow import WORKFLOW

    if campaign.get("models"):
        raise ConfigError(f"{path}: key 'models': an interim check identifies no model; remove the key")
    check = campaign["interim_check"]
    # itself, a missing file, another check, robot, stage, a reference that starts later:
    # refused on the raw file, before loading it (a cycle of references would load forever)
    check_reference(campaign, path, "interim_check.reference", check["reference"])
    ref = load(path.parent / f"{check['reference']}.yaml")
    check_after(campaign, path, check["reference"], ref["start"])  # its start may be the default
    if check["model"] not in ref["models"]:
        raise ConfigError(
            f"{path}: key 'interim_check.model': expected one of the reference's models "
            f"{sorted(ref['models'])}, got {check['model']!r}"
        )
    ident = ref["identification"]
    interim = Interim(
        reference=check["reference"],
        model=check["model"],
        dwell_s=check.get("dwell_s", ref["validation"]["dwell_s"]),  # visits settle as the reference's did
        workspace={k: list(ident[k]) for k in ("x_um", "y_um", "theta_deg")},
        runs=tuple(WORKFLOW.all_runs(ref)),
    )
    return interim, ref
