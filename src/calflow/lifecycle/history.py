"""A stage's history (``results/stages/<id>/history.json``) from its campaigns' summaries.

Each campaign's numbers come from its robot family (``Family.history_entry``, a
``"module:function"``; ``function(summary) -> {model: {parameters: {p: {value, std}},
correlation, accuracy_um}}`` where ``correlation`` is over the parameters with a positive
σ, in the order of ``parameters``). An interim check's summary carries ``interim_check:
{model, accuracy_um, decision, …}`` and enters the history with its accuracy only.

The history holds, in time order, every campaign of the stage whose results are on disk
(:mod:`calflow.lifecycle.members`), and those that left it with the reason; between consecutive calibrations the
change test (:mod:`calflow.lifecycle.decisions.change`); control charts (:mod:`calflow.lifecycle.decisions.charts`);
and the due date (:mod:`calflow.lifecycle.decisions.due`).
"""

from __future__ import annotations

import numpy as np

from calflow.errors import CalflowError
from calflow.family import family_of, resolve
from calflow.lifecycle.decisions import as_found, change, charts, due, interval

DEFAULTS = {"alpha": 0.05, "reliability": 0.95, "min_pairs": 3, "model": None, "tolerance_um": None}


def entry(campaign: dict, summary: dict) -> dict:
    """``campaigns[i]`` of the history: ``{campaign, start, kind, models}``."""
    base = {"campaign": campaign["name"], "start": campaign["start"], "robot": campaign["robot"]}
    if campaign.get("tolerance_um") is not None:
        base["tolerance_um"] = campaign["tolerance_um"]
    if campaign.get("note"):  # known from the earlier history or its summary, not its campaign file
        base["note"] = campaign["note"]
    if "interim_check" in summary:
        check = summary["interim_check"]
        found = as_found.interim_as_found(campaign, check)
        return {
            **base,
            "kind": "interim",
            "reference": check.get("reference"),
            "decision": check.get("decision"),
            "models": {check["model"]: {"accuracy_um": check.get("accuracy_um"), "as_found": found}},
        }
    family = family_of(campaign["robot"])
    target = getattr(family, "history_entry", None)
    if not target:
        raise CalflowError(
            f"stage history: the {family.name} family does not describe its campaigns for a "
            f"history (no history_entry); campaign {campaign['name']!r} cannot enter one"
        )
    models = resolve(target)(summary)
    as_found.carry_as_found(models, summary)
    return {**base, "kind": "calibration", "models": models}


def estimate(model: dict) -> change.Estimate:
    """The free parameters (positive σ) of one model of one campaign with their covariance."""
    names = tuple(p for p, v in model["parameters"].items() if v.get("std") and v["std"] > 0)
    value = np.array([model["parameters"][p]["value"] for p in names], float)
    std = np.array([model["parameters"][p]["std"] for p in names], float)
    corr = np.asarray(model.get("correlation") or np.eye(len(names)), float)
    if corr.shape != (len(names), len(names)):
        corr = np.eye(len(names))  # no usable correlation: the σ alone (said in the report)
    return change.Estimate(names, value, corr * np.outer(std, std))


def _segments(entries: list[dict], changes: list[dict]) -> list[int]:
    """Segment index of every entry: a new segment starts where a detected change shows first.

    A change is detected at a calibration flagged by the change test; it shows first at the
    earliest interim check since the calibration before that decided "recalibrate" (the
    check saw the step the calibration confirmed), else at the flagged calibration itself. A
    "recalibrate" check that no flagged calibration confirms (the stage drifted, or no
    calibration came yet) starts nothing: its value stays on the segment's trend.
    """
    flagged = {c["to"] for c in changes if any(m["significant"] for m in c["models"].values())}
    starts: set[int] = set()
    first_alarm = None  # the earliest "recalibrate" check since the last calibration
    for i, e in enumerate(entries):
        if e["kind"] == "calibration":
            if e["campaign"] in flagged:
                starts.add(first_alarm if first_alarm is not None else i)
            first_alarm = None
        elif e.get("decision") == "recalibrate" and first_alarm is None:
            first_alarm = i
    seg, out = 0, []
    for i in range(len(entries)):
        seg += i in starts
        out.append(seg)
    return out


def _due_model(entries: list[dict], settings: dict) -> str | None:
    if settings.get("model"):
        return settings["model"]
    latest = [e for e in entries if e["kind"] == "calibration"]
    if not latest:
        return None
    acc = {m: v.get("accuracy_um") for m, v in latest[-1]["models"].items()}
    acc = {m: a for m, a in acc.items() if isinstance(a, (int, float)) and np.isfinite(a)}
    return min(acc, key=acc.get) if acc else None


