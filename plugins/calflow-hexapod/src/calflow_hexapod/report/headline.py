"""The one figure the cross-campaign index lists for a hexapod campaign
(:attr:`calflow.family.Family.headline`): the last model of the ladder's held-out ISO 9283
position AP (µm)."""

from __future__ import annotations


def headline(summary: dict) -> dict | None:
    """``{"label", "key", "unit"}`` of the campaign's headline, or None when it has none."""
    models = summary.get("models") or {}
    for name in reversed(summary.get("model_order") or list(models)):
        if ((models.get(name) or {}).get("heldout") or {}).get("accuracy_um") is not None:
            return {
                "label": f"Model {name} held-out AP",
                "key": f"models.{name}.heldout.accuracy_um",
                "unit": "µm",
            }
    return None
