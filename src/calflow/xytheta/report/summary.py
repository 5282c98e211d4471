"""The campaign summary (``results/<campaign>/summary.json``; keys in docs/architecture.md).

The summary is assembled from the campaign's result files, recognised by their
attributes (``calflow_kind``, ``plan``, ``model``), so a rule hands over its inputs as a
list. XYΘ here; the nanopositioning summaries are in :mod:`calflow.nano.report.summary`.
"""

from __future__ import annotations

import json

import numpy as np
import xarray as xr

from calflow.configuration.reference import declared
from calflow.data.io import jsonable, sha256_file
from calflow.summary_routing import route, summary_head
from calflow.xytheta.family import FAMILY
from calflow.xytheta.models.kinematics import PARAMETER_NAMES, PARAMETER_UNITS
from calflow.xytheta.report.heldout import adequacy, disjointness, repeatability_floor

_SUFFIX = {"um": "um", "degree": "deg"}


def parameter_key(name: str) -> str:
    """Summary key of a parameter: its name and unit, e.g. ``x_R_um``, ``alpha_deg``."""
    return f"{name}_{_SUFFIX[PARAMETER_UNITS[name]]}"


def _per_target(m: xr.Dataset) -> list[dict]:
    return [
        {
            "target": int(t),
            "x_um": float(m["target_x"].sel(target=t)),
            "y_um": float(m["target_y"].sel(target=t)),
            "theta_deg": float(m["target_theta"].sel(target=t)),
            "ap_um": float(m["ap"].sel(target=t)),
            "rp_um": float(m["rp"].sel(target=t)),
        }
        for t in m["target"].values
    ]


def _model_entry(
    name: str,
    model: xr.Dataset,
    heldout: xr.Dataset | None,
    ref: xr.Dataset | None,
    floor: dict,
    angle: dict | None,
    published: dict,
) -> dict:
    """One model's block; ``published``: the campaign's declared reference values ({} when none)."""
    corr = model["correlation"].values
    main = heldout if heldout is not None else ref
    entry = {
        "accuracy_um": jsonable(float(main.attrs["accuracy_um"])) if main is not None else None,
        "repeatability_um": jsonable(float(main.attrs["repeatability_um"])) if main is not None else None,
        "protocol": "heldout" if heldout is not None else "reference_targets",
        "free": [str(p) for p in model["parameter"].values],
        "position_table": bool(model.attrs.get("position_table", 0)),
        "angle_table": bool(model.attrs.get("angle_table", 0)),
        "parameters": {
            parameter_key(p): {
                "value": float(model[p].values),
                "std": jsonable(float(model[p].attrs.get("std", np.nan))),
            }
            for p in PARAMETER_NAMES
        },
        "correlation": [[jsonable(v) for v in row] for row in corr],
        "identifiability": {
            "r_diag": [jsonable(v) for v in model["r_diag"].values] if "r_diag" in model else [],
            "not_identifiable": model.attrs.get("not_identifiable", ""),
        },
        "identification": {
            k: jsonable(v)
            for k, v in model.attrs.items()
            if k
            in (
                "residual_rms_um",
                "sigma_fit_um",
                "cv_rms_um",
                "cv_folds",
                "n_poses",
                "dof",
                "condition_number",
                "uncertainty",
                "O1",
                "O2",
                "O3",
                "O4",
                "sigma_um",
                "robust_loss",
            )
        },
        "per_target": _per_target(main) if main is not None else [],
        "adequacy": adequacy(
            model.attrs.get("sigma_fit_um"), model.attrs.get("n_poses"), len(model["parameter"]), floor
        ),
    }
    rejected = str(model.attrs.get("rejected_poses", ""))
    entry["identification"]["rejected_poses"] = [int(i) for i in rejected.split(",") if i.strip()]
    if ref is not None:
        entry["reference_targets"] = {
            "accuracy_um": jsonable(float(ref.attrs["accuracy_um"])),
            "repeatability_um": jsonable(float(ref.attrs["repeatability_um"])),
            "thesis_accuracy_um": ((published.get("models") or {}).get(name) or {}).get("accuracy_um"),
            "per_target": _per_target(ref),
        }
    if angle is not None:
        entry["angle_table_info"] = angle
    return entry


