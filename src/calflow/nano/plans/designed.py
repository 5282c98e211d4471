"""The designed training plan of the nano campaigns, its bound before acquisition and the
achieved σ after identification (``training.plan: optimal``).

Noise model of a training reading (the mean of the last ``average_last_s`` of a dwell):
σ² = σ_pose² + σ_sample² / N, σ_pose the stage's repeatability per visit (not reduced by
averaging), σ_sample the interferometer's noise per sample (with its quantisation,
r²/12), N = ``average_last_s`` × the sample rate. Averaging inside a dwell costs no time,
and the dwell is set by the settling and creep of a move (which no noise model here
describes), so dwell and averaging stay the configured ones; the design chooses the
positions (:mod:`calflow.nano.plans.design`) and the number of cycles. Time model: each reading
takes the rig's rise time plus the dwell (Fig. 5.8).
"""

from __future__ import annotations

import json

import numpy as np

from calflow.identification.design import crlb_sigma
from calflow.nano.plans import design
from calflow.nano.plans import sequences as plans

NOT_WHITE = (
    "The Cramér–Rao bound assumes white reading noise (the sensor's noise model). The stage's "
    "thermal drift, hysteresis and creep are not white noise and the thermal terms are "
    "identified only through the temperature the training happens to see, so the bound is a "
    "lower bound: the achieved σ is larger."
)


def _stroke(c: dict) -> tuple[np.ndarray, np.ndarray]:
    t = c["training"]
    d = 1 if c["robot"] == "stage1d" else 2
    return np.full(d, float(t["start_um"])), np.full(d, float(t["stop_um"]))


def noise_model(c: dict) -> dict | None:
    """σ of a reading's parts (nm) and the sample rate (Hz): ``training.design.noise_nm`` when
    given, else the simulated rig's declared options; None for a rig that declares none."""
    given = c["training"]["design"].get("noise_nm") or {}
    if given.get("pose") is not None and given.get("sample") is not None:
        return {
            "pose": float(given["pose"]),
            "sample": float(given["sample"]),
            "rate_hz": float(given.get("rate_hz", 10.0)),
        }
    if c["rig"]["factory"] != "simulated":
        return None
    from calflow.nano.stage import rig

    check = rig.check_nano1d if c["robot"] == "stage1d" else rig.check_nano2d  # the family's declared check
    o = check(**(c["rig"].get("options") or {}))  # the options with the rig's defaults
    return {
        "pose": float(o["repeatability_nm"]),
        "sample": float(
            np.hypot(o["interferometer_noise_nm"], o["interferometer_resolution_nm"] / np.sqrt(12))
        ),
        "rate_hz": float(o["stream_rate_hz"]),
    }


def reading_sigma_um(noise: dict, average_s: float) -> float:
    """σ (µm) of a reading averaged over ``average_s`` s under the noise model."""
    n = max(1, int(round(average_s * noise["rate_hz"])))
    return float(np.sqrt(noise["pose"] ** 2 + noise["sample"] ** 2 / n)) * 1e-3


def reading_s(c: dict) -> float:
    """Time of one training reading (s): the rig's rise time (Fig. 5.8: 4 s) plus the dwell."""
    rise = (
        (c["rig"].get("options") or {}).get("rise_time_s", 4.0) if c["rig"]["factory"] == "simulated" else 4.0
    )
    return float(rise) + float(c["training"]["dwell_s"])


def grid_positions(c: dict) -> np.ndarray:
    """The thesis's training grid (n, d) µm: start:step:stop on every axis."""
    t = c["training"]
    g = np.arange(t["start_um"], t["stop_um"] + 1e-9, t["step_um"])
    if c["robot"] == "stage1d":
        return g[:, None]
    X, Y = np.meshgrid(g, g, indexing="ij")
    return np.column_stack([X.ravel(), Y.ravel()])


