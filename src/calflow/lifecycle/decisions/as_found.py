"""As found and as left in a stage's history, and the history's ``interval`` from them.

A calibration's summary carries per model ``as_left = {accuracy_um, repeatability_um, date}``
(what it left the stage with) and, when it measured the stage first through the
compensation in use, ``as_found = {accuracy_um, repeatability_um, date, reference}``; an
interim check is an as-found value on its own targets. Here they are carried into the
history's entries, paired (each value found with the as-left value of the adjustment it was
found through) and handed to :mod:`calflow.lifecycle.decisions.interval` — the variables method on the
deviations and the exponential model on the decisions — with every input kept, so another
RP-1 tool recomputes the interval from ``history.json`` alone (docs/lifecycle.md).
"""

from __future__ import annotations

import datetime as dt

import numpy as np

from calflow.lifecycle.decisions.interval import (
    ATTRIBUTES,
    VARIABLES,
    add_days,
    attributes,
    check_settings,
    variables,
)


def _days(a: str, b: str) -> float:
    ta = dt.datetime.fromisoformat(str(a).replace("Z", "+00:00"))
    tb = dt.datetime.fromisoformat(str(b).replace("Z", "+00:00"))
    return (tb - ta).total_seconds() / 86400.0


def _number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and bool(np.isfinite(v))


def as_found_values(entries: list[dict], segments: list[int], model: str) -> list[dict]:
    """Every value of ``model`` found through an earlier adjustment, in time order:
    ``{campaign, reference, interim_check, days, as_found_um, as_left_um, level, decision}``
    (``level``: the segment of the value when a detected change lies between its adjustment
    and it, else 0; ``decision``: an interim check's). A value whose reference has no dated
    as-left value of the model is left out (nothing to subtract from)."""
    by_name = {e["campaign"]: i for i, e in enumerate(entries)}
    out = []
    for i, e in enumerate(entries):
        found = (e["models"].get(model) or {}).get("as_found")
        if not found or not _number(found.get("accuracy_um")):
            continue
        j = by_name.get(found.get("reference"))
        left = (entries[j]["models"].get(model) or {}).get("as_left") if j is not None else None
        if not left or not _number(left.get("accuracy_um")) or not left.get("date") or not found.get("date"):
            continue
        days = _days(left["date"], found["date"])
        if days <= 0:
            continue
        out.append(
            {
                "campaign": e["campaign"],
                "reference": found["reference"],
                "interim_check": e["kind"] == "interim",
                "days": days,
                "as_found_um": float(found["accuracy_um"]),
                "as_left_um": float(left["accuracy_um"]),
                "level": int(segments[i]) if segments[i] != segments[j] else 0,
                "decision": e.get("decision"),
            }
        )
    return out