def _angle_info(model_path: str, model: xr.Dataset) -> dict | None:
    """The angle table of Model IV/V: tabulated and swept curves, the step and its reasons."""
    if not model.attrs.get("angle_table"):
        return None
    from calflow.data.io import group_names, open_dataset

    if "angle_table" not in group_names(model_path):
        return None
    t = open_dataset(model_path, group="angle_table")
    info = {"table": t.attrs.get("table", "")}
    for k in (
        "angle_table_kind",
        "angle_step_deg",
        "angle_sweep_step_deg",
        "angle_shortest_period_deg",
        "angle_noise_um",
        "angle_interpolation_error_um",
        "angle_undersampled",
        "angle_warning",
    ):
        if k in model.attrs:
            info[k[len("angle_") :]] = jsonable(model.attrs[k])
    if t.attrs.get("table") == "angle_sweep":
        info["theta_deg"] = [float(v) for v in t["theta"].values]
        info["f_ax_um"] = [[jsonable(float(v)) for v in row] for row in t["f_ax"].values]
        info["f_ay_um"] = [[jsonable(float(v)) for v in row] for row in t["f_ay"].values]
        if "sweep_theta" in t:
            info["sweep_theta_deg"] = [float(v) for v in t["sweep_theta"].values]
            info["sweep_f_ax_um"] = [[jsonable(float(v)) for v in row] for row in t["sweep_f_ax"].values]
            info["sweep_f_ay_um"] = [[jsonable(float(v)) for v in row] for row in t["sweep_f_ay"].values]
    return info


def _characterisation(luts: xr.Dataset) -> dict:
    out = {
        name: jsonable(float(luts[name])) for name in ("x_stage_angle", "perpendicularity") if name in luts
    }
    out["periods_um"] = {
        k[len("period_") :]: jsonable(float(luts[k])) for k in luts.data_vars if k.startswith("period_")
    }
    out["repeatability_um"] = {
        k[len("rep_") :]: {
            "median": jsonable(float(np.nanmedian(luts[k].values))),
            "max": jsonable(float(np.nanmax(luts[k].values))),
        }
        for k in luts.data_vars
        if k.startswith("rep_")
    }
    out["peak_to_valley_um"] = {
        k[len("err_") :]: jsonable(float(np.nanmax(luts[k].values) - np.nanmin(luts[k].values)))
        for k in luts.data_vars
        if k.startswith("err_")
    }
    return out


def _xy_test(m: xr.Dataset) -> dict:
    return {
        "accuracy_um": jsonable(float(m.attrs["accuracy_um"])),
        "repeatability_um": jsonable(float(m.attrs["repeatability_um"])),
        "per_target": [
            {"target": int(t), "ap_um": jsonable(float(m["ap"].sel(target=t)))} for t in m["target"].values
        ],
    }


def _iso230_2_of_sweep(run: xr.Dataset, axis: str) -> dict:
    """ISO 230-2 of one stage from its characterisation sweep (stage frame, µm)."""
    from calflow.metrics.iso230_2_runs import iso230_2_of_run
    from calflow.xytheta.tables.characterisation import stage_positions

    u, v = stage_positions(run)
    r = iso230_2_of_run(run, attained=u if axis == "x" else v, target=run[f"cmd_{axis}"].values)
    out = {
        "units": "um",
        "targets": len(r["targets_um"]),
        "cycles_forward": r["cycles_forward"],
        "cycles_backward": r["cycles_backward"],
    }
    for key in ("E", "E_fwd", "E_bwd", "M", "B", "B_mean", "R", "R_fwd", "R_bwd", "A", "A_fwd", "A_bwd"):
        out[f"{key}_um"] = jsonable(r[f"{key}_nm"] / 1000.0)
    return out