def cycle_rows(c: dict, positions: np.ndarray) -> np.ndarray:
    """The readings (R, d) µm of one cycle at ``positions``: there and back (1-DoF), raster (2-DoF)."""
    if c["robot"] == "stage1d":
        return plans.sweep_1d("training", np.sort(positions[:, 0]), 1, 0.0).commands["x"][:, None]
    return positions[design.raster(positions)]


def designed_positions(c: dict) -> np.ndarray:
    """The designed training positions (n, d) µm: ``design.positions`` of them (default: as
    many as the grid), from a candidate grid of ``design.candidate_step_um`` over the stroke."""
    d = c["training"]["design"]
    lo, hi = _stroke(c)
    pool = design.candidates(lo, hi, float(d["candidate_step_um"]))
    n = int(d["positions"] or len(grid_positions(c)))
    if n > len(pool):
        raise ValueError(f"training.design.positions: {n} asked from {len(pool)} candidate positions")
    idx = design.design_positions(
        pool, n, c["model"]["order"], np.maximum(np.abs(lo), np.abs(hi)), d["criterion"], d["space_filling"]
    )
    return pool[idx]


def bound(c: dict, positions: np.ndarray, cycles: int) -> dict:
    """What a plan promises before acquisition: positions, cycles, rig time (h), the reading
    σ of the noise model (nm), the Cramér–Rao σ of the geometric coefficients (units of the
    model's table) and of the geometric correction over the stroke (nm). None without a noise model."""
    lo, hi = _stroke(c)
    order = c["model"]["order"]
    rows = cycle_rows(c, positions)
    noise = noise_model(c)
    out = {
        "positions": int(len(positions)),
        "positions_um": np.asarray(positions).tolist(),
        "cycles": int(cycles),
        "readings": int(len(rows) * cycles),
        "rig_time_h": len(rows) * cycles * reading_s(c) / 3600.0,
        "noise_nm": noise,
        "reading_sigma_nm": None,
        "crlb_sigma": None,
        "crlb_shape_sigma_nm": None,
        "statement": NOT_WHITE,
    }
    if noise is None:
        return out
    s = reading_sigma_um(noise, c["training"]["average_last_s"])
    sig = design.coefficient_sigma(rows, cycles, s, order, np.maximum(np.abs(lo), np.abs(hi)))
    out["reading_sigma_nm"] = s * 1e3
    out["crlb_sigma"] = _both_axes(c, dict(zip(coefficient_names(c), (float(v) for v in sig))))
    out["crlb_shape_sigma_nm"] = design.shape_sigma_um(rows, cycles, s, order, lo, hi) * 1e3
    return out


def _both_axes(c: dict, sigma: dict) -> dict:
    """The q_x equation's σ, and for 2-DoF the same for the q_y equation (same basis, same readings)."""
    if c["robot"] == "stage1d":
        return sigma
    return {**sigma, **{k[:-1] + "y": v for k, v in sigma.items()}}


def coefficient_names(c: dict) -> list[str]:
    """Names of the geometric coefficients in the model's table: a_i (1-DoF); a_ix, b_ix (2-DoF, q_x equation;
    the q_y equation has the same basis, hence the same bound)."""
    n = c["model"]["order"]
    if c["robot"] == "stage1d":
        return [f"a_{i}" for i in range(1, n + 1)]
    return [f"a_{i}x" for i in range(1, n + 1)] + [f"b_{i}x" for i in range(1, n + 1)]


