"""What an XYΘ calibration brings to its stage's history (:mod:`calflow.lifecycle.history`).

Per model: the identified geometry (x_R, y_R in µm; α, β in degrees, Table 4.6) with the σ
and correlation of the identification (Sec. 4.5.2), free parameters first in the model's
order, and the held-out accuracy AP (µm, ISO 9283 Sec. 7.2.1, max over the held-out targets).
"""

from __future__ import annotations


def history_entry(summary: dict) -> dict:
    out = {}
    for name, m in (summary.get("models") or {}).items():
        params = m.get("parameters") or {}
        free = [
            next((k for k in params if k == f or k.startswith(f"{f}_")), None) for f in m.get("free") or []
        ]
        free = [k for k in free if k is not None]
        ordered = {k: {"value": params[k]["value"], "std": params[k].get("std")} for k in free}
        ordered.update({k: {"value": v["value"], "std": None} for k, v in params.items() if k not in ordered})
        corr = m.get("correlation")
        out[name] = {
            "parameters": ordered,
            "accuracy_um": m.get("accuracy_um"),
            "correlation": corr if corr is not None and len(corr) == len(free) else None,
        }
    return out
