"""The summary of a hexapod campaign (``results/<campaign>/summary.json``).

Assembled from the result files, routed by the family's plan → section registry
(:attr:`calflow.family.Family.summary_sections`): each model of the ladder with its identified
parameter count, what the QR analysis dropped, χ²/dof and residual; its held-out ISO 9283
pose accuracy and repeatability for position (µm) and orientation (degree), on targets no
identification saw; when the campaign has them, the same on the five ISO 9283 poses; and the
held-out accuracy through each model's exported bundle (closed loop) beside the in-process one.
The accuracy numbers are held out; what a model cannot do is said in words (``statement``).
"""

from __future__ import annotations

import json

import numpy as np

from calflow.configuration.reference import declared
from calflow.data.io import jsonable, sha256_file
from calflow.summary_routing import route, summary_head
from calflow_hexapod.family import FAMILY

_ORIENT = ("a", "b", "c")


def _iso(m) -> dict:
    """Maxima over target poses and per-target rows of one metrics file."""
    out = {
        "accuracy_um": jsonable(float(m.attrs["accuracy_um"])),
        "repeatability_um": jsonable(float(m.attrs["repeatability_um"])),
        **{f"accuracy_{x}_deg": jsonable(float(m.attrs[f"accuracy_{x}_deg"])) for x in _ORIENT},
        **{f"repeatability_{x}_deg": jsonable(float(m.attrs[f"repeatability_{x}_deg"])) for x in _ORIENT},
        "n_targets": int(m.sizes["target"]),
        "cycles": int(m.attrs.get("cycles", 0)),
    }
    out["per_target"] = [
        {
            "target": int(t),
            "ap_um": jsonable(float(m["ap"].sel(target=t))),
            "rp_um": jsonable(float(m["rp"].sel(target=t))),
            **{f"ap_{x}_deg": jsonable(float(m[f"ap_{x}"].sel(target=t))) for x in _ORIENT},
            **{f"rp_{x}_deg": jsonable(float(m[f"rp_{x}"].sel(target=t))) for x in _ORIENT},
        }
        for t in m["target"].values
    ]
    return out


def _model(ds) -> dict:
    free = [str(p) for p in ds["parameter"].values] if "parameter" in ds.coords else []
    dropped = [d for d in str(ds.attrs.get("dropped", "")).split(",") if d]
    return {
        "free": len(free),
        "dropped": dropped,
        "chi2_dof": jsonable(float(ds.attrs.get("chi2_dof", np.nan))),
        "residual_rms_um": jsonable(float(ds.attrs.get("residual_rms_um", np.nan))),
        "n_poses": int(ds.attrs.get("n_poses", 0)),
        "rejected_poses": int(ds.attrs.get("rejected", 0)),
    }


def _bound(ds, crlb: dict | None) -> dict | None:
    """The bound before beside the result after: each parameter's identified σ over the
    Cramér–Rao σ the design promised before acquisition (1 when the rig's noise is as the
    design assumed and the model fits; above 1 when the model does not)."""
    if not crlb:
        return None
    ratios = {
        p: float(ds[p].attrs["std"]) / float(sigma)
        for p, sigma in crlb.items()
        if p in ds and sigma and np.isfinite(float(ds[p].attrs.get("std", np.nan)))
    }
    if not ratios:
        return None
    values = np.array(list(ratios.values()))
    return {
        "parameters": len(ratios),
        "sigma_ratio_median": jsonable(float(np.median(values))),
        "sigma_ratio_max": jsonable(float(values.max())),
        "worst": max(ratios, key=ratios.get),
    }


#: |AP through the bundle − AP in process| this small (µm) is numerical agreement: the two runs
#: share their noise on a simulated rig, so only the export could make them differ.
NUMERICAL_UM = 1e-6

EXPORT_DEFINITION = (
    "accuracy_um: ISO 9283 AP (max over the held-out targets) of the closed-loop run commanded through the "
    "Compensator loaded from the exported bundle; in_process_accuracy_um: the same of the held-out run "
    "commanded through the in-process model; on a simulated rig both draw the same noise, so they agree "
    "to numerical precision (|difference| <= 1e-6 um) unless the export changed the model; through a "
    "real controller they agree within the held-out repeatability (tolerance_um)"
)


