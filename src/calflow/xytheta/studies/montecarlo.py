"""Monte-Carlo study of the XYΘ identification (thesis Sec. 4.5.4–4.5.5, Fig. 4.21).

Many simulated campaigns over seeds × sensor noise × number of identification poses:
each *point* acquires an identification run on the simulated rig, identifies the study's
model with the pose-difference cost (Eq. 4.28–4.30), validates it on the Table 4.7
targets (ISO 9283 AP/RP, max over targets), and records the observability indices
O1–O4 (Eq. 4.10–4.13) of the identification Jacobian. Fig. 4.21 shows how the indices
grow with the number of poses; the study shows what they predict: the identification
error and the validation accuracy.

The code keeps three parts apart:

* **simulation** (:func:`simulate_run`): the only part that touches the simulator; it
  returns the run dataset and, separately, the rig's truth;
* **analysis** (:func:`identify_run`, :func:`validation_accuracy`): run datasets only,
  exactly as the workflow's ``identify`` and ``metrics`` steps do;
* **scoring** (:func:`score`): the identified parameters against the truth — the only
  use of the truth, after the analysis is done.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from calflow.configuration import layout
from calflow.errors import ConfigError

#: Parameters of Eq. (4.18): (model name, summary key, units).
PARAMETERS = (
    ("x_R", "x_R_um", "um"),
    ("y_R", "y_R_um", "um"),
    ("alpha", "alpha_deg", "degree"),
    ("beta", "beta_deg", "degree"),
)


# ---------------------------------------------------------------------------- study files


def load_study(path: str | Path, campaign_dir: str | Path = "config/campaigns") -> dict:
    """Load and validate a study file; its name is the file's stem.

    The base campaign is loaded from ``campaign_dir`` and kept under ``base`` (and the
    study's own path under ``file``); it must be
    an XYΘ campaign on the simulated rig (the study scores estimates against the rig's
    truth), and ``model`` one of its identified models without a position table.
    """
    from calflow.configuration.campaign import load as load_campaign
    from calflow.configuration.config import check_campaign_name, load_yaml, validate

    path = Path(path)
    check_campaign_name(path.stem)
    study = validate(load_yaml(path), "study", path)
    base = load_campaign(Path(campaign_dir) / f"{study['campaign']}.yaml")
    if base["robot"] != "xytheta":
        raise ConfigError(
            f"{path}: key 'campaign': expected an xytheta campaign, got robot {base['robot']!r}"
        )
    if base["rig"]["factory"] != "simulated":
        raise ConfigError(
            f"{path}: key 'campaign': expected a campaign on the simulated rig (the study needs "
            f"the rig's truth), got rig.factory {base['rig']['factory']!r}"
        )
    spec = base["models"].get(study["model"])
    if spec is None or "free" not in spec or spec.get("position_table"):
        usable = sorted(k for k, s in base["models"].items() if "free" in s and not s.get("position_table"))
        raise ConfigError(
            f"{path}: key 'model': expected an identified model without position table of "
            f"campaign {study['campaign']!r} (one of {usable}), got {study['model']!r}"
        )
    from calflow.xytheta.stage.rig import XYThetaTruth

    fields = set(XYThetaTruth.__dataclass_fields__) - {"sensor_noise_um"}
    unknown = sorted(set(study["rig_options"]) - fields)
    if unknown:
        raise ConfigError(
            f"{path}: unknown key 'rig_options.{unknown[0]}' (expected simulated XYΘ rig options: "
            f"{', '.join(sorted(fields))}; noise comes from noise_um)"
        )
    study.update(name=path.stem, file=str(path), base=base)
    return study


def noise_label(noise_um: float) -> str:
    """The noise level as it appears in file names (``0.05``, ``2``)."""
    return f"{float(noise_um):.12g}"


def grid(study: dict) -> list[tuple[int, str, int]]:
    """Every point of the study: (seed, noise label, poses)."""
    return [
        (s, noise_label(n), p)
        for s in range(study["seeds"])
        for n in study["noise_um"]
        for p in study["poses"]
    ]


def seed_batches(study: dict) -> list[str]:
    """The seed labels of the study's jobs: ``"3"`` (one seed) or ``"0-7"`` (seeds 0 to 7)."""
    k, n = study.get("seeds_per_job", 1), study["seeds"]
    return [str(a) if min(a + k, n) - 1 == a else f"{a}-{min(a + k, n) - 1}" for a in range(0, n, k)]


def parse_seeds(label: str) -> list[int]:
    """The seeds of a label of :func:`seed_batches` (``"3"`` or ``"0-7"``)."""
    first, _, last = str(label).partition("-")
    try:
        a, b = int(first), int(last or first)
    except ValueError:
        raise ValueError(f"seed {label!r}: expected N or FIRST-LAST") from None
    if b < a:
        raise ValueError(f"seed {label!r}: expected FIRST <= LAST")
    return list(range(a, b + 1))


def jobs(study: dict) -> list[tuple[str, str, int]]:
    """Every job of the study: (seed label, noise label, poses)."""
    return [
        (s, noise_label(n), p) for s in seed_batches(study) for n in study["noise_um"] for p in study["poses"]
    ]


def code_digest(part: str = "point") -> str:
    """Digest of the code of a study's ``point`` jobs (``calflow mc-point``) or of its
    ``report`` (``calflow mc-aggregate`` and ``calflow mc-report``):
    :func:`calflow.provenance.code_digest`."""
    from calflow.provenance import code_digest as command_digest

    commands = ("mc-point",) if part == "point" else ("mc-aggregate", "mc-report")
    return "".join(command_digest(c, "xytheta") for c in commands)


def point_digest(study: dict) -> str:
    """Rerun digest of a study's points: the code, the base campaign's rig, clock, identification,
    model and validation settings, and the study keys every point uses (not the grid: adding
    seeds, noise levels or pose counts runs only the new points)."""
    from calflow.configuration.config import digest

    b = study["base"]
    v = b["validation"]
    used = {"targets": v.get("targets"), "dwell_s": v["dwell_s"]}  # the validation keys a point reads
    if not study.get("validation_cycles"):
        used["cycles"] = v["cycles"]
    return digest(
        [
            code_digest("point"),
            b["seed"],
            b["start"],
            b["rig"],
            b["identification"],
            used,
            b["models"][study["model"]],
            {k: study[k] for k in ("model", "validation_cycles", "rig_options")},
        ]
    )


def study_digest(study: dict) -> str:
    """Rerun digest of a study's aggregate and page: their code and the study file's keys."""
    from calflow.configuration.config import digest

    return digest([code_digest("report"), {k: v for k, v in study.items() if k not in ("base", "file")}])


def point_files(study: dict) -> list[str]:
    """The point files of a study's jobs, ``results/studies/<name>/points/<seeds>_<noise>_<poses>.json``."""
    return [layout.study_point(study["name"], s, n, p) for s, n, p in jobs(study)]


def point_seed(campaign: dict, seed: int) -> int:
    """Seed of the rig and of the pose draw of replication ``seed``: the same for every noise
    level and pose count (common random numbers; the first poses of a draw are shared)."""
    return int(np.random.SeedSequence([int(campaign["seed"]), int(seed), 8_4]).generate_state(1)[0])


# ---------------------------------------------------------------------------- simulation


def simulate_run(campaign: dict, plan, run_id: str, rig_seed: int, noise_um: float, model: str | None = None):
    """Run ``plan`` on the campaign's simulated rig with sensor noise ``noise_um``.

    Returns ``(run dataset, truth)``. The truth is for :func:`score` only.
    """
    from calflow.acquisition.runner import acquire
    from calflow.commands.common import meta
    from calflow.xytheta.stage.rig import simulated_xytheta

    rig_cfg = campaign["rig"]
    options = {**rig_cfg.get("options", {}), **rig_cfg.get("runs", {}).get(run_id, {})}
    options.update(seed=rig_seed, stream=run_id, sensor_noise_um=float(noise_um))
    rig = simulated_xytheta(**options)
    try:
        run = acquire(plan, rig, meta(campaign, "simulated", plan.name, model))
        truth = rig.truth()
    finally:
        rig.close()
    return run, truth


# ---------------------------------------------------------------------------- analysis (run datasets only)


def identify_run(run, campaign: dict, model: str):
    """Identify ``model`` of the campaign on an identification run, as ``calflow identify``.

    Returns ``(MicroModel or None, diagnostics)``; None when the least squares failed.
    """
    from calflow.identification import diagnostics
    from calflow.identification.robust import Robust
    from calflow.xytheta.models import cost
    from calflow.xytheta.models.identification import identify as fit
    from calflow.xytheta.models.kinematics import Parameters
    from calflow.xytheta.models.ladder import MicroModel

    spec = campaign["models"][model]
    theta = run["meas_theta"].values - run["meas_theta"].values[0]
    P_mx, P_my = cost.measured_points(run["meas_x"].values, run["meas_y"].values, theta)
    initial = Parameters(**{**campaign["identification"]["initial"], **spec.get("fixed", {})})
    result = fit(
        run["cmd_x"].values,
        run["cmd_y"].values,
        theta,
        P_mx,
        P_my,
        free=tuple(spec["free"]),
        initial=initial,
        robust=Robust.from_config(campaign["identification"].get("robust")),
    )
    diag = {
        "n_poses": result.n_poses,
        "residual_rms_um": result.residual_rms_um,
        "rejected": len(result.rejected),
        "condition_number": float(np.linalg.cond(result.jacobian)),
        **diagnostics.observability(result.jacobian),
    }
    if not result.success or not np.all(np.isfinite(result.parameters.as_array())):
        return None, {**diag, "failed": result.message}
    return MicroModel(model, result.parameters, result.free, result.std, result.correlation, diag), diag


def validation_accuracy(run, campaign: dict) -> dict:
    """ISO 9283 AP and RP (µm), max over the validation targets, of a validation run."""
    from calflow.commands.common import meta
    from calflow.xytheta.evaluation import xytheta_validation_metrics

    ds = xytheta_validation_metrics(
        run, meta(campaign, run.attrs["source"], "validation", run.attrs.get("model"))
    )
    return {"accuracy_um": ds.attrs["accuracy_um"], "repeatability_um": ds.attrs["repeatability_um"]}


# ---------------------------------------------------------------------------- scoring (the only use of truth)


def score(model, truth: dict, bound: dict | None = None) -> dict:
    """Per parameter: estimate, reported std, truth, signed and absolute error, z = error/std,
    and the Cramér–Rao bound on its σ (``bound``, from :func:`truth_bound`; NaN without)."""
    out = {}
    bound = bound or {}
    for name, key, units in PARAMETERS:
        free = model is not None and name in model.free
        est = getattr(model.parameters, name) if model is not None else math.nan
        std = model.std.get(name, math.nan) if free else math.nan
        err = est - float(truth[key])
        out[key] = {
            "units": units,
            "free": free,
            "estimate": est,
            "std": std,
            "truth": float(truth[key]),
            "error": err,
            "abs_error": abs(err),
            "z": err / std if std and std > 0 else math.nan,
            "crlb": bound.get(name, math.nan) if free else math.nan,
        }
    return out


def truth_bound(run, truth: dict, free) -> dict:
    """Cramér–Rao bound (µm or degree) of the ``free`` parameters at the rig's true geometry
    for the poses of an identification run, with the rig's true noise per reading and axis:
    the vision sensor's noise, the stage's repeatability and the rounding to the sensor's
    resolution (uniform, res/√12) in quadrature; the angle reading's noise is not in it.
    Scoring only (truth)."""
    from calflow.xytheta.models.identification import crlb
    from calflow.xytheta.models.kinematics import Parameters

    theta = run["meas_theta"].values - run["meas_theta"].values[0]
    X, Y = run["cmd_x"].values, run["cmd_y"].values
    ok = np.isfinite(run["meas_x"].values) & np.isfinite(run["meas_y"].values) & np.isfinite(theta)
    sigma = math.hypot(
        float(truth["sensor_noise_um"]),
        float(truth["stage_repeatability_um"]),
        float(truth["sensor_resolution_um"]) / math.sqrt(12.0),
    )
    if sigma <= 0 or ok.sum() < 3:
        return {}
    p = Parameters(*(float(truth[key]) for _, key, _ in PARAMETERS))
    return crlb(p, X[ok], Y[ok], theta[ok], sigma, free=tuple(free)).std


# ---------------------------------------------------------------------------- one point


def run_point(
    base_campaign: dict,
    seed: int,
    noise_um: float,
    poses: int,
    model: str = "II",
    validation_cycles: int | None = None,
    rig_options: dict | None = None,
) -> dict:
    """One simulated campaign: identification on ``poses`` random poses with sensor noise
    ``noise_um`` (µm), identification of ``model``, validation, then scoring.

    ``rig_options`` override the base campaign's simulated-rig options.
    """
    from calflow.xytheta.plans import poses as plans

    c = base_campaign
    if rig_options:
        c = {**c, "rig": {**c["rig"], "options": {**c["rig"].get("options", {}), **rig_options}}}
    p, v = c["identification"], c["validation"]
    rig_seed = point_seed(c, seed)
    plan = plans.identification(
        int(poses), p["x_um"], p["y_um"], p["theta_deg"], seed=rig_seed, dwell_s=p["dwell_s"]
    )
    ident_run, truth = simulate_run(c, plan, "identification", rig_seed, noise_um)

    identified, diag = identify_run(ident_run, c, model)  # the run dataset only
    accuracy = {"accuracy_um": math.nan, "repeatability_um": math.nan}
    if identified is not None:
        vplan = plans.validation(
            identified.inverse, v.get("targets"), validation_cycles or v["cycles"], v["dwell_s"]
        )
        val_run, _ = simulate_run(c, vplan, f"validation_{model}", rig_seed, noise_um, model)
        accuracy = validation_accuracy(val_run, c)  # the run dataset only

    from calflow.data.io import jsonable  # xarray: not at the workflow's start-up

    return jsonable(
        {
            "campaign": c["name"],
            "model": model,
            "seed": int(seed),
            "noise_um": float(noise_um),
            "poses": int(poses),
            "rig_seed": rig_seed,
            "failed": diag.pop("failed", None),
            "diagnostics": diag,
            **accuracy,
            "parameters": score(identified, truth, truth_bound(ident_run, truth, c["models"][model]["free"])),
        }
    )


def render_page(aggregate: dict, study: dict) -> str:
    """The study's HTML page (see :mod:`calflow.xytheta.studies.page`)."""
    from calflow.xytheta.studies.page import render

    return render(aggregate, study)
