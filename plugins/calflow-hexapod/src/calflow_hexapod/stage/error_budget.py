"""Error budget of the hexapod's calibration at the held-out targets, per effect of the simulated rig.

What is left of each effect once a model has calibrated the rig — test and report use only:
it reads the simulated rig's effects. Analysis code never imports it.

For every effect ``e`` of :data:`calflow_hexapod.stage.physics.EFFECTS` the rig has on, the
campaign's calibration is replayed in-process — identification plan, identification of every
model (:func:`calflow_hexapod.models.identification.identify`), held-out validation through each
model's inverse — on the same rig with ``e`` switched off, with the same seeds and noise
streams as the workflow's runs (stream = run id). One more replay, the *baseline*, has every
effect off: what is left is noise (legs' repeatability, the tracker's random error) through
identification and validation, and a model's structural error on a rig it should describe.

How the contributions combine (as the XYΘ budget): per model the score is the mean square of
the per-target systematic errors, MS = mean_k AP_k² (ISO 9283 AP of target k, the distance
from the target to the barycentre of its visits), for the position (µm) and the orientation
(degree, the norm of AP_a, AP_b, AP_c). With every effect on, MS_full = MS_baseline +
Σ_e ΔMS_e + MS_interaction, ΔMS_e = MS_full − MS_{−e}; entries are sign(ΔMS)·√|ΔMS|.

The repeatability floor (:func:`floor`) is the held-out validation commanded through the
rig's *true* parameters (:func:`calflow_hexapod.stage.rig.truth_parameters`): the accuracy a
perfect geometric model reaches on this rig, and the pooled within-target scatter of the
readings (per reading and axis) — what no model can remove.
"""

from __future__ import annotations

import numpy as np

from calflow.rigs.simulated.budget import Replays, budget_command, decompose, effects_of, require_simulated
from calflow_hexapod.models.calibration import HexapodModel, command
from calflow_hexapod.models.geometry import AXES, h811
from calflow_hexapod.models.identification import identify, run_inputs
from calflow_hexapod.models.ladder import LADDER
from calflow_hexapod.plans import campaign as campaign_plans
from calflow_hexapod.plans import design as design_plan
from calflow_hexapod.plans.poses import validation
from calflow_hexapod.stage.physics import EFFECTS, options_off, truth_from_options
from calflow_hexapod.stage.rig import simulated_hexapod, truth_parameters

REPLAYS = ("baseline", *EFFECTS)  # "baseline": every effect off; any other: that effect off


def _options(c: dict) -> dict:
    return dict(c["rig"].get("options") or {})


def active_effects(c: dict) -> list[str]:
    """The effects the campaign's simulated rig has switched on."""
    return EFFECTS.active(
        truth_from_options({k: v for k, v in _options(c).items() if k not in ("seed", "stream")})
    )


def replay_options(name: str) -> dict:
    """Rig options of a replay: every effect off (``baseline``), one effect off, none (``none``)."""
    return {} if name == "none" else options_off() if name == "baseline" else options_off(name)


def _acquire(c: dict, overrides: dict, acquisition) -> dict:
    """Readings (arrays by name, with ``cmd_*``) of a plan on the campaign's simulated rig with
    ``overrides``, stream = the run id, as the acquisition runner's bulk path takes them."""
    o = {**_options(c), **overrides}
    rig = simulated_hexapod(
        seed=int(o.pop("seed", c["seed"])),
        stream=acquisition.run_id,
        **{k: v for k, v in o.items() if k != "stream"},
    )
    plan = acquisition.plan
    got = rig.visit(plan.commands, plan.dwell_s)
    return {**got, **{f"cmd_{a}": np.asarray(plan.commands[a], dtype=float) for a in AXES}}


def _run_dataset(readings: dict):
    import xarray as xr

    data = {k: ("sample", np.asarray(v, dtype=float)) for k, v in readings.items() if k not in ("T1", "T2")}
    temps = np.column_stack([readings["T1"], readings["T2"]])
    return xr.Dataset({**data, "temperature": (("sample", "sensor"), temps)}, coords={"sensor": ["T1", "T2"]})


def identify_models(c: dict, overrides: dict, acquire=_acquire) -> dict[str, HexapodModel]:
    """Every model of the campaign identified from the identification run on the rig with
    ``overrides``; ``acquire(campaign, overrides, acquisition) -> readings`` runs a plan (default:
    the simulated rig, :func:`_acquire`)."""
    run = _run_dataset(acquire(c, overrides, campaign_plans.identification(c, None)))
    ctl = h811()
    measured, lam, temperature = run_inputs(run, ctl)
    noise = design_plan.noise_model(c) or {"position_um": 1.0, "angle_deg": 1e-4, "leg_um": 0.0}
    sigma = (noise["position_um"],) * 3 + (noise["angle_deg"],) * 3
    out = {}
    for name, spec in (c.get("models") or {}).items():
        free = tuple((spec or {}).get("free") or LADDER[name])
        fit = identify(
            measured,
            lam,
            ctl.zero_lengths,
            free=free,
            initial=design_plan.nominal_parameters(c),
            sigma_pose=sigma,
            sigma_leg_um=noise["leg_um"],
            temperature=temperature,
        )
        out[name] = HexapodModel.from_identification(name, fit, ctl)
    return out