def designed_plan(c: dict) -> tuple[np.ndarray, int, dict]:
    """Positions (n, d), cycles and the design record of ``training.plan: optimal``.

    Cycles: ``design.cycles`` if given, else the fewest whose σ of the geometric correction
    over the stroke is at most ``design.sigma_target_nm`` (null: the grid's own bound, i.e.
    the grid's precision in the least time), and at least ``design.min_training_h`` of
    training (the thermal terms are identified only through the temperature variation the
    training sees: the duration, not the positions, decides it).
    """
    d = c["training"]["design"]
    noise = noise_model(c)
    positions = designed_positions(c)
    rows = cycle_rows(c, positions)
    lo, hi = _stroke(c)
    grid = bound(c, grid_positions(c), c["training"]["cycles"])
    target = d["sigma_target_nm"] if d["sigma_target_nm"] is not None else grid["crlb_shape_sigma_nm"]
    if d["cycles"]:
        cycles = int(d["cycles"])
    elif noise is None or target is None:
        raise ValueError(
            "training.design.noise_nm: the rig declares no noise model; expected pose and sample (nm), "
            "or training.design.cycles"
        )
    else:
        s = reading_sigma_um(noise, c["training"]["average_last_s"])
        cycles = design.cycles_for(target * 1e-3, rows, s, c["model"]["order"], lo, hi)
    per_cycle_h = len(rows) * reading_s(c) / 3600.0
    if d["min_training_h"]:
        cycles = max(cycles, int(np.ceil(d["min_training_h"] / per_cycle_h - 1e-9)))
    cycles = max(cycles, 2)  # a repeatability needs two visits (ISO 230-2)
    record = {
        "criterion": d["criterion"],
        "space_filling": float(d["space_filling"]),
        "candidate_step_um": float(d["candidate_step_um"]),
        "sigma_target_nm": target,
        "min_training_h": d["min_training_h"],
        "grid": {k: grid[k] for k in ("positions", "cycles", "rig_time_h", "crlb_shape_sigma_nm")},
    }
    return positions, cycles, record


def start_s(c: dict, duration_s: float) -> float:
    """Campaign time (s) the designed training starts: so that it ends when validation starts
    (``design.ends_at_validation``, the thesis's "time 0 = end of training"), else 0."""
    if c["training"]["design"]["ends_at_validation"] and "validation" in c:
        return max(0.0, float(c["validation"]["start_h"]) * 3600.0 - duration_s)
    return 0.0


def _recorded_bound(c: dict, run, sigma_um: float, kept: set[str] | None) -> dict:
    """Cramér–Rao σ of the terms of each equation of the model on the readings the training
    recorded (measured positions and thermocouples, λ a nuisance, σ per reading): the terms
    stepwise kept (``kept``; every term when None) — collinear thermocouples left out would
    otherwise inflate the bound of the ones kept."""
    two = c["robot"] == "stage2d"
    axes = ["x", "y"] if two else ["x"]
    X = np.column_stack([run[f"meas_{a}"].values for a in axes])
    order = c["model"]["order"]
    cols = [design.basis(X, order, np.nanmax(np.abs(X), axis=0))[:, 0, :]]
    scale = list(design.coefficient_scale(order, np.nanmax(np.abs(X), axis=0)))
    k = 0
    if "temperature" in run:
        t = np.asarray(run["temperature"].values, dtype=float).reshape(len(X), -1)
        k = t.shape[1]
        cols.append(t - np.nanmean(t, axis=0))
        scale += [1.0] * k
    R = np.column_stack(cols)
    R, scale = R[np.isfinite(R).all(axis=1)], np.array(scale)
    out = {}
    for eq in axes if two else [""]:
        geo = [n[:-1] + eq for n in coefficient_names(c)] if two else coefficient_names(c)
        names = geo + [f"{'c' if two else 'b'}_{i}{eq}" for i in range(1, k + 1)]
        use = np.array([kept is None or n in kept or n in geo for n in names])  # the geometric terms always
        s = crlb_sigma(R[:, None, use], sigma_um) / scale[use]
        out.update({n: float(v) for n, v in zip(np.array(names)[use], s)})
    return out


