"""Campaign summaries of the nanopositioning stages (``summary.json``; keys in docs/architecture.md).

Built from the metrics datasets of :mod:`calflow.nano.evaluation` (AP/RP in nm per test
and pose).  Every value is JSON-ready: Python numbers, lists and dicts only, NaN and
infinities become None (``json.dumps(..., allow_nan=False)`` works).

Time in the per-test series is in hours since the start of validation (the first sample
of the validation run), as Fig. 5.17-5.19 ("Time 0 = end of training = start of
validation"); ``campaign_time_h`` keeps the hours since the campaign start.  Days for
``max_accuracy_nm_by_day`` are ``floor(time_h / 24)`` of each test's mean time.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import xarray as xr

from calflow.configuration.reference import declared
from calflow.data.io import (
    jsonable,  # noqa: F401 (re-exported)
    sha256_file,
)
from calflow.nano.evaluation import accuracy_vs_temperature, mode_names
from calflow.nano.report.iso9283 import iso9283_block
from calflow.nano.robustness import robustness_by_mode
from calflow.summary_routing import summary_head

__all__ = ["jsonable", "mode_block", "stage1d_summary", "stage2d_summary", "unsupported_sections"]


def _budget(budget):
    """The GUM budget as rows: a dict/list as given, or an object with ``.table()`` (Table 3.4)."""
    if budget is None:
        return None
    if hasattr(budget, "table"):
        rows = [{"name": n, "category": c, "formula": f, "value_nm": v} for n, c, f, v in budget.table()]
        return {"rows": rows, "combined_nm": getattr(budget, "combined_nm", None)}
    return budget


def _nanmax(a) -> float:
    a = np.asarray(a, dtype=float)
    a = a[np.isfinite(a)]
    return float(a.max()) if a.size else float("nan")


def _max_by_day(values: np.ndarray, day: np.ndarray, n_days: int) -> list:
    """Max of ``values`` per day 0..n_days-1 (None where a day has no finite value)."""
    return [_nanmax(values[day == d]) for d in range(n_days)]


def mode_block(metrics: xr.Dataset, training_range_c: tuple[float, float] | None = None) -> tuple[dict, dict]:
    """Per-mode headline and series of a validation metrics dataset, plus the period info.

    Returns ``(tests, validation)``: ``tests[mode]`` has ``max_accuracy_nm`` (max AP over
    every pose of every test of the mode, whole period), ``max_accuracy_nm_by_day`` (list
    over days since validation start), ``max_repeatability_nm``, ``max_repeatability_nm_by_day``,
    ``max_intrinsic_repeatability_nm`` (RP with the estimated drift removed, Eq. 3.14),
    ``n_tests`` and ``series`` (per test: test, time_h, campaign_time_h, day, max_ap_nm,
    max_rp_nm, max_rp_intrinsic_nm, temperature_c, temperature_range_c,
    in_training_range).  ``validation`` has start_h, end_h, duration_h, days, n_tests.
    """
    start = float(metrics.attrs.get("start_time_h", np.nanmin(metrics["time_start_h"].values)))
    end = float(metrics.attrs.get("end_time_h", np.nanmax(metrics["time_end_h"].values)))
    rel = metrics["time_h"].values - start
    day = np.floor(rel / 24.0).astype(int)
    n_days = int(math.floor((end - start) / 24.0)) + 1
    mode = metrics["mode"].values
    with warnings.catch_warnings():  # all-NaN tests give NaN
        warnings.simplefilter("ignore", RuntimeWarning)
        rp_int = np.nanmax(metrics["rp_intrinsic"].transpose("test", "pose").values, axis=1)
    temperature = accuracy_vs_temperature(metrics, training_range_c)
    tests: dict = {}
    for k, name in enumerate(mode_names(metrics)):
        rows = np.flatnonzero(mode == k)
        if rows.size == 0:
            continue
        ap, rp = metrics["ap_max"].values[rows], metrics["rp_max"].values[rows]
        tests[name] = {
            "max_accuracy_nm": _nanmax(ap),
            "max_accuracy_nm_by_day": _max_by_day(ap, day[rows], n_days),
            "max_repeatability_nm": _nanmax(rp),
            "max_repeatability_nm_by_day": _max_by_day(rp, day[rows], n_days),
            "max_intrinsic_repeatability_nm": _nanmax(rp_int[rows]),
            "n_tests": int(rows.size),
            "series": {
                "test": metrics["test"].values[rows],
                "time_h": rel[rows],
                "campaign_time_h": metrics["time_h"].values[rows],
                "day": day[rows],
                "max_ap_nm": ap,
                "max_rp_nm": rp,
                "max_rp_intrinsic_nm": rp_int[rows],
                "temperature_c": metrics["temperature_c"].values[rows],
                "temperature_range_c": metrics["temperature_range_c"].values[rows],
                "in_training_range": temperature[name]["in_training_range"],
            },
        }
    validation = {
        "start_h": start,
        "end_h": end,
        "duration_h": end - start,
        "days": n_days,
        "n_tests": int(metrics.sizes["test"]),
        "time_origin": "time_h is hours since the first validation sample; campaign_time_h since campaign start",
        "training_temperature_range_c": list(training_range_c) if training_range_c is not None else None,
        "drift_estimator": metrics.attrs.get("drift_estimator"),
    }
    return tests, validation


def heldout_block(validation_metrics: xr.Dataset, training_metrics: xr.Dataset | None, tests: dict) -> dict:
    """Is the validation out of sample? Times and positions against the training run's.

    Records whether validation starts after training ends, which validation positions
    (µm) are also training positions, and adds to each mode in ``tests`` the max AP over
    the validation poses at positions training never visited (``heldout_max_accuracy_nm``)
    — the figure that says how a model does where it was not trained.
    """
    if training_metrics is None:
        return {"time_disjoint": None, "shared_positions_um": None}
    axes = str(validation_metrics.attrs.get("axes", "x")).split()
    val = np.column_stack([validation_metrics[f"target_{a}"].values for a in axes])
    train = np.column_stack([training_metrics[f"target_{a}"].values for a in axes])
    shared = np.array([np.any(np.all(np.abs(train - v) < 1e-6, axis=1)) for v in val])
    t_end = float(training_metrics.attrs.get("end_time_h", np.nanmax(training_metrics["time_end_h"].values)))
    v_start = float(
        validation_metrics.attrs.get("start_time_h", np.nanmin(validation_metrics["time_start_h"].values))
    )
    mode = validation_metrics["mode"].values
    ap = validation_metrics["ap"].transpose("test", "pose").values
    for k, name in enumerate(mode_names(validation_metrics)):
        if name in tests:
            tests[name]["heldout_max_accuracy_nm"] = (
                _nanmax(ap[mode == k][:, ~shared]) if (~shared).any() else None
            )
    return {
        "time_disjoint": bool(v_start > t_end),
        "training_end_h": t_end,
        "validation_start_h": v_start,
        "shared_positions_um": np.unique(val[shared], axis=0).tolist(),
        "heldout_positions_um": np.unique(val[~shared], axis=0).tolist(),
        "statement": (
            "Validation starts after training ends; "
            + (
                "every validation position is one training never visited."
                if not shared.any()
                else f"{int(np.unique(val[shared], axis=0).shape[0])} of its {int(np.unique(val, axis=0).shape[0])} "
                "positions are training positions (the thesis's protocol), so "
                "tests.<mode>.heldout_max_accuracy_nm gives the max AP over the others."
            )
        ),
    }


def _per_pose(metrics: xr.Dataset, test: int = 0) -> list[dict]:
    m = metrics.isel(test=test)
    axes = str(metrics.attrs.get("axes", "x")).split()
    rows = []
    for j, p in enumerate(m["pose"].values):
        row = {"pose": int(p)}
        row.update({f"target_{a}_um": m[f"target_{a}"].values[j] for a in axes})
        row.update(direction=m["direction"].values[j], ap_nm=m["ap"].values[j], rp_nm=m["rp"].values[j])
        rows.append(row)
    return rows


def _headline(metrics: xr.Dataset) -> dict:
    """Accuracy and repeatability of a single-test run (metrology, training): max over poses."""
    return {
        "accuracy_nm": _nanmax(metrics["ap"].values),
        "repeatability_nm": _nanmax(metrics["rp"].values),
        "temperature_c": metrics["temperature_c"].values[0],
        "temperature_range_c": metrics["temperature_range_c"].values[0],
        "per_pose": _per_pose(metrics),
    }


def unsupported_sections(robot: str, plans, temperatures: bool, budget: bool = True) -> dict[str, str]:
    """Report sections the campaign's runs cannot support, each with the reason in plain words.

    ``plans``: the plans of the runs the summary has (``training``, ``metrology``,
    ``validation``); ``temperatures``: whether any of them holds thermocouple readings;
    ``budget``: whether the interferometer's uncertainty inputs are known.
    Empty for a complete campaign; a recorded campaign (docs/data.md) lists what its
    recordings do not allow, and the report prints it.
    """
    plans = set(plans)
    out: dict[str, str] = {}
    if "training" not in plans:
        eqs = "Eq. 5.10" if robot == "stage2d" else "Eq. 5.3-5.6"
        out["models"] = (
            f"no training run was recorded, and the models (thesis {eqs}) are fitted "
            "to a training run over the stroke, so no model is identified"
        )
        out["training"] = (
            "no training run was recorded, so its accuracy, repeatability and error plots are absent"
        )
    if "validation" not in plans:
        out["validation"] = (
            "no validation run was recorded: validation commands the stage through each model at "
            "run time, which a recording made without those models cannot replay"
        )
        out["robustness"] = (
            "space and time robustness (Eq. 5.8, 5.9) are computed over the validation tests, "
            "and there are none"
        )
    if robot == "stage1d" and "metrology" not in plans:
        out["metrology"] = (
            "no metrology run was recorded, so the intrinsic accuracy and repeatability are absent"
        )
    if not temperatures:
        out["temperature"] = (
            "the recordings hold no temperature readings, so thermal drift and accuracy against "
            "temperature cannot be shown"
        )
    if not budget:
        out["budget"] = (
            "the measuring instrument's uncertainty inputs are not given (campaign key 'uncertainty'), "
            "and the thesis's interferometer budget (Table 3.4) would describe another instrument"
        )
    return out


def _common(campaign: dict, robot: str, models: dict, budget, inputs: list[str]) -> dict:
    return {
        **summary_head(campaign, robot),
        "models": models,
        "budget": _budget(budget),
        "reference": declared(
            campaign
        ),  # the published values it declares (calflow.configuration.reference), or {}
        "inputs": {str(p): sha256_file(p) for p in inputs},
    }


def _validation(
    validation_metrics: xr.Dataset | None, training_metrics, training_range_c
) -> tuple[dict, dict | None, dict]:
    """(tests, validation, robustness) of a validation run; empty when the campaign has none."""
    if validation_metrics is None:
        return {}, None, {}
    tests, validation = mode_block(validation_metrics, training_range_c)
    validation["heldout"] = heldout_block(validation_metrics, training_metrics, tests)
    return tests, validation, robustness_by_mode(validation_metrics)


def stage1d_summary(
    campaign: dict,
    metrology_metrics: xr.Dataset | None,
    validation_metrics: xr.Dataset | None,
    models: dict,
    budget=None,
    inputs: list[str] = (),
    *,
    training_range_c: tuple[float, float] | None = None,
    iso230_2: dict | None = None,
    training_metrics: xr.Dataset | None = None,
    validation_run: xr.Dataset | None = None,
    error_budget: dict | None = None,
    step_response_run: xr.Dataset | None = None,
) -> dict:
    """Summary of a 1-DoF nano campaign (docs/architecture.md "Campaign summary", thesis Sec. 5.3.3).

    ``intrinsic`` from the metrology run (Remark 1: AP_I, RP_I, max over poses, nm);
    ``tests.<mode>`` from the validation run (:func:`mode_block`); ``robustness.<mode>``
    with ``space`` (Eq. 5.8, µm), ``time`` (Eq. 5.9, µm/h) and ``units``; ``training``
    (training-run AP/RP, Fig. 5.13) when ``training_metrics`` is given; ``iso230_2`` as
    given (:func:`calflow.nano.evaluation.iso230_2_of_run` of the training run);
    ``models`` coefficient tables and ``budget`` rows as given; ``reference`` = the published
    values the campaign declares (``reference: thesis-sec5.3``: Tan, Sec. 5.3.3), or ``{}``; ``inputs`` {path: sha256}; ``iso9283`` (vAP, AD,
    RD, dAP, dRP, stabilisation time, overshoot per test type, :func:`iso9283_block`) when
    the ``validation_run`` is given (stabilisation time and overshoot from ``step_response_run``).
    """
    summary = _common(campaign, "stage1d", models, budget, inputs)
    summary["intrinsic"] = _headline(metrology_metrics) if metrology_metrics is not None else None
    runs = (validation_metrics, training_metrics, training_range_c, validation_run, step_response_run)
    return _validated(summary, campaign, *runs, error_budget, iso230_2=iso230_2)


def stage2d_summary(
    campaign: dict,
    validation_metrics: xr.Dataset | None,
    models: dict,
    budget=None,
    inputs: list[str] = (),
    *,
    training_metrics: xr.Dataset | None = None,
    training_range_c: tuple[float, float] | None = None,
    validation_run: xr.Dataset | None = None,
    error_budget: dict | None = None,
    step_response_run: xr.Dataset | None = None,
) -> dict:
    """Summary of a 2-DoF nano campaign (docs/architecture.md, thesis Sec. 5.4.2): ``tests.<no_calibration|
    single>`` (AP/RP over x, y in nm, :func:`mode_block`), ``robustness`` as for 1-DoF,
    ``training`` (training-run AP/RP) when given, ``reference`` = the declared values (``thesis-sec5.4``), or ``{}``,
    ``iso9283`` (:func:`iso9283_block`) when the ``validation_run`` is given."""
    summary = _common(campaign, "stage2d", models, budget, inputs)
    runs = (validation_metrics, training_metrics, training_range_c, validation_run, step_response_run)
    return _validated(summary, campaign, *runs, error_budget)


def _validated(
    summary: dict,
    campaign: dict,
    validation_metrics: xr.Dataset | None,
    training_metrics: xr.Dataset | None,
    training_range_c: tuple[float, float] | None,
    validation_run: xr.Dataset | None,
    step_response_run: xr.Dataset | None,
    error_budget: dict | None,
    **more,
) -> dict:
    """The blocks both nano summaries hold after their own: ``training``, ``validation``,
    ``tests``, ``robustness`` (:func:`_validation`), ``more`` as given, ``iso9283`` when
    the ``validation_run`` is given and the rig physics' blocks; as JSON values."""
    tests, validation, robustness = _validation(validation_metrics, training_metrics, training_range_c)
    summary.update(
        training=_headline(training_metrics) if training_metrics is not None else None,
        validation=validation,
        tests=tests,
        robustness=robustness,
        **more,
    )
    if validation_run is not None:
        summary["iso9283"] = iso9283_block(validation_run, step_response_run)
    _physics_blocks(summary, error_budget, campaign)
    return jsonable(summary)


def _physics_blocks(summary: dict, error_budget: dict | None, campaign: dict) -> None:
    """The rig physics' blocks: ``tests.<t>.error_budget_nm`` (simulated rigs: the summary step's budget after
    calibration, :mod:`calflow.nano.stage.error_budget`), ``validation.error_budget_method`` and the
    ``ordering`` paragraph (:mod:`calflow.nano.report.ordering`)."""
    from calflow.nano.report.ordering import ordering_block

    if error_budget:
        for mode, t in summary["tests"].items():
            if mode in error_budget:
                t["error_budget_nm"] = error_budget[mode]
        summary["validation"]["error_budget_method"] = error_budget.get("method")
    whose = "The thesis's" if isinstance(campaign.get("reference"), str) else "The reference's"
    summary["ordering"] = ordering_block(
        summary["tests"], summary.get("robustness"), summary["reference"], whose
    )