def per_target(readings: dict, plan) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per target of a validation plan: AP of the position (µm) and of the orientation (degree,
    norm of AP_a, AP_b, AP_c) — ISO 9283:1998 Sec. 7.2.1 — and the within-target residuals (rows
    of the readings less their target's barycentre, for the floor)."""
    meas = np.column_stack([readings[f"meas_{a}"] for a in AXES])
    target = np.column_stack([plan.targets[a] for a in AXES])
    rows = np.asarray(plan.pose) > 0
    ap_um, ap_deg, scatter = [], [], []
    for k in np.unique(np.asarray(plan.pose)[rows]):
        sel = np.asarray(plan.pose) == k
        bary = meas[sel].mean(0)
        ap_um.append(float(np.linalg.norm(bary[:3] - target[sel][0, :3])))
        ap_deg.append(float(np.linalg.norm(bary[3:] - target[sel][0, 3:])))
        scatter.append(meas[sel] - bary)
    return np.array(ap_um), np.array(ap_deg), np.vstack(scatter)


def _heldout(c: dict, overrides: dict, commands, name: str, acquire=_acquire):
    h = c["validation"]["heldout"]
    plan = validation(commands, campaign_plans.heldout_targets(c), h["cycles"], c["validation"]["dwell_s"])
    from calflow.plan import Acquisition

    return per_target(acquire(c, overrides, Acquisition(plan, f"validation_heldout_{name}", name)), plan)


def replay_heldout(c: dict, overrides: dict, acquire=_acquire) -> dict[str, dict[str, list[float]]]:
    """Per-target held-out AP of every model (``ap_um``, ``ap_deg``) after the calibration replayed
    on the rig with ``overrides`` (through ``acquire``, default the simulated rig)."""
    out = {}
    for name, model in identify_models(c, overrides, acquire).items():
        ap_um, ap_deg, _ = _heldout(c, overrides, model.command, name, acquire)
        out[name] = {"ap_um": ap_um.tolist(), "ap_deg": ap_deg.tolist()}
    return out


BUDGET = Replays(replay_options, active_effects, lambda c, options: replay_heldout(c, options))


def replay(c: dict, name: str) -> dict:
    """One replay of the budget (:data:`REPLAYS`, or ``none``): per-target held-out AP by model,
    or ``active: false`` when the campaign's rig has that effect off already."""
    return BUDGET.replay(c, name)


def floor(c: dict, noise_of: str = "truth") -> dict:
    """The rig's own floor at the held-out targets: validation through the true parameters on the
    campaign's rig (every effect as configured). ``accuracy_um``/``accuracy_deg``: max AP;
    ``floor_um``/``floor_deg``: pooled within-target σ per reading and axis. ``noise_of``: the
    held-out run whose noise stream the validation draws — its own (``truth``), or a model's,
    so that the floor and that model's held-out AP differ only by the model (common random numbers)."""
    t = truth_from_options({k: v for k, v in _options(c).items() if k not in ("seed", "stream")})
    phi = truth_parameters(t)
    ap_um, ap_deg, scatter = _heldout(c, {}, lambda targets: command(phi, h811(), targets), noise_of)
    dof = max(len(scatter) - len(ap_um), 1)
    s = np.sqrt(np.sum(scatter**2, axis=0) / dof)
    return {
        "accuracy_um": float(ap_um.max()),
        "accuracy_deg": float(ap_deg.max()),
        "floor_um": float(np.sqrt(np.mean(s[:3] ** 2))),
        "floor_deg": float(np.sqrt(np.mean(s[3:] ** 2))),
    }


def combine(heldout: dict[str, dict[str, list[float]]], records: list[dict]) -> dict:
    """The budget of every model from the campaign's own held-out per-target AP and the replays'
    (module docstring): per model and quantity (``um``, ``deg``), ``rms_ap`` and ``budget``
    (effect → signed entry, with ``baseline`` and ``interaction``); Σ sign·v² = rms_ap²."""
    by, effects = effects_of(records)
    models: dict = {}
    for name, ap in heldout.items():
        models[name] = {}
        for unit in ("um", "deg"):
            without = {e: by[e]["ap"][name][f"ap_{unit}"] for e in effects}
            rms, budget = decompose(ap[f"ap_{unit}"], by["baseline"]["ap"][name][f"ap_{unit}"], without)
            models[name][unit] = {"rms_ap": rms, "budget": budget}
    unmodelled = [e for e in effects if not EFFECTS.modelled(e)]
    return {"effects": effects, "unmodelled": unmodelled, "models": models}


def error_budget(c: dict, names=REPLAYS) -> dict:
    """The whole budget of a campaign on its simulated rig: the campaign's own held-out AP, each
    replay, their combination and the floor."""
    require_simulated(c, f"campaign {c['name']}")
    records = BUDGET.run(c, names)
    full = replay(c, "none")["ap"]
    return {"campaign": c["name"], "replays": records, "budget": combine(full, records), "floor": floor(c)}


#: ``calflow hexapod-error-budget --campaign FILE --out FILE.json`` for a hexapod campaign: the
#: budget's replays, combination and floor, written as JSON for the summary (tests and reports)
def error_budget_command(args) -> None:
    budget_command(lambda path, c, jobs: error_budget(c))(args)
