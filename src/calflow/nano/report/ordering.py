"""Which calibration came out best on the simulated rig, beside the thesis, and why (error budget).

A short paragraph generated from a nano summary's numbers — max AP per test type, the
robustness indices and the error budget after calibration (:mod:`calflow.nano.stage.error_budget`)
— never a fixed claim: whatever ordering the rig's physics gives is the one it states.
"""

from __future__ import annotations

__all__ = ["ordering_block"]

_LABEL = {
    "no_calibration": "no calibration",
    "single": "the single model",
    "adaptive_kmz": "the adaptive KMZ model",
}
_THERMAL = ("stage_drift", "optics_drift", "expansion", "deadpath", "compensation", "walk")


def _order(values: dict) -> list[str]:
    return sorted((k for k, v in values.items() if v is not None), key=lambda k: values[k])


def _largest(budget: dict) -> tuple[str, float] | None:
    effects = {k: v for k, v in budget.items() if k not in ("total", "interaction") and v is not None}
    return max(effects.items(), key=lambda kv: kv[1]) if effects else None


def ordering_block(tests: dict, robustness: dict, reference: dict) -> dict:
    """``{"order", "thesis_order", "agrees", "statement"}``: test types from best (smallest max AP)
    to worst on the rig and in the thesis, and the paragraph that explains the rig's from its
    error budgets (``tests.<t>.error_budget_nm``, when present)."""
    ap = {k: t.get("max_accuracy_nm") for k, t in tests.items()}
    order = _order(ap)
    ref = {k: v.get("max_accuracy_nm") for k, v in (reference.get("tests") or {}).items() if k in ap}
    thesis = _order(ref)
    parts = [
        "On this rig, from best to worst max AP over the validation: "
        + ", ".join(f"{_LABEL.get(k, k)} ({ap[k]:.0f} nm)" for k in order)
        + "."
    ]
    if thesis:
        parts.append(
            "The thesis's order: "
            + ", ".join(f"{_LABEL.get(k, k)} (about {ref[k]:.0f} nm)" for k in thesis)
            + (" — the same." if thesis == order else " — a different one.")
        )
    for k in order:
        b = tests[k].get("error_budget_nm")
        top = _largest(b) if b else None
        if top is None:
            continue
        name, nm = top
        kind = "thermal" if name in _THERMAL else "noise" if name == "noise_and_estimation" else "position"
        parts.append(
            f"At the held-out positions, what is left with {_LABEL.get(k, k)} (rms {b['total']:.0f} nm) is "
            f"mostly {name.replace('_', ' ')} ({nm:.0f} nm rms, a {kind} term)"
            + (
                f", partly cancelled by others (interaction {b['interaction']:.0f} nm)."
                if b.get("interaction", 0.0) < -0.5 * b["total"]
                else "."
            )
        )
    kmz, single = tests.get("adaptive_kmz"), tests.get("single")
    if kmz and single and kmz.get("error_budget_nm") and single.get("error_budget_nm"):
        th_k = sum(kmz["error_budget_nm"].get(e, 0.0) ** 2 for e in _THERMAL) ** 0.5
        th_s = sum(single["error_budget_nm"].get(e, 0.0) ** 2 for e in _THERMAL) ** 0.5
        better = "single" if th_s < th_k else "adaptive_kmz"
        parts.append(
            f"Thermal terms left (root-sum-square): {th_s:.0f} nm rms with the single model, {th_k:.0f} nm with KMZ — "
            + (
                "the thermocouples, read at every pose, follow the rig's drift better than one KMZ visit per "
                "test, which misses the drift during the test"
                if better == "single"
                else "one KMZ visit per test follows the drift better than the thermocouples, whose readings "
                "do not span what the drift depends on"
            )
            + "."
        )
    r = {k: v.get("time") for k, v in (robustness or {}).items()}
    if all(v is not None for v in r.values()) and r:
        parts.append(
            "Time robustness R_T from best to worst: " + ", ".join(_LABEL.get(k, k) for k in _order(r)) + "."
        )
    return {
        "order": order,
        "thesis_order": thesis,
        "agrees": thesis == order if thesis else None,
        "statement": " ".join(parts),
    }