def xytheta_summary(campaign: dict, files: list[str], truth: dict | None) -> dict:
    """Assemble the summary of an XYΘ campaign from its result files."""
    if "interim_check" in campaign:  # a check through a calibration's bundle (report/interim.py)
        from calflow.xytheta.report.interim import interim_summary

        return interim_summary(campaign, files, truth)
    models, paths, ref, heldout, xy, luts, obs, iso, study = {}, {}, {}, {}, {}, None, None, {}, None
    found = route(files, FAMILY.summary_sections, "XYΘ family")
    for path, ds in found.get("models", []):
        models[ds.attrs["model"]], paths[ds.attrs["model"]] = ds, path
    ref = {ds.attrs["model"]: ds for _, ds in found.get("reference_targets", [])}
    heldout = {ds.attrs["model"]: ds for _, ds in found.get("heldout", [])}
    for _, ds in found.get("xy_tests", []):
        xy.setdefault(ds.attrs["plan"], {})[ds.attrs.get("compensation", "none")] = _xy_test(ds)
    for _, ds in found.get("observability", []):
        obs = ds
    for _, ds in found.get("design_study", []):
        from calflow.xytheta.design.study import summary_block

        study = summary_block(ds)
    for _, ds in found.get("characterisation", []):
        luts = ds
    for _, ds in found.get("iso230_2", []):
        iso[ds.attrs["plan"][-1]] = _iso230_2_of_sweep(ds, ds.attrs["plan"][-1])
    heldout_runs = [ds for _, ds in found.get("heldout_runs", [])]
    # models.<M>.export: the closed-loop check of the exported files (docs/export.md)
    exported = {ds.attrs["model"]: ds for _, ds in found.get("export", [])}
    training_runs = [ds for _, ds in found.get("training_runs", [])]
    order = [name for name in campaign["models"] if name in models]
    floor = repeatability_floor(list(heldout.values()) + list(ref.values()))
    reference = declared(campaign)
    summary = {
        **summary_head(campaign),
        "models": {
            name: _model_entry(
                name,
                models[name],
                heldout.get(name),
                ref.get(name),
                floor,
                _angle_info(paths[name], models[name]),
                reference,
            )
            for name in order
        },
        "validation": _validation_block(campaign, heldout, ref, heldout_runs, training_runs, floor, truth),
        "reference": reference,  # the published values it declares (calflow.configuration.reference), or {}
        "inputs": {str(p): sha256_file(p) for p in files},
    }
    if exported:
        from calflow.xytheta.export.verification import summary_entry

        for name, ds in exported.items():
            if name in summary["models"]:
                summary["models"][name]["export"] = summary_entry(ds)
    from calflow.xytheta.report.as_found import add as add_as_found

    add_as_found(summary, campaign, found)  # models.<M>.as_left, .as_found (docs/lifecycle.md)
    _crlb_block(summary, campaign, training_runs)
    if study is not None:
        summary["design_study"] = study
    if luts is not None:
        summary["characterisation"] = _characterisation(luts)
    if xy:
        summary["xy_tests"] = xy
    if iso:
        summary["iso230_2"] = iso
    if obs is not None:
        summary["observability"] = {
            "poses": [int(v) for v in obs["poses"].values],
            **{k: [jsonable(v) for v in obs[k].values] for k in ("O1", "O2", "O3", "O4")},
            "O2_plateau_poses": int(obs.attrs["O2_plateau_poses"]),
            "O2_plateau_tolerance": jsonable(obs.attrs.get("O2_plateau_tolerance")),
            "O2_limit": jsonable(obs.attrs.get("O2_limit")),
            "repeats": jsonable(obs.attrs.get("repeats")),
        }
    from calflow.xytheta.report.instrument import summary_block

    bench = next((ds for _, ds in found.get("instrument", [])), None)
    runs = [ds for sec in ("iso230_2", "training_runs", "heldout_runs") for _, ds in found.get(sec, [])]
    sensor = summary_block(runs, bench)
    if sensor is not None:
        summary["sensor"] = sensor
    if truth and truth.get("error_budget") and heldout:
        _add_error_budget(summary, heldout, truth["error_budget"])
    if truth and truth.get("available", True):
        summary["truth"] = {
            "parameters": {k: truth[k] for k in ("x_R_um", "y_R_um", "alpha_deg", "beta_deg")}
        }
    return summary


def _add_error_budget(summary: dict, heldout: dict, budget: dict) -> None:
    """``models.<M>.error_budget_um`` and ``validation.heldout.error_budget`` from the budget's
    replays on the simulated truth (:mod:`calflow.xytheta.stage.error_budget`): reports only."""
    from calflow.xytheta.stage.error_budget import combine, groups

    _add_noise_model_sensor(summary, budget)
    if not any(r["replay"] == "baseline" for r in budget["replays"]):  # only the noise-model replay
        return
    ap = {name: m["ap"].values for name, m in heldout.items()}
    b = combine(ap, budget["replays"])
    for name, entry in b["models"].items():
        if name in summary["models"]:
            summary["models"][name].update(
                error_budget_um=entry["error_budget_um"],
                error_budget_rms_um=entry["rms_ap_um"],
                error_budget_groups_um=groups(entry["error_budget_um"], b["unmodelled"]),
            )
    summary["validation"].setdefault("heldout", {})["error_budget"] = {
        k: b[k] for k in ("effects", "unmodelled", "combination")
    }


