"""What a nano-stage calibration brings to its stage's history (:mod:`calflow.lifecycle.history`).

Per model: the coefficients the model kept (Eq. (5.3)–(5.5); units in the summary) with
their standard errors, and the held-out accuracy, the maximum AP over the validation
positions no training visited (nm in the summary, µm here). The summary gives no
correlation of the coefficients: the history's change test then uses their σ alone,
which the report says.
"""

from __future__ import annotations

#: The validation mode that runs each model (a 2-DoF stage's model runs as ``single``).
_MODE = {"two_dof": "single"}


def history_entry(summary: dict) -> dict:
    out = {}
    tests = summary.get("tests") or {}
    for name, coefficients in (summary.get("models") or {}).items():
        kept = [c for c in coefficients if c.get("in_model")]
        params = {c["name"]: {"value": c["value"], "std": c.get("std_error")} for c in kept}
        test = tests.get(_MODE.get(name, name)) or {}
        nm = test.get("heldout_max_accuracy_nm", test.get("max_accuracy_nm"))
        out[name] = {
            "parameters": params,
            "correlation": None,
            "accuracy_um": nm / 1000.0 if isinstance(nm, (int, float)) else None,
        }
    return out
