"""Which calibration came out best on the simulated rig, beside the thesis, and why.

A short paragraph generated from a nano summary's numbers — max AP per test type, the
robustness indices and the error budget after calibration (:mod:`calflow.nano.stage.error_budget`)
— never a fixed claim: whatever ordering the rig's physics gives is the one it states.
"""

from __future__ import annotations

from calflow.nano.stage.unseen.options import HEAT_SOURCES, TC_ERRORS

__all__ = ["ordering_block"]

_LABEL = {
    "no_calibration": "no calibration",
    "single": "the single model",
    "adaptive_kmz": "the adaptive KMZ model",
}
_THERMAL = ("stage_drift", "optics_drift", "expansion", "deadpath", "compensation", "walk")
# what each budget entry is, physically (docs/rigs.md has the sources)
_UNSEEN_DRIFT = (
    *HEAT_SOURCES,
    "mount_settling",
    "move_settling",
    "humidity_swelling",
    "sensor_air",
    "laser_wander",
)
_KIND = {
    **{e: "room drift the thermocouples follow" for e in _THERMAL},
    **{e: "heat the thermocouples do not see" for e in HEAT_SOURCES},
    "mount_settling": "mechanical settling",
    "move_settling": "mechanical settling",
    "humidity_swelling": "humidity",
    "sensor_air": "humidity and pressure at the capacitive sensor",
    **{e: "a thermocouple error the model reads as drift" for e in TC_ERRORS},
    "laser_wander": "the laser's wavelength",
    "periodic_nonlinearity": "interferometer nonlinearity",
    "turbulence": "air turbulence",
    "noise_and_estimation": "noise",
}


def _order(values: dict) -> list[str]:
    return sorted((k for k, v in values.items() if v is not None), key=lambda k: values[k])


def _largest(budget: dict, n: int = 3) -> list[tuple[str, float]]:
    effects = {k: v for k, v in budget.items() if k not in ("total", "interaction") and v is not None}
    return sorted(effects.items(), key=lambda kv: -kv[1])[:n]


def _rss(budget: dict, names) -> float:
    return sum((budget.get(e) or 0.0) ** 2 for e in names) ** 0.5


def ordering_block(tests: dict, robustness: dict, reference: dict, whose: str = "The thesis's") -> dict:
    """``{"order", "thesis_order", "agrees", "statement"}``: test types from best (smallest max AP)
    to worst on the rig and in the campaign's declared reference (``whose``: how the statement
    names it; no reference, no comparison), and the paragraph that explains the rig's from its
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
            f"{whose} order: "
            + ", ".join(f"{_LABEL.get(k, k)} (about {ref[k]:.0f} nm)" for k in thesis)
            + (" — the same." if thesis == order else " — a different one.")
        )
    for k in order:
        b = tests[k].get("error_budget_nm")
        top = _largest(b) if b else []
        if not top:
            continue
        words = [
            f"{n.replace('_', ' ')} ({nm:.0f} nm rms, {_KIND.get(n, 'a position term')})" for n, nm in top
        ]
        parts.append(
            f"At the held-out positions, what is left with {_LABEL.get(k, k)} (rms {b['total']:.0f} nm) is "
            f"mostly {', then '.join(words)}"
            + (
                f", partly cancelled by others (interaction {b['interaction']:.0f} nm)."
                if b.get("interaction", 0.0) < -0.5 * b["total"]
                else "."
            )
        )
    kmz, single = tests.get("adaptive_kmz"), tests.get("single")
    if kmz and single and kmz.get("error_budget_nm") and single.get("error_budget_nm"):
        bk, bs = kmz["error_budget_nm"], single["error_budget_nm"]
        th_k, th_s = _rss(bk, _THERMAL), _rss(bs, _THERMAL)
        un_k, un_s = _rss(bk, _UNSEEN_DRIFT), _rss(bs, _UNSEEN_DRIFT)
        tc_s = _rss(bs, TC_ERRORS)
        drift_s, drift_k = (th_s**2 + un_s**2 + tc_s**2) ** 0.5, (th_k**2 + un_k**2) ** 0.5
        parts.append(
            f"Drift left (root-sum-square): with the single model {th_s:.0f} nm of room drift the thermocouples "
            f"follow, {un_s:.0f} nm of drift they do not see (heat off their paths, settling, humidity, the laser) "
            f"and {tc_s:.0f} nm from their own errors; with KMZ {th_k:.0f} nm and {un_k:.0f} nm — "
            + (
                "the thermocouples, read at every pose, follow the rig's drift better than one KMZ visit per "
                "test, which misses the drift during the test"
                if drift_s < drift_k
                else "one KMZ visit per test measures the drift whatever causes it, while the thermocouples' "
                "regression can only follow what their readings span and carries their errors into the position"
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