def _add_noise_model_sensor(summary: dict, budget: dict) -> None:
    """``models.<M>.noise_model_sensor`` of a rig that reads through images: the held-out AP
    and RMS of the same calibration replayed with the noise-model sensor (same seeds)."""
    record = next((r for r in budget["replays"] if r["replay"] == "noise_model" and r.get("active")), None)
    if record is None:
        return
    for name, ap in record["ap_um"].items():
        if name in summary["models"]:
            ap = np.asarray(ap, dtype=float)
            summary["models"][name]["noise_model_sensor"] = {
                "accuracy_um": float(np.max(ap)),
                "rms_ap_um": float(np.sqrt(np.mean(ap**2))),
            }
    summary["validation"].setdefault("heldout", {})["sensor_comparison"] = (
        "models.<M>.accuracy_um: the sensor read through rendered frames and the decoder; "
        "models.<M>.noise_model_sensor.accuracy_um: the same calibration (seeds, poses, stage "
        "draws) with the noise-model sensor; validation.heldout.floor_um: the rig's repeatability floor"
    )


def _validation_block(campaign, heldout, ref, heldout_runs, training_runs, floor, truth) -> dict:
    from calflow.xytheta.plans.campaign import heldout_seed

    v = campaign["validation"]
    out = {"repeatability_floor": floor}
    if heldout:
        any_metrics = next(iter(heldout.values()))
        out["heldout"] = {
            "n_targets": int(any_metrics.sizes["target"]),
            "requested_targets": v["heldout"]["targets"],
            "cycles": v["heldout"]["cycles"],
            "seed": heldout_seed(campaign),
            "drawn_over": {k: campaign["identification"][k] for k in ("x_um", "y_um", "theta_deg")},
            **disjointness(heldout_runs, training_runs),
        }
        if truth and truth.get("rig") == "simulated_xytheta" and heldout_runs:
            from calflow.xytheta.stage.oracle import oracle_validation  # the simulated truth: reports only

            oracle = oracle_validation(truth, heldout_runs[0], int(campaign.get("seed") or 0))
            out["heldout"].update(
                floor_um=oracle["floor_um"],
                oracle_accuracy_um=oracle["accuracy_um"],
                floor_definition="ISO 9283 RP (max over the held-out targets) of the targets "
                "commanded through the simulated truth's exact inverse",
            )
    if ref:
        any_metrics = next(iter(ref.values()))
        out["reference_targets"] = {
            "n_targets": int(any_metrics.sizes["target"]),
            "cycles": v["cycles"],
            "source": "Table 4.7" if v.get("targets") is None else "validation.targets",
        }
    return out


def _crlb_block(summary: dict, campaign: dict, training_runs: list[xr.Dataset]) -> None:
    """The bound before beside the result after (optimal design): each model's Cramér–Rao σ and the
    expected virtual rig time, written into the identification run before acquisition
    (attribute ``design``), as ``models.<M>.identification.crlb_sigma`` / ``.rig_time_h``
    next to the achieved ``parameters.<p>.std``; the run's actual virtual time as
    ``.rig_time_h_achieved``; and the plan's design as ``identification_design``."""
    run = next(
        (r for r in training_runs if r.attrs.get("plan") == "identification" and "design" in r.attrs), None
    )
    if run is None:
        return
    record = json.loads(run.attrs["design"])
    crlb = record.pop("crlb_sigma", None) or {}
    achieved_h = float(run["time"].values[-1]) / 3600.0 if run.sizes.get("sample") else None
    summary["identification_design"] = {**record, "rig_time_h_achieved": jsonable(achieved_h)}
    for name, entry in summary["models"].items():
        spec = campaign["models"][name]
        bound = crlb.get(spec.get("base", name))
        if bound is not None:
            entry["identification"].update(
                crlb_sigma=bound,
                rig_time_h=record.get("rig_time_h"),
                rig_time_h_achieved=jsonable(achieved_h),
            )


def summarise(c, args) -> dict:
    """The family's step hook ``summarise(c, args)`` (:mod:`calflow.family_contract`): the
    summary of the campaign's result files ``args.files``, with the rig's ``args.truth``
    (simulated rigs; tests and reports only) or None."""
    return xytheta_summary(c, args.files, args.truth)
