"""The one figure the cross-campaign index lists for a nano-stage campaign
(:attr:`calflow.family.Family.headline`): the best calibration's max ISO 9283 AP over the
validation (nm, thesis Sec. 5.3.3); without a validation, the metrology run's intrinsic AP,
or the training run's AP."""

from __future__ import annotations

from calflow.family import modes


def headline(summary: dict) -> dict | None:
    """``{"label", "key", "unit"}`` of the campaign's headline, or None when it has none."""
    tests = {
        name: t["max_accuracy_nm"]
        for name, t in (summary.get("tests") or {}).items()
        if isinstance(t, dict) and t.get("max_accuracy_nm") is not None
    }
    calibrated = {k: v for k, v in tests.items() if k != "no_calibration"} or tests
    if calibrated:
        best = min(calibrated, key=calibrated.get)
        return {
            "label": f"max AP, {modes().get(best, best.replace('_', ' '))}",
            "key": f"tests.{best}.max_accuracy_nm",
            "unit": "nm",
        }
    for block, label in (("intrinsic", "intrinsic AP"), ("training", "training-run AP")):
        if (summary.get(block) or {}).get("accuracy_nm") is not None:
            return {"label": label, "key": f"{block}.accuracy_nm", "unit": "nm"}
    return None