def export_entry(export: dict, heldout: dict | None, command_difference: float | None) -> dict:
    """``models.<M>.export``: the closed-loop run through the exported bundle beside the
    in-process held-out run (both :func:`_iso` entries)."""
    out = {
        "accuracy_um": export["accuracy_um"],
        "repeatability_um": export["repeatability_um"],
        **{f"accuracy_{x}_deg": export[f"accuracy_{x}_deg"] for x in _ORIENT},
        "command_difference": jsonable(command_difference),
        "definition": EXPORT_DEFINITION,
    }
    if heldout and heldout["accuracy_um"] is not None and export["accuracy_um"] is not None:
        diff = export["accuracy_um"] - heldout["accuracy_um"]
        out.update(
            in_process_accuracy_um=heldout["accuracy_um"],
            difference_um=jsonable(diff),
            difference_deg=jsonable(
                max(abs(export[f"accuracy_{x}_deg"] - heldout[f"accuracy_{x}_deg"]) for x in _ORIENT)
            ),
            tolerance_um=heldout["repeatability_um"],
            numerically_equal=bool(abs(diff) <= NUMERICAL_UM),
            verified=bool(abs(diff) <= heldout["repeatability_um"]),
        )
    return out


def _statement(name: str, entry: dict, best: float | None) -> str:
    """What the model can and cannot do, in words, from its held-out numbers."""
    h = entry.get("heldout")
    if not h:
        return f"Model {name} was not validated on held-out targets: its accuracy is unknown."
    ap, rp = h["accuracy_um"], h["repeatability_um"]
    if ap is None or rp is None:
        return f"Model {name}: the held-out validation gave no finite accuracy."
    words = f"On {h['n_targets']} held-out targets, model {name} reaches {ap:.2f} µm (worst AP) against a repeatability of {rp:.2f} µm"
    if ap <= 1.2 * rp:
        return words + ": it leaves only what the rig cannot repeat."
    more = f" ({ap / rp:.1f} × RP): it does not model every error the rig has"
    if best is not None and ap > 1.5 * best:
        more += f"; a richer model of the ladder does better ({best:.2f} µm)"
    return words + more + "."


def hexapod_summary(campaign: dict, files: list[str], truth: dict | None) -> dict:
    """Assemble the summary of a hexapod campaign from its result files (truth unused: the
    summary's numbers are all measured)."""
    found = route(files, FAMILY.summary_sections, "hexapod family")
    design = next(
        (
            json.loads(run.attrs["design"])
            for _, run in found.get("identification", [])
            if "design" in run.attrs
        ),
        {},
    )
    models = {}
    for _, ds in found.get("models", []):
        name = ds.attrs["model"]
        models[name] = _model(ds)
        bound = _bound(ds, (design.get("crlb_sigma") or {}).get(name))
        if bound:
            models[name]["bound"] = bound
    for section in ("heldout", "iso9283"):
        for _, ds in found.get(section, []):
            name = ds.attrs.get("model")
            if name in models:
                models[name][section] = _iso(ds)
    for _, ds in found.get("export", []):
        name = ds.attrs.get("model")
        if name in models:
            diff = ds.attrs.get("command_difference")
            models[name]["export"] = export_entry(
                _iso(ds), models[name].get("heldout"), None if diff is None else float(diff)
            )
    order = [m for m in campaign["models"] if m in models]
    aps = [models[m]["heldout"]["accuracy_um"] for m in order if models[m].get("heldout")]
    best = min((a for a in aps if a is not None), default=None)
    for name in order:
        models[name]["statement"] = _statement(name, models[name], best)
    summary = {
        **summary_head(campaign),
        "models": {name: models[name] for name in order},
        "model_order": order,  # the ladder's order (the summary's keys are written sorted)
        "reference": declared(
            campaign
        ),  # the published values it declares (calflow.configuration.reference), or {}
        "inputs": {str(p): sha256_file(p) for p in files},
    }
    budget = (truth or {}).get("error_budget")
    if budget:  # replays on the simulated truth (calflow_hexapod.stage.error_budget): reports only
        for name, entry in budget["budget"]["models"].items():
            if name in summary["models"]:
                summary["models"][name]["error_budget"] = entry
        summary["error_budget"] = {
            "effects": budget["budget"]["effects"],
            "unmodelled": budget["budget"]["unmodelled"],
            "floor": budget.get("floor"),
        }
    for _, run in found.get("identification", []):
        if "design" in run.attrs:
            summary["identification_design"] = json.loads(run.attrs["design"])
        summary["identification_poses"] = int((np.asarray(run["pose"].values) > 0).sum())
    return summary


def summarise(c, args) -> dict:
    """The family's step hook ``summarise(c, args)`` (:mod:`calflow.family_contract`): the
    summary of the campaign's result files ``args.files``, with the rig's ``args.truth``
    (simulated rigs; tests and reports only) or None."""
    return hexapod_summary(c, args.files, args.truth)