def training_design_block(c: dict, training_run, models: dict) -> dict | None:
    """``training_design`` of summary.json: the plan's record and bound written before
    acquisition (run attribute ``design``), and after identification the achieved σ of each
    term (the model's standard error, terms stepwise kept), the Cramér–Rao σ of the kept terms
    on the recorded positions and temperatures (thermal terms included), their ratio, the rig
    time the training took, and for a designed plan the design study (:func:`design_study`:
    how many positions, how long). None when the training run carries no design record."""
    if training_run is None or "design" not in training_run.attrs:
        return None
    record = json.loads(training_run.attrs["design"])
    table = models.get("single" if c["robot"] == "stage1d" else "two_dof") or []
    achieved = {
        r["name"]: (float(r["std_error"]) if r["in_model"] else None) for r in table if r["name"][0] in "abc"
    }  # a_i, b_i, c_i: the geometric and thermal terms (not λ)
    noise = record.get("noise_nm")
    kept = {r["name"] for r in table if r["in_model"]} if table else None
    sigma = reading_sigma_um(noise, c["training"]["average_last_s"]) if noise else None
    recorded = _recorded_bound(c, training_run, sigma, kept) if noise else None
    ratio = (
        {k: (achieved[k] / v if achieved.get(k) is not None and v > 0 else None) for k, v in recorded.items()}
        if recorded
        else None
    )
    from calflow.nano.evaluation import run_seconds

    time = run_seconds(training_run) if "time" in training_run else np.array([])
    if record.get("plan") == "optimal" and noise:
        record["study"] = design_study(
            c, target_nm=record.get("sigma_target_nm")
        )  # how many positions, how long
    return {
        **record,
        "achieved_sigma": achieved,
        "crlb_sigma_recorded": recorded,
        "sigma_ratio_achieved_to_recorded_bound": ratio,
        "rig_time_h_achieved": float((time.max() - time.min()) / 3600.0) if time.size else None,
    }


def design_study(c: dict, counts=None, target_nm: float | None = None) -> dict:
    """How many positions, how long: for each count of positions, the Cramér–Rao σ (nm) of the
    geometric correction over the stroke after one hour of training, grid (evenly spaced, the
    2-DoF grid √n per axis) against designed, and the hours each needs for ``target_nm``
    (default: the configured grid's bound). From the information alone (σ ∝ 1/√hours, whole
    cycles ignored): no acquisition, and no thermal term — the duration the thermal terms
    need is the room's, not the noise model's."""
    lo, hi = _stroke(c)
    order = c["model"]["order"]
    noise = noise_model(c)
    if noise is None:
        raise ValueError(
            "training.design.noise_nm: the rig declares no noise model; expected pose and sample (nm)"
        )
    if counts is None:
        counts = (4, 6, 8, 12, 17, 24, 33) if len(lo) == 1 else (16, 25, 36, 49, 64, 81)
    s = reading_sigma_um(noise, c["training"]["average_last_s"])
    target = (
        target_nm
        if target_nm is not None
        else bound(c, grid_positions(c), c["training"]["cycles"])["crlb_shape_sigma_nm"]
    )
    out = {
        "positions": [],
        "grid_sigma_nm_1h": [],
        "designed_sigma_nm_1h": [],
        "grid_hours": [],
        "designed_hours": [],
        "target_nm": target,
    }
    for n in counts:
        side = int(round(n ** (1 / len(lo))))
        if side < 2 or side ** len(lo) != n and len(lo) > 1:
            continue
        axes = [np.linspace(a, b, side) for a, b in zip(lo, hi)]
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, len(lo))
        d = dict(c, training={**c["training"], "design": {**c["training"]["design"], "positions": n}})
        sig = []
        for positions in (grid, designed_positions(d)):
            rows = cycle_rows(c, positions)
            hours = len(rows) * reading_s(c) / 3600.0
            sig.append(design.shape_sigma_um(rows, 1, s, order, lo, hi) * 1e3 * np.sqrt(hours))
        out["positions"].append(int(n))
        for key, v in zip(("grid", "designed"), sig):
            out[f"{key}_sigma_nm_1h"].append(float(v))
            out[f"{key}_hours"].append(float((v / target) ** 2))
    return out
