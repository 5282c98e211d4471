"""Error budget after calibration at the held-out targets, per effect of the simulated rig.

What is left of each effect once a model has calibrated the rig. Test and report use
only, like the oracle (:mod:`calflow.xytheta.stage.oracle`): it reads the simulated rig's
effects. Analysis code never imports it.

For every effect ``e`` the rig has on, the campaign's calibration is replayed in-process —
characterisation and XY tables, identification of every model, angle characterisation,
held-out validation — on the same rig with ``e`` switched off, with the same seeds and
noise streams, through the same command functions the workflow's jobs run. One more
replay, the *baseline*, has every effect off: what is left is noise (stage repeatability,
sensor noise and resolution, through identification, tables and validation) and the
model's own structural error on a rig it should describe (Model I's fixed α, β).

How the contributions combine. Per model, the score is the mean square of the per-target
systematic errors at the held-out targets, MS = mean_k AP_k² (µm², AP_k the ISO 9283
distance from target k to the barycentre of its visits). With every effect on,

    MS_full = MS_baseline + Σ_e ΔMS_e + MS_interaction,   ΔMS_e = MS_full − MS_{−e},

ΔMS_e what switching ``e`` off removes, MS_baseline the baseline replay's MS, and the
interaction the remainder (effects that add or cancel in the same direction are not
additive). The budget is given in µm as sign(ΔMS)·√|ΔMS|; the RMS of AP_k is √MS_full.
An effect a model compensates has a small ΔMS_e; one it cannot has ΔMS_e near the
effect's own mean square at the targets.

A rig that reads its sensor through images (``sensor: images``, :mod:`.images`) has no
noise-model terms (``decode``, ``gross_errors``): its sensor is one more effect,
``sensor``, whose replay reads the camera point exactly (no frames, no noise), so ΔMS_sensor
is what the rendered frames and their decoding add. Its campaigns also replay once with
the noise-model sensor (``noise_model``, not an effect of the budget): the same calibration
with the sensor the rig has without images, side by side in the summary.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import yaml

from calflow.configuration.campaign import raw as campaign_file
from calflow.configuration.campaign import thaw
from calflow.rigs.simulated.budget import (
    Replays,
    budget_command,
    decompose,
    effects_of,
    require_simulated,
    signed_root,
)
from calflow.step import Job
from calflow.xytheta.stage.physics import EFFECTS, XYThetaTruth, options_off, truth_from_options

REPLAYS = ("baseline", *EFFECTS)  # "baseline": every effect off; any other: that effect off
NOISE_MODEL = {"sensor": "model", "camera": None, "pattern": None}  # an images rig read by the noise model
IDEAL_SENSOR = {  # the camera point read exactly: the "sensor" effect of an images rig switched off
    **NOISE_MODEL,
    "sensor_noise_um": 0.0,
    "sensor_theta_noise_deg": 0.0,
    "decode_error_um": 0.0,
    "gross_error_rate": 0.0,
    "sensor_resolution_um": 1e-6,
}
IMAGES_ONLY = {"sensor": IDEAL_SENSOR, "noise_model": NOISE_MODEL}  # replays of an images rig only
MODEL_ONLY = ("decode", "gross_errors")  # effects of the noise-model sensor


def reads_images(options: dict) -> bool:
    """True when rig options ``options`` read the vision sensor through images."""
    return (options or {}).get("sensor") == "images"


def budget_replays(campaign: dict) -> tuple[str, ...]:
    """The replays a campaign's budget file holds: the effects' (``validation.heldout.error_budget``,
    with ``sensor`` on an images rig) and, on an images rig, ``noise_model``."""
    images = reads_images(campaign["rig"].get("options") or {})
    names = (*REPLAYS, "sensor") if images else REPLAYS
    names = names if campaign["validation"]["heldout"].get("error_budget", True) else ()
    return (*names, "noise_model") if images else names


def active_effects(truth: XYThetaTruth, images: bool = False) -> list[str]:
    """The effects (names of :data:`EFFECTS`) that ``truth`` has switched on; on a rig that
    reads through images (``images``), the noise model's own (:data:`MODEL_ONLY`) are not
    and ``sensor`` is."""
    names = EFFECTS.active(truth)
    if images:
        names = [n for n in names if n not in MODEL_ONLY] + ["sensor"]
    return names


def replay_options(replay: str) -> dict:
    """Rig options of a replay: every effect off (``baseline``), one effect off, the sensor
    read exactly or by the noise model (images rigs: ``sensor``, ``noise_model``), or none
    (``none``)."""
    if replay == "none":
        return {}
    if replay == "baseline":
        return options_off()
    if replay in IMAGES_ONLY:
        return dict(IMAGES_ONLY[replay])
    return options_off(replay)


def replay_heldout(campaign_path: str | Path, rig_options: dict, work: Path) -> dict[str, list[float]]:
    """Per-target AP (µm) at the held-out targets of every model, after replaying the
    campaign's XYΘ calibration in ``work`` on its simulated rig with ``rig_options``
    overriding the campaign's. Same seeds and noise streams as the campaign's own runs."""
    from calflow.commands.acquire import acquire_job
    from calflow.commands.common import campaign as load
    from calflow.data.io import open_dataset, write_dataset
    from calflow.xytheta import steps as commands

    raw = thaw(campaign_file(campaign_path))
    raw.setdefault("rig", {})
    raw["rig"]["options"] = {**(raw["rig"].get("options") or {}), **rig_options}
    work.mkdir(parents=True, exist_ok=True)
    path = work / Path(campaign_path).name  # the same stem: the same campaign name, seeds and streams
    path.write_text(yaml.safe_dump(raw))
    c_path, f = str(path), lambda name: str(work / name)
    c = load(c_path)

    def run(plan: str, out: str, model: str | None = None) -> None:  # `calflow acquire`, without a journal
        args = Job.of("acquire", model=[f(model)] if model else None, luts=None, compensation="none")
        write_dataset(acquire_job(c, plan, args)[0], f(out))

    def identify(name: str, **files) -> None:
        ns = dict(
            campaign=c_path,
            model_name=name,
            run=f("identification.nc"),
            luts=None,
            base=None,
            residuals=None,
            out=f(f"{name}.nc"),
        )
        commands.identify(c, Job.of("identify", **{**ns, **{k: f(v) for k, v in files.items()}}))

    models = c["models"]
    if any(s.get("position_table") for s in models.values()):
        run("characterisation_x", "cx.nc")
        run("characterisation_y", "cy.nc")
        commands.characterise(
            Job.of("characterise", campaign=c_path, x=f("cx.nc"), y=f("cy.nc"), out=f("luts.nc"))
        )
    run("identification", "identification.nc")
    for name, spec in models.items():
        if "base" not in spec:
            identify(name, **({"luts": "luts.nc"} if spec.get("position_table") else {}))
    for base in sorted({s["base"] for s in models.values() if "base" in s}):
        run("angle_residuals", f"angle_{base}.nc", f"{base}.nc")
    for name, spec in models.items():
        if "base" in spec:
            identify(name, base=f"{spec['base']}.nc", residuals=f"angle_{spec['base']}.nc")
    out = {}
    for name in models:
        run("validation_heldout", f"heldout_{name}.nc", f"{name}.nc")
        commands.metrics(
            c, Job.of("metrics", campaign=c_path, run=f(f"heldout_{name}.nc"), out=f(f"m_{name}.nc"))
        )
        out[name] = [float(v) for v in open_dataset(f(f"m_{name}.nc"))["ap"].values]
    return out


def _active(campaign_path) -> list[str]:
    from calflow.commands.common import campaign as load

    options = dict(load(campaign_path)["rig"].get("options") or {})
    return active_effects(truth_from_options(options), reads_images(options))


def _heldout(campaign_path, options: dict) -> dict[str, list[float]]:
    with tempfile.TemporaryDirectory(prefix="calflow-budget-") as tmp:
        return replay_heldout(campaign_path, options, Path(tmp))


BUDGET = Replays(replay_options, _active, _heldout, key="ap_um", always=("baseline", "none", "noise_model"))


def replay(campaign_path: str | Path, name: str) -> dict:
    """One replay of the budget (:data:`REPLAYS`, or ``none``): its per-target held-out AP
    by model, or ``active: false`` when the campaign's rig has that effect off already."""
    return BUDGET.replay(campaign_path, name)


