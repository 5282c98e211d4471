"""The as-found run of a recalibration: the stage measured through the compensation in use.

Before a calibration adjusts anything, a stage that has an earlier calibration is measured
as it was used: the campaign's own held-out targets (the same targets, in the same order,
its held-out validation will visit through the new model, :func:`calflow.xytheta.plans.
campaign.validation_heldout`) commanded in closed loop through the exported bundle of the
earlier calibration's model (``results/<reference>/export/<model>/``), exactly as that
calibration's own closed-loop check and the interim checks command their targets
(:func:`calflow.xytheta.export.verification.export_plan`, bundle path only: home first,
then ``validation.heldout.cycles`` visits of each target). Its ISO 9283 AP and RP are the
*as-found* values; the held-out validation through the new model gives the *as-left* ones
(docs/lifecycle.md, "As found, as left").

Opt-in per campaign (``as_found: {reference, model}``): which compensation the stage ran is
a fact of the lab, not something the files can tell (a lab may have loaded another model
than the most accurate one). Refused at load, one line naming the key: a reference that is
not a campaign of the same folder, is an interim check, belongs to another stage, does not
start before this campaign, or has no exported bundle of ``model`` (does not identify it);
``as_found`` on an interim check (it is an as-found measurement already).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from calflow.errors import CalflowError, ConfigError
from calflow.plan import Acquisition


def check(campaign: dict, path: Path) -> None:
    """Refuse an ``as_found`` section that cannot run (module docstring), one line each."""
    spec = campaign.get("as_found")
    if spec is None:
        return
    if "interim_check" in campaign:
        raise ConfigError(
            f"{path}: key 'as_found': an interim check measures through the bundle in use already; remove the key"
        )
    if campaign.get("stage") is None:
        raise ConfigError(
            f"{path}: key 'as_found': expected a campaign of a stage (key 'stage'), whose earlier "
            "calibration's compensation was in use"
        )
    from calflow.lifecycle.stages import check_reference

    # another campaign of the folder, of the same robot and stage, starting earlier; read as it
    # is written (a chain or a cycle of references is refused there, not loaded without end)
    ref = check_reference(campaign, path, "as_found.reference", spec["reference"])
    if spec["model"] not in (ref.get("models") or {}):
        raise ConfigError(
            f"{path}: key 'as_found.model': expected a model whose bundle {spec['reference']!r} exports "
            f"(one of {sorted(ref.get('models') or {})}), got {spec['model']!r}: no exported bundle"
        )


def heldout_target_rows(c: dict) -> np.ndarray:
    """(n, 3) held-out targets of campaign ``c``: x_T, y_T (µm, world frame), Θ_T (degree), in
    the order its held-out validation visits them."""
    from calflow.xytheta.models.kinematics import Parameters
    from calflow.xytheta.plans.campaign import heldout_seed
    from calflow.xytheta.plans.poses import heldout_targets

    p, h = c["identification"], c["validation"]["heldout"]
    return np.asarray(
        heldout_targets(
            h["targets"], p["x_um"], p["y_um"], p["theta_deg"], Parameters(**p["initial"]), heldout_seed(c)
        ),
        float,
    )


def as_found(c: dict, args) -> Acquisition:
    """``calflow acquire --plan as_found --export DIR``: the campaign's held-out targets through
    the bundle of DIR (the reference's export of ``as_found.model``)."""
    from calflow.xytheta.export.verification import export_plan

    spec = c.get("as_found")
    if not spec:
        raise CalflowError(f"calflow acquire --plan as_found: campaign {c['name']} has no 'as_found' section")
    folder = getattr(args, "export", None)
    if not folder:
        raise CalflowError(
            "calflow acquire --plan as_found: --export DIR (the earlier calibration's export of the model in use) is required"
        )
    if not Path(folder).is_dir():
        raise CalflowError(
            f"calflow acquire --plan as_found: {folder}: no exported bundle of model {spec['model']} "
            f"of {spec['reference']}; run that campaign's export first"
        )
    h = c["validation"]["heldout"]
    plan, _ = export_plan(
        folder, heldout_target_rows(c), int(h["cycles"]), c["validation"]["dwell_s"], paths=("bundle",)
    )
    return Acquisition(
        dataclasses.replace(plan, name="as_found"),
        "as_found",
        spec["model"],
        attrs={
            "as_found_reference": spec["reference"],
            "export_paths": "bundle",
            "export_cycles": int(h["cycles"]),
        },
    )
