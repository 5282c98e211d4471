"""The summary of an interim check (``interim_check`` of summary.json): the decision and its cost.

Per visit of the check run (:mod:`calflow.xytheta.plans.interim`), the error e (µm) is the
attained tool point (Eq. 4.27) minus the target. The decision is Wald's SPRT on the scale of
e (:class:`calflow.lifecycle.decisions.sprt.SPRT`) with

* H0: r0, the rms visit error of the reference calibration through the same bundle — its
  export's closed-loop check (``results/<reference>/runs/export_<model>.nc``, bundle segment);
* H1: r1 = ``interim_check.tolerance_um`` (else the campaign's ``tolerance_um``) as an rms error,

at ``alpha`` (false "recalibrate") and ``beta`` (missed "recalibrate"). Beside it the check's
ISO 9283 AP (max over its targets), which enters the stage's history as its accuracy.

The check is acquired sequentially (:func:`calflow.xytheta.plans.interim.sequential`): the
test looks at the end of each cycle from the second on (:data:`MIN_CYCLES`), and the rig
stops at the first decision; the summary repeats the test on the run as acquired.

Rig time: a run's rig time is the span of its time axis (last reading minus first, s of
virtual rig time on a simulated rig); the check's is its run's, the full calibration's the sum
over the reference campaign's runs. Their ratio is recorded against the 5 % budget.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import xarray as xr

from calflow.configuration import layout
from calflow.configuration.reference import declared
from calflow.errors import CalflowError, ConfigError
from calflow.lifecycle.decisions.sprt import SPRT
from calflow.summary_routing import summary_head

# the check's rig time budget, a run's rig time and H0, defined beside the check at load
from calflow.xytheta.plans.interim_load import BUDGET, reference_rms_um, rig_time_s, visit_errors  # noqa: F401

#: Cycles before the sequential test first looks: ISO 9283's RP needs two visits of every target.
MIN_CYCLES = 2


def visit_groups(run: xr.Dataset) -> np.ndarray:
    """The look of each visit (pose > 0) of a check run: its cycle, the first
    :data:`MIN_CYCLES` cycles one look — the test looks at the end of each group."""
    cycle = np.asarray(run["cycle"].values)[run["pose"].values > 0]
    return np.maximum(cycle - (cycle.min() if cycle.size else 0), MIN_CYCLES - 1)


def check_test(campaign: dict, r0: float) -> SPRT:
    """The interim check's SPRT: H0 rms ``r0``, H1 the tolerance, at the check's error rates."""
    check, name = campaign["interim_check"], campaign["name"]
    tol = check.get("tolerance_um", campaign.get("tolerance_um"))
    if tol is None:
        raise ConfigError(
            f"campaign {name}: key 'interim_check.tolerance_um': expected a tolerance (µm), "
            "here or as the campaign's tolerance_um"
        )
    try:
        return SPRT(r0, float(tol), alpha=check["alpha"], beta=check["beta"])
    except ValueError as exc:
        raise ConfigError(f"campaign {name}: key 'interim_check.tolerance_um': {exc}") from None


def indifference_rms_um(r0: float, r1: float) -> float:
    """The rms error (µm) at which a visit's expected log-likelihood ratio is zero: the SPRT
    drifts to "recalibrate" above it, to "within tolerance" below — √(ln(r1²/r0²) /
    (1/r0² − 1/r1²)), from the per-visit ratio of :mod:`calflow.lifecycle.decisions.sprt`."""
    return float(np.sqrt(np.log(r1**2 / r0**2) / (1 / r0**2 - 1 / r1**2)))


def _open(path: str) -> xr.Dataset:
    from calflow.data.io import open_dataset

    return open_dataset(path, kind="run" if "/runs/" in path else "metrics")


def interim_summary(campaign: dict, files: list[str], truth: dict | None = None) -> dict:
    """summary.json of an interim-check campaign from its run, its metrics, and the reference's
    summary and runs (every file named by the family's workflow)."""
    check = campaign["interim_check"]
    ref, model, name = check["reference"], check["model"], campaign["name"]
    own_run = layout.run(name, "interim_check")
    own_metrics = layout.metrics(name, "interim_check")
    export_run = layout.run(ref, f"export_{model}")
    missing = [f for f in (own_run, own_metrics, export_run) if f not in files]
    if missing:
        raise CalflowError(f"interim check {name}: --files lacks {missing[0]}")
    run, metrics = _open(own_run), _open(own_metrics)
    ref_runs = [f for f in files if f.startswith(layout.campaign(ref, "runs") + "/")]
    r0 = reference_rms_um(_open(export_run))
    test = check_test(campaign, r0)
    tol = test.r1_um
    errors = visit_errors(run)
    cycles = int(run.attrs.get("export_cycles", check["cycles"]))
    decision = test.decide(errors, visit_groups(run), planned=int(metrics.sizes["target"]) * cycles)
    own_time = rig_time_s(run)
    ref_time = float(sum(rig_time_s(_open(f)) for f in ref_runs))
    ratio = own_time / ref_time if ref_time > 0 else None
    block = {
        "reference": ref,
        "model": model,
        "targets": int(metrics.sizes["target"]),
        "cycles": cycles,
        "cycles_acquired": int(np.unique(run["cycle"].values[run["pose"].values > 0]).size),
        "tolerance_um": float(tol),
        "alpha": float(check["alpha"]),
        "beta": float(check["beta"]),
        "reference_rms_um": r0,
        "rms_um": float(np.sqrt(np.mean(np.sum(errors**2, axis=1)))),
        "accuracy_um": float(metrics.attrs["accuracy_um"]),
        "repeatability_um": float(metrics.attrs["repeatability_um"]),
        **decision,
        "expected_visits": test.expected_visits(),
        "indifference_rms_um": indifference_rms_um(r0, float(tol)),
        "target_choice": json.loads(run.attrs.get("target_choice", "{}")),
        "targets_um": np.column_stack(
            [metrics["target_x"].values, metrics["target_y"].values, metrics["target_theta"].values]
        ).tolist(),
        "rig_time_s": own_time,
        "reference_rig_time_s": ref_time,
        "reference_runs": [Path(f).stem for f in ref_runs],
        "rig_time_ratio": ratio,
        "rig_time_budget": BUDGET,
        "within_budget": bool(ratio is not None and ratio <= BUDGET),
        "definition": (
            "decision: Wald's SPRT of the visit errors' scale, H0 rms reference_rms_um (the reference's "
            "bundle check) against H1 rms tolerance_um, at alpha and beta; accuracy_um: ISO 9283 AP, max "
            "over the check's targets; rig_time_ratio: the check run's time span over the sum of the "
            "reference campaign's runs' spans"
        ),
    }
    block["as_found"] = {  # through the bundle in use: an as-found value (docs/lifecycle.md)
        "accuracy_um": block["accuracy_um"],
        "repeatability_um": block["repeatability_um"],
        "date": campaign["start"],
        "reference": ref,
    }
    summary = {
        **summary_head(campaign),
        "start": campaign["start"],
        "stage": campaign.get("stage"),
        "models": {},
        "reference": declared(campaign),  # a lab's own stage: none unless the campaign declares one
        "interim_check": block,
    }
    if truth and truth.get("available", True) and "x_R_um" in truth:
        summary["truth"] = {
            "parameters": {k: truth[k] for k in ("x_R_um", "y_R_um", "alpha_deg", "beta_deg")}
        }
    return summary