def replays(campaign_path: str | Path, names=REPLAYS, workers: int = 1) -> list[dict]:
    """:func:`replay` of each of ``names``, over ``workers`` processes (no more than replays)."""
    return BUDGET.run(str(campaign_path) if workers > 1 else campaign_path, names, workers)


def combine(heldout_ap: dict[str, np.ndarray], records: list[dict]) -> dict:
    """The budget of every model from the campaign's own held-out per-target AP (µm) and the
    replays' (module docstring): per model ``rms_ap_um`` and ``error_budget_um`` (effect →
    signed µm, with ``baseline`` and ``interaction``); Σ sign·v² over it = rms_ap_um²."""
    by, effects = effects_of(records, skip=("noise_model",))
    models = {}
    for name, ap in heldout_ap.items():
        rms, budget = decompose(ap, by["baseline"]["ap_um"][name], {e: by[e]["ap_um"][name] for e in effects})
        models[name] = {"rms_ap_um": rms, "error_budget_um": budget}
    return {
        "effects": effects,
        "unmodelled": [e for e in effects if e in IMAGES_ONLY or not EFFECTS.modelled(e)],
        "combination": "rms_ap_um^2 = sum over error_budget_um of sign(v)*v^2, where rms_ap_um^2 is the mean "
        "over held-out targets of AP_k^2; an effect's entry is sign*sqrt(rms_ap_um^2 - the same "
        "mean after a calibration on the rig without it); baseline: every effect off; "
        "interaction: the remainder",
        "models": models,
    }


def groups(budget_um: dict[str, float], unmodelled: list[str]) -> dict[str, float]:
    """A model's budget in four parts (signed µm, combining as the entries do): ``baseline``,
    ``modelled`` (effects some calflow model represents), ``unmodelled``, ``interaction``."""

    def part(names):
        return signed_root(sum(np.sign(budget_um[n]) * budget_um[n] ** 2 for n in names))

    effects = [n for n in budget_um if n not in ("baseline", "interaction")]
    return {
        "baseline": budget_um["baseline"],
        "modelled": part([n for n in effects if n not in unmodelled]),
        "unmodelled": part([n for n in effects if n in unmodelled]),
        "interaction": budget_um["interaction"],
    }


def _budget(campaign_path: str, c: dict, jobs: int) -> dict:
    require_simulated(c, campaign_path, family=c["robot"] == "xytheta")
    return {"campaign": c["name"], "replays": replays(campaign_path, budget_replays(c), jobs)}


#: ``calflow error-budget``: the budget's replays of a campaign on its simulated rig, written as
#: JSON for the summary step (tests and reports only)
def error_budget_command(args) -> None:
    budget_command(_budget)(args)
