"""The one figure the cross-campaign index lists for an XYΘ campaign
(:attr:`calflow.family.Family.headline`): the last model's ISO 9283 AP (µm), on the held-out
targets when the campaign drew them, else on the reference targets (Table 4.7); an interim
check's AP through the calibration's bundle."""

from __future__ import annotations


def headline(summary: dict) -> dict | None:
    """``{"label", "key", "unit"}`` of the campaign's headline, or None when it has none."""
    check = summary.get("interim_check")
    if check:
        return {
            "label": f"interim check AP through Model {check.get('model')}",
            "key": "interim_check.accuracy_um",
            "unit": "µm",
        }
    models = summary.get("models") or {}
    for name in reversed(list(models)):
        entry = models[name] or {}
        if entry.get("accuracy_um") is not None:
            where = "held-out" if entry.get("protocol") == "heldout" else "reference targets"
            return {"label": f"Model {name} AP, {where}", "key": f"models.{name}.accuracy_um", "unit": "µm"}
    return None