def build(
    stage: str,
    pairs: list[tuple[dict, dict]],
    settings: dict | None = None,
    departed: list[dict] | None = None,
) -> dict:
    """The history of ``stage`` from (campaign, summary) pairs in any order; ``departed``: the
    campaigns an earlier history held that left it, with the reason
    (:func:`calflow.lifecycle.members.departed`)."""
    s = {**DEFAULTS, **(settings or {})}
    entries = sorted((entry(c, m) for c, m in pairs), key=lambda e: due.parse(e["start"]))
    cals = [e for e in entries if e["kind"] == "calibration"]
    series = [{m: estimate(v) for m, v in e["models"].items() if v.get("parameters")} for e in cals]
    tests = change.changes(series, alpha=s["alpha"], min_pairs=s["min_pairs"])
    changes = [{"from": a["campaign"], "to": b["campaign"], **t} for a, b, t in zip(cals, cals[1:], tests)]
    segments = _segments(entries, changes)
    model = _due_model(entries, s)
    tol = s["tolerance_um"]
    if tol is None:
        tols = [e.get("tolerance_um") for e in entries if e.get("tolerance_um") is not None]
        tol = tols[-1] if tols else None
    interval.check_settings(s["reliability"], tol, "stage settings")
    found = as_found.from_history(entries, segments, model, tol, s["reliability"])
    return {
        "stage": stage,
        "robot": entries[0]["robot"] if entries else None,
        "alpha": s["alpha"],
        "correction": "Holm's step-down procedure over the models of a change",
        "campaigns": [{k: v for k, v in e.items() if k != "robot"} for e in entries],
        "changes": changes,
        "segments": segments,
        "charts": _charts(entries),
        "due": as_found.due(found) or _due(entries, segments, model, tol, s),
        "interval": found,
        "settings": s,
        "departed": list(departed or []),
    }


def _charts(entries: list[dict]) -> dict:
    acc: dict = {}
    models = sorted({m for e in entries for m in e["models"]})
    for m in models:  # the calibrations' held-out AP: an interim check's AP is on its own targets
        pts = [
            (e["campaign"], e["models"][m].get("accuracy_um"))
            for e in entries
            if m in e["models"] and e["kind"] == "calibration"
        ]
        pts = [(c, a) for c, a in pts if isinstance(a, (int, float)) and np.isfinite(a)]
        acc[m] = {
            "campaigns": [c for c, _ in pts],
            "individuals": charts.individuals([a for _, a in pts]),
            "ewma": charts.ewma([a for _, a in pts]),
        }
    par: dict = {}
    for m in models:
        cal = [e for e in entries if e["kind"] == "calibration" and m in e["models"]]
        names = [p for p in (cal[-1]["models"][m].get("parameters") or {}) if cal] if cal else []
        for p in names:
            vals = [(e["campaign"], e["models"][m]["parameters"].get(p, {}).get("value")) for e in cal]
            vals = [(c, v) for c, v in vals if isinstance(v, (int, float))]
            stds = [e["models"][m]["parameters"].get(p, {}).get("std") for e in cal]
            if not any(isinstance(x, (int, float)) and x > 0 for x in stds):
                continue  # a fixed parameter: nothing to chart
            par.setdefault(m, {})[p] = {
                "campaigns": [c for c, _ in vals],
                "individuals": charts.individuals([v for _, v in vals]),
                "ewma": charts.ewma([v for _, v in vals]),
            }
    return {"accuracy_um": acc, "parameters": par}


def _due(entries, segments, model, tol, s) -> dict:
    out = {"date": None, "tolerance_um": tol, "model": model, "method": due.METHOD}
    if model is None:
        return {**out, "statement": "not enough history: no calibration with an accuracy"}
    if tol is None:
        return {
            **out,
            "statement": "no tolerance stated (tolerance_um in the stage's settings or a campaign)",
        }
    pts = [
        (e["start"], e["models"][model].get("accuracy_um"), g, e["kind"] == "interim")
        for e, g in zip(entries, segments)
        if model in e["models"]
    ]
    pts = [p for p in pts if isinstance(p[1], (int, float)) and np.isfinite(p[1])]
    if not pts:
        return {**out, "statement": f"not enough history: no accuracy of model {model}"}
    res = due.due_date(
        [p[0] for p in pts],
        [p[1] for p in pts],
        [p[2] for p in pts],
        tol,
        reliability=s["reliability"],
        checks=[p[3] for p in pts],
    )
    return {**out, **res}