def from_history(
    entries: list[dict], segments: list[int], model: str | None, tol, reliability: float
) -> dict:
    """history.json's ``interval``: V1 on the as-found values of ``model`` with its inputs, and
    ``attributes``, the exponential model on their in/out-of-tolerance decisions (a calibration's
    as-found AP against the tolerance, an interim check's decision; an undecided check, and a
    value found after a detected change — a step, not the drift R(t) describes — are left
    out). Dates: the interval counted from the latest as-left value of ``model``."""
    check_settings(reliability, tol, "stage settings")
    head = {"method": VARIABLES, "model": model, "date": None, "interval_days": None}
    head.update({"reliability": reliability, "tolerance_um": tol})
    attr = {"method": ATTRIBUTES, "date": None, "interval_days": None, "reliability": reliability}
    attr["tolerance_um"] = tol
    values = as_found_values(entries, segments, model) if model is not None else []
    lefts = [
        (e["campaign"], e["models"][model]["as_left"])
        for e in entries
        if e["kind"] == "calibration"
        and _number(((e["models"].get(model) or {}).get("as_left") or {}).get("accuracy_um"))
        and e["models"][model]["as_left"].get("date")
    ]
    inputs = {
        "days_since_adjustment": [v["days"] for v in values],
        "as_found_minus_as_left": [v["as_found_um"] - v["as_left_um"] for v in values],
        "as_found_um": [v["as_found_um"] for v in values],
        "as_left_um": [v["as_left_um"] for v in values],
        "campaign": [v["campaign"] for v in values],
        "reference": [v["reference"] for v in values],
        "interim_check": [v["interim_check"] for v in values],
        "level": [v["level"] for v in values],
    }
    out = {**head, "inputs": inputs, "fit": {}}
    if model is None or tol is None:
        why = (
            "no watched model"
            if model is None
            else "no tolerance stated (tolerance_um in the stage's settings or a campaign)"
        )
        no = {"days_since_adjustment": [], "in_tolerance": [], "campaign": []}
        return {**out, "statement": why, "attributes": {**attr, "statement": why, "inputs": no}}
    if not lefts:
        out["statement"] = f"not enough history: no as-left value of model {model}"
    else:
        campaign, left = lefts[-1]
        out["as_left"] = {
            "campaign": campaign,
            "accuracy_um": float(left["accuracy_um"]),
            "date": left["date"],
        }
        res = variables(
            inputs["days_since_adjustment"],
            inputs["as_found_minus_as_left"],
            tol,
            float(left["accuracy_um"]),
            reliability,
            checks=inputs["interim_check"],
            levels=inputs["level"],
        )
        out.update(res)
        out["date"] = add_days(left["date"], res["interval_days"])
    stepped = [v for v in values if v["level"] > 0]  # a re-mount is an event, not the drift R(t) models
    usable = [v for v in values if v["level"] == 0]
    decided = [
        v for v in usable if not v["interim_check"] or v["decision"] in ("within tolerance", "recalibrate")
    ]
    ok = [
        (v["decision"] == "within tolerance") if v["interim_check"] else (v["as_found_um"] <= tol)
        for v in decided
    ]
    a_inputs = {
        "days_since_adjustment": [v["days"] for v in decided],
        "in_tolerance": ok,
        "campaign": [v["campaign"] for v in decided],
    }
    a = attributes(a_inputs["days_since_adjustment"], ok, reliability)
    left_out = []
    if len(usable) > len(decided):
        left_out.append(f"{len(usable) - len(decided)} undecided interim check(s)")
    if stepped:
        left_out.append(f"{len(stepped)} value(s) found after a detected change")
    if left_out:
        a["statement"] += f" ({' and '.join(left_out)} left out)"
    out["attributes"] = {**attr, **a, "inputs": a_inputs}
    if lefts:
        out["attributes"]["date"] = add_days(lefts[-1][1]["date"], a["interval_days"])
    return out


def interim_as_found(campaign: dict, check: dict) -> dict:
    """An interim check's as-found value: its AP and RP on its own targets through the
    reference's bundle, on the check's date."""
    given = check.get("as_found")
    if isinstance(given, dict):
        return given
    return {
        "accuracy_um": check.get("accuracy_um"),
        "repeatability_um": check.get("repeatability_um"),
        "date": campaign["start"],
        "reference": check.get("reference"),
    }


def carry_as_found(models: dict, summary: dict) -> None:
    """Copy ``as_found`` and ``as_left`` of each model from a calibration's summary
    (``models.<M>.as_found``, ``.as_left``; the top-level ``as_found`` of a model the campaign
    did not identify again) into its history entry."""
    given = summary.get("models")
    given = given if isinstance(given, dict) else {}  # a family may keep a list there
    for m, entry in models.items():
        block = given.get(m) if isinstance(given.get(m), dict) else {}
        for key in ("as_found", "as_left"):
            if isinstance(block.get(key), dict):
                entry[key] = block[key]
    top = summary.get("as_found")  # the model in use, when the campaign did not identify it again
    if isinstance(top, dict) and top.get("model") and top["model"] not in models:
        keys = ("accuracy_um", "repeatability_um", "date", "reference")
        models[top["model"]] = {"as_found": {k: top.get(k) for k in keys}}


def due(found: dict) -> dict | None:
    """history.json's ``due`` from the interval: V1 when it can fit, else the attributes
    model when it gives an interval, else the reasons of both; None without any as-found
    value (the history then keeps the trend of the as-left AP)."""
    if not found.get("inputs", {}).get("days_since_adjustment"):
        return None
    a = found["attributes"]
    base = {
        "tolerance_um": found["tolerance_um"],
        "model": found["model"],
        "reliability": found["reliability"],
    }
    if found.get("coverage_factor") is not None:
        out = {**base, "date": found["date"], "method": found["method"], "statement": found["statement"]}
        out["fit"] = found["fit"]
        left = found["as_left"]
        out["trend"] = {
            "dates": [add_days(left["date"], d) for d in found["trend"]["days"]],
            "mean_um": found["trend"]["mean_um"],
            "upper_um": found["trend"]["upper_um"],
        }
        return out
    if a.get("interval_days") is not None and a.get("date"):
        return {**base, "date": a["date"], "method": a["method"], "statement": a["statement"]}
    both = (
        found["statement"]
        if a["statement"] == found["statement"]
        else f"{found['statement']}; attributes: {a['statement']}"
    )
    return {**base, "date": None, "method": found["method"], "statement": both}
