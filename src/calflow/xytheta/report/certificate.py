"""What the XYΘ family's certificate figures are measured from, and its vision sensor's budget.

The held-out AP and RP of each model (ISO 9283, max over the held-out targets; world frame,
Eq. 4.27), the as-found AP and RP through the compensation in use (the ``as_found`` run,
when the campaign has one), an interim check's AP and RP, and ISO 230-2 of the X and Y
characterisation sweeps. The vision sensor's declared terms (µm):

* resolution: below 10 nm (thesis Sec. 3.5.1), a quantisation step of 10 nm, u = q/√12,
  per reading (in the observed scatter);
* thermal drift, Table 3.3: 0.157 µm/°C in x, 1.357 µm/°C in y, times the temperature
  excursion of the run from its first reading (the run's own thermometers, rectangular:
  max |ΔT|/√3), independent between targets;
* alignment of the world frame: its angle is the home reading's Θ (Eq. 4.27), whose
  error turns every target about home — u(Θ) from the run's own Θ scatter at repeated
  targets, as a relative term (1e-6 rad = 1 ppm).

The pattern's pitch (the reference standard of the vision sensor) has no stated
uncertainty in the source; it is left out of the budget and the certificate says so.
"""

from __future__ import annotations

import math

import numpy as np

from calflow.certificate import Measurement
from calflow.metrics.uncertainty import Term

RESOLUTION_UM = 0.01  # Sec. 3.5.1: "high resolution which is below 10 nm"
DRIFT_UM_PER_DEGC = (0.157, 1.357)  # Table 3.3, x and y
NOTES = (
    "the pattern's pitch (the vision sensor's reference standard) has no stated uncertainty: not in the budget",
)
#: The vision sensor's chain to the SI metre (the certificate's traceability statement).
TRACEABILITY = (
    "the pitch of the vision sensor's reference pattern (its calibration: not recorded in the campaign)",
    "the rig's thermometers, for the temperature the drift term uses (their calibration: not recorded)",
)


def temperature_excursion(run) -> float | None:
    """u(ΔT) in °C: the largest excursion of the run's mean thermometer reading from its first, /√3."""
    if "temperature" not in run:
        return None
    t = np.asarray(run["temperature"].values, float)
    t = t.mean(axis=tuple(range(1, t.ndim))) if t.ndim > 1 else t
    t = t[np.isfinite(t)]
    return float(np.max(np.abs(t - t[0])) / math.sqrt(3.0)) if t.size else None


def _theta_ppm(run) -> float:
    """u of the world frame's angle (1e-6 rad): the within-target scatter of the Θ readings."""
    pose = run["pose"].values
    th = np.asarray(run["meas_theta"].values, float)
    groups = [th[(pose == p) & np.isfinite(th)] for p in np.unique(pose[pose > 0])]
    groups = [g for g in groups if g.size >= 2]
    if not groups:
        return 0.0
    dof = sum(g.size - 1 for g in groups)
    s = math.sqrt(sum(float(((g - g.mean()) ** 2).sum()) for g in groups) / dof)
    return math.radians(s) * 1e6


def vision_terms(run, axes: tuple[int, ...] = (0, 1)) -> tuple[tuple[Term, ...], tuple[str, ...]]:
    """The vision sensor's terms for a run (µm) and what the budget leaves out, in words."""
    notes = list(NOTES)
    terms = [Term("sensor resolution", RESOLUTION_UM / math.sqrt(12.0), scope="reading")]
    dT = temperature_excursion(run)
    if dT is None:
        notes.append(
            "the run has no thermometer: the sensor's thermal drift (Table 3.3) is not in the budget"
        )
    else:
        drift = tuple(DRIFT_UM_PER_DEGC[a] * dT for a in axes)
        terms.append(Term("sensor thermal drift (Table 3.3)", drift, scope="target"))
    if len(axes) == 2:
        terms.append(Term("alignment: world-frame angle", _theta_ppm(run), scope="common", relative=True))
    return tuple(terms), tuple(notes)


def _targets(run):
    """Command (T, 2) and the attained world-frame points of each target of an XYΘ run."""
    from calflow.xytheta.evaluation import attained_points

    x, y = attained_points(run)
    pose = run["pose"].values
    cmd, att = [], []
    for p in np.unique(pose[pose > 0]):
        sel = (pose == p) & np.isfinite(x) & np.isfinite(y)
        if sel.sum() < 2:
            continue
        cmd.append([run["target_x"].values[sel][0], run["target_y"].values[sel][0]])
        att.append(np.column_stack([x[sel], y[sel]]))
    return np.array(cmd), att


def _iso9283(path, run, label, state) -> Measurement | None:
    cmd, att = _targets(run)
    if len(att) == 0:
        return None
    terms, notes = vision_terms(run)
    return Measurement(
        path=path,
        keys={"accuracy": "accuracy_um", "repeatability": "repeatability_um"},
        data={"command": cmd, "attained": att},
        terms=terms,
        label=label,
        notes=notes,
        state=state,
        traceability=TRACEABILITY,
    )


def measurements(campaign: dict, files: list[str]) -> list[Measurement]:
    """The XYΘ figures with a U (:class:`calflow.certificate.Measurement`)."""
    from calflow.data.io import open_dataset
    from calflow.metrics.iso230_2_runs import tables_of_run
    from calflow.summary_routing import route
    from calflow.xytheta.family import FAMILY

    out = []
    if "interim_check" in campaign:
        for f in files:
            if f.endswith(f"{campaign['name']}/runs/interim_check.nc"):
                m = _iso9283(
                    ("interim_check",), open_dataset(f, kind="run"), "interim check (as found)", "as_found"
                )
                out += [m] if m else []
        return out
    found = route(files, FAMILY.summary_sections, "XYΘ family")
    spec = campaign.get("as_found") or {}
    for _, run in found.get("as_found_runs", []):  # first: the as-left loop decides as_found with its U
        label = f"Model {spec.get('model')}, as found through {spec.get('reference')}"
        for path in (("models", str(spec.get("model")), "as_found"), ("as_found",)):
            m = _iso9283(path, run, label, "as_found")
            out += [m] if m else []
    for _, run in found.get("heldout_runs", []):
        model = run.attrs.get("model")
        m = _iso9283(("models", str(model)), run, f"Model {model}, held-out targets", "as_left")
        out += [m] if m else []
    for _, run in found.get("iso230_2", []):
        from calflow.xytheta.tables.characterisation import stage_positions

        axis = run.attrs["plan"][-1]
        u, v = stage_positions(run)
        targets, fwd, bwd, *_ = tables_of_run(run, u if axis == "x" else v, run[f"cmd_{axis}"].values)
        terms, notes = vision_terms(run, (0,) if axis == "x" else (1,))
        out.append(
            Measurement(
                path=("iso230_2", axis),
                keys={k: f"{k}_um" for k in ("E", "M", "B", "A", "R")},
                kind="iso230_2",
                data={"targets": targets, "forward": fwd, "backward": bwd},
                terms=terms,
                label=f"ISO 230-2, {axis.upper()} stage (characterisation sweep)",
                notes=notes,
                traceability=TRACEABILITY,
            )
        )
    return out
