"""Nano steps: training the models (Sec. 5.2) and scoring runs (Sec. 5.3, 5.4).

The family's step hooks, each called as ``hook(c, args)`` (:mod:`calflow.family_contract`):
``c`` the loaded campaign, ``args`` the step's inputs."""

from __future__ import annotations

import numpy as np

from calflow.commands.common import meta
from calflow.data.io import open_dataset, write_dataset


def identify(c, args) -> None:
    """Train the single model (Eq. 5.3–5.5) and its KMZ variant (5.6), or the 2-DoF model (5.10)."""
    from calflow.nano.models.kmz import AdaptiveKMZModel
    from calflow.nano.models.thermal import SingleModel, TwoDoFModel

    run = open_dataset(args.run, kind="run")
    temps = run["temperature"].values if "temperature" in run else None  # a recording may have none
    s = c["model"]
    if c["robot"] == "stage1d":
        model = SingleModel.fit(
            run["cmd_x"].values,
            run["meas_x"].values,
            temps,
            order=s["order"],
            penter=s["penter"],
            premove=s["premove"],
        )
        if args.model_name == "adaptive_kmz":
            model = AdaptiveKMZModel.from_single(model, variant=s["kmz_variant"])
    else:
        cmd = np.column_stack([run["cmd_x"].values, run["cmd_y"].values])
        meas = np.column_stack([run["meas_x"].values, run["meas_y"].values])
        model = TwoDoFModel.fit(
            cmd, meas, temps, order=(s["order"], s["order"]), penter=s["penter"], premove=s["premove"]
        )
    write_dataset(model.to_dataset(meta(c, run.attrs["source"], "training", args.model_name)), args.out)


def metrics(c, args) -> None:
    """Per-test, per-pose AP and RP of a training, metrology or validation run."""
    from calflow.nano.evaluation import pose_metrics_1d, pose_metrics_2d

    run = open_dataset(args.run, kind="run")
    ds = pose_metrics_1d(run) if c["robot"] == "stage1d" else pose_metrics_2d(run)
    ds.attrs.update(meta(c, run.attrs["source"], run.attrs["plan"]).attrs("metrics"))
    write_dataset(ds, args.out)


def summarise(c, args) -> dict:
    """The stage1d / stage2d summary from the campaign's model, metrics and run files
    (``args.files``); with the simulated rig's ``args.truth``, each test type's error budget
    (:mod:`calflow.nano.stage.error_budget`)."""
    files, truth = args.files, args.truth
    from calflow.instruments.interferometer import interferometer_budget
    from calflow.nano.evaluation import iso230_2_of_run, temperature_range
    from calflow.nano.family import FAMILY
    from calflow.nano.models.registry import model_from_dataset
    from calflow.nano.report.summary import stage1d_summary, stage2d_summary, unsupported_sections
    from calflow.summary_routing import route

    found = route(files, FAMILY.summary_sections, "nano family")
    metrics = {ds.attrs["plan"]: ds for _, ds in found.get("metrics", [])}
    models = {
        ds.attrs["model"]: model_from_dataset(ds).coefficients.to_dict(orient="records")
        for _, ds in found.get("models", [])
    }
    runs = {ds.attrs["plan"]: ds for _, ds in found.get("runs", [])}
    recordings = c["rig"].get("options", {}).get("recordings")
    recorded = c["rig"]["factory"] == "replay" and isinstance(recordings, dict)  # an instrument's files
    # the thesis's interferometer inputs describe the simulated rig, not another lab's instrument
    budget = (
        interferometer_budget(**c.get("uncertainty", {})) if c.get("uncertainty") or not recorded else None
    )
    training = runs.get("training")
    heated = any("temperature" in ds for ds in runs.values())
    t_range = temperature_range(training) if training is not None and "temperature" in training else None
    unsupported = unsupported_sections(c["robot"], set(metrics) | set(runs), heated, budget is not None)
    physics = None
    if (
        truth is not None
        and training is not None
        and "validation" in runs
        and truth.get("rig") in ("nano1d", "nano2d")
    ):
        from calflow.nano.stage.error_budget import error_budget

        physics = error_budget(truth, c, training, runs["validation"])
    if c["robot"] == "stage1d":
        iso_run = training if training is not None else runs.get("metrology")  # a recorded ISO 230-2 test
        iso = {**iso230_2_of_run(iso_run), "run": iso_run.attrs["plan"]} if iso_run is not None else None
        summary = stage1d_summary(
            c,
            metrics.get("metrology"),
            metrics.get("validation"),
            models,
            budget,
            files,
            training_range_c=t_range,
            iso230_2=iso,
            training_metrics=metrics.get("training"),
            validation_run=runs.get("validation"),
            error_budget=physics,
            step_response_run=runs.get("step_response"),
        )
    else:
        summary = stage2d_summary(
            c,
            metrics.get("validation"),
            models,
            budget,
            files,
            training_metrics=metrics.get("training"),
            training_range_c=t_range,
            validation_run=runs.get("validation"),
            error_budget=physics,
            step_response_run=runs.get("step_response"),
        )
    from calflow.data.io import jsonable
    from calflow.nano.plans.designed import training_design_block
    from calflow.nano.report.extrapolation import extrapolation_block

    if summary.get("validation") is not None:  # beside each day's figures: does it leave training's range?
        humidity = None
        if physics is not None:
            from calflow.nano.stage.error_budget import humidity_ranges

            humidity = humidity_ranges(truth, training, metrics["validation"])
        block = extrapolation_block(metrics.get("validation"), t_range, summary["tests"], humidity)
        summary["validation"]["extrapolation"] = jsonable(block)

    summary["training_design"] = jsonable(training_design_block(c, training, models))
    return {**summary, "unsupported": unsupported}
