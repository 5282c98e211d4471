"""The designed identification plan of the XYΘ campaign: noise and time models, the pose
order, frames per pose, and the bound written before acquisition.

The time model is the simulated rig's (:class:`calflow.xytheta.stage.rig.SimulatedXYTheta`):
a move takes max(|ΔX|, |ΔY|)/v + |ΔΘ|/v_Θ + settle, then the plan dwells; a pose of k
frames reads k − 1 more frames of ``frame_s`` each. The noise model separates what
averaging removes (the sensor's per-frame noise, Table 3.3) from what it does not (the
stage's repeatability, Table 4.1, and the per-pose decoding error of the pattern, a
function of where the camera looks): σ²(k) = σ_pose² + σ_frame²/k per axis.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calflow.identification.design import latin_hypercube, space_filling
from calflow.xytheta.design import criteria as design


@dataclass(frozen=True)
class NoiseModel:
    """σ per axis of a reading (µm): ``pose_um`` not reduced by averaging, ``frame_um`` per frame."""

    pose_um: float
    frame_um: float

    def sigma(self, frames: int = 1) -> float:
        return float(np.sqrt(self.pose_um**2 + self.frame_um**2 / frames))


@dataclass(frozen=True)
class TimeModel:
    """Virtual rig time of a plan (s): the simulated rig's move, settle and dwell, plus frames."""

    velocity_um_s: float = 1000.0
    velocity_deg_s: float = 10.0
    settle_s: float = 0.5
    dwell_s: float = 1.0
    frame_s: float = 0.04

    def moves_s(self, q: np.ndarray) -> np.ndarray:
        """Time of each move of the sequence ``q`` (n, 3) from the previous row (from home for row 0)."""
        d = np.abs(np.diff(np.vstack([np.zeros(3), np.asarray(q, dtype=float)]), axis=0))
        return (
            np.maximum(d[:, 0], d[:, 1]) / self.velocity_um_s + d[:, 2] / self.velocity_deg_s + self.settle_s
        )

    def plan_s(self, q: np.ndarray, frames: int = 1) -> float:
        """Total time of visiting ``q`` in order with ``frames`` frames per pose (s)."""
        return float(self.moves_s(q).sum() + len(q) * (self.dwell_s + (frames - 1) * self.frame_s))


def noise_model(campaign: dict) -> NoiseModel | None:
    """The campaign's noise model: ``identification.design.noise_um`` when given, else the
    simulated rig's declared options (stage repeatability, decoding error of amplitude a —
    variance a²/2 —, resolution r — r²/12 — per pose; sensor noise per frame). None when
    neither is known (a real rig without a declared noise model)."""
    given = (campaign["identification"].get("design") or {}).get("noise_um") or {}
    if given.get("pose") is not None and given.get("frame") is not None:
        return NoiseModel(float(given["pose"]), float(given["frame"]))
    if campaign["rig"]["factory"] != "simulated":
        return None
    from calflow.xytheta.stage.physics import truth_from_options

    t = truth_from_options(
        {k: v for k, v in (campaign["rig"].get("options") or {}).items() if k not in ("seed", "stream")}
    )
    pose = np.sqrt(t.stage_repeatability_um**2 + t.decode_error_um**2 / 2 + t.sensor_resolution_um**2 / 12)
    return NoiseModel(
        float(given.get("pose", pose) if given.get("pose") is not None else pose),
        float(given["frame"]) if given.get("frame") is not None else t.sensor_noise_um,
    )


def time_model(campaign: dict) -> TimeModel:
    """The rig's velocities and settling (the simulated rig's options or defaults) and the plan's dwell."""
    from calflow.xytheta.stage.physics import XYThetaTruth

    d = XYThetaTruth()
    o = campaign["rig"].get("options") or {} if campaign["rig"]["factory"] == "simulated" else {}
    p = campaign["identification"]
    return TimeModel(
        float(o.get("velocity_um_s", d.velocity_um_s)),
        float(o.get("velocity_deg_s", d.velocity_deg_s)),
        float(o.get("settle_s", d.settle_s)),
        float(p["dwell_s"]),
        float((p.get("design") or {}).get("frame_s", 0.04)),
    )


def frames_per_pose(noise: NoiseModel, time_per_pose_s: float, frame_s: float, frames_max: int = 10) -> int:
    """Frames per pose that maximise the information per second, 1/(σ²(k) t(k)), k ≤ ``frames_max``.

    t(k) = ``time_per_pose_s`` + (k − 1) ``frame_s``; averaging helps only while the
    per-frame noise dominates the per-pose errors.
    """
    k = np.arange(1, int(frames_max) + 1)
    rate = 1.0 / ((noise.pose_um**2 + noise.frame_um**2 / k) * (time_per_pose_s + (k - 1) * frame_s))
    return int(k[np.argmax(rate)])


def order(q: np.ndarray, tm: TimeModel, start=(0.0, 0.0, 0.0), passes: int = 3) -> np.ndarray:
    """Visiting order of the poses ``q`` (n, 3) from ``start``: nearest neighbour in move time,
    improved by 2-opt (segment reversals while the tour's time falls); returns indices."""
    q = np.asarray(q, dtype=float)
    n = len(q)
    pts = np.vstack([np.asarray(start, dtype=float), q])
    scale = np.array([1.0 / tm.velocity_um_s, 1.0 / tm.velocity_um_s, 1.0 / tm.velocity_deg_s])

    def cost(a, b):
        d = np.abs(pts[a] - pts[b]) * scale
        return np.maximum(d[..., 0], d[..., 1]) + d[..., 2]

    left = np.ones(n + 1, dtype=bool)
    left[0] = False
    tour = [0]
    for _ in range(n):
        rest = np.flatnonzero(left)
        nxt = rest[int(np.argmin(cost(tour[-1], rest)))]
        tour.append(nxt)
        left[nxt] = False
    tour = np.array(tour)
    for _ in range(passes):  # 2-opt on an open path starting at `start`
        improved = False
        for i in range(1, n):
            a, b = tour[i - 1], tour[i]
            c, d = tour[i:-1], tour[i + 1 :]
            gain = cost(a, b) + cost(c, d) - cost(a, c) - cost(b, d)
            tail = cost(a, b) - cost(a, tour[-1])  # reversing the whole tail
            j = int(np.argmax(gain)) if gain.size else -1
            if gain.size and gain[j] > 1e-9 and gain[j] >= tail:
                tour[i : i + j + 1] = tour[i : i + j + 1][::-1]
                improved = True
            elif tail > 1e-9:
                tour[i:] = tour[i:][::-1]
                improved = True
        if not improved:
            break
    return tour[1:] - 1


def approach(q: np.ndarray, overshoot_um: float) -> tuple[np.ndarray, np.ndarray]:
    """Commands that approach every pose of ``q`` in +X and +Y (one side of the backlash,
    Sec. 4.4.1): a pose reached by a negative move of X or Y is preceded by a row
    ``overshoot_um`` below it on both. Returns the commands and, per row, True for the poses
    (False for the approach rows, whose readings are other-side readings)."""
    rows, measured, last = [], [], np.zeros(3)
    for p in np.asarray(q, dtype=float):
        if p[0] < last[0] or p[1] < last[1]:
            rows.append(p - [overshoot_um, overshoot_um, 0.0])
            measured.append(False)
        rows.append(p)
        measured.append(True)
        last = p
    return np.array(rows), np.array(measured)


def candidates(n: int, x_range, y_range, theta_range, seed: int) -> np.ndarray:
    """A pool of ``n`` candidate joint poses (n + 8, 3) over the workspace: a Latin hypercube
    (each axis cut in n strata, one pose in each: an even cover of every joint's range) from
    its own random stream, plus the box's 8 corners."""
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 15]))
    lo = np.array([x_range[0], y_range[0], theta_range[0]], dtype=float)
    hi = np.array([x_range[1], y_range[1], theta_range[1]], dtype=float)
    corners = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], dtype=float)
    return np.vstack([lo + (hi - lo) * corners, latin_hypercube(rng, n, lo, hi)])


def design_poses(
    n: int, pool: np.ndarray, phi, free, criterion: str, scale, fraction_space_filling: float, lo, hi
) -> np.ndarray:
    """n distinct poses of ``pool``: ⌊f n⌋ space-filling ones, the rest optimal given them."""
    m = int(np.floor(fraction_space_filling * n))
    fixed_idx = space_filling(pool, m, lo, hi)
    keep = np.setdiff1d(np.arange(len(pool)), fixed_idx)
    J = design.pose_jacobians(pool, phi, free)
    fixed = J[fixed_idx] if m else None
    d = design.optimal_design(J[keep], n, criterion, fixed, scale)
    return np.vstack([pool[fixed_idx], pool[keep][d.index]])


def _phi(campaign: dict, model: str):
    from calflow.xytheta.models.kinematics import Parameters

    spec = campaign["models"][model]
    return Parameters(**{**campaign["identification"]["initial"], **spec.get("fixed", {})}), tuple(
        spec["free"]
    )


def bound(campaign: dict, q: np.ndarray, frames: int = 1) -> dict:
    """What a plan of joint poses ``q`` (n, 3, in visiting order, home first) promises before
    acquisition: the Cramér–Rao σ of every identified model's free parameters (µm, degree)
    under the campaign's noise model, at the nominal geometry (``identification.initial``),
    and the virtual rig time (h) of the time model. Models with a ``base`` share their base's
    parameters; the bound is None without a noise model (a real rig that declares none)."""
    noise = noise_model(campaign)
    tm = time_model(campaign)
    out = {
        "poses": int(len(q)),
        "frames_per_pose": int(frames),
        "rig_time_h": tm.plan_s(q, frames) / 3600.0,
        "noise_um": None if noise is None else {"pose": noise.pose_um, "frame": noise.frame_um},
        "crlb_sigma": None,
    }
    if noise is not None:
        out["crlb_sigma"] = {}
        for name, spec in campaign["models"].items():
            if "free" not in spec:
                continue
            phi, free = _phi(campaign, name)
            s = design.crlb_sigma(design.pose_jacobians(q, phi, free), noise.sigma(frames))
            out["crlb_sigma"][name] = {design.parameter_key(k): float(v) for k, v in zip(free, s)}
    return out


def _random_poses(campaign: dict, n: int) -> np.ndarray:
    from calflow.xytheta.plans import poses as plans

    p = campaign["identification"]
    c = plans.identification(int(n), p["x_um"], p["y_um"], p["theta_deg"], seed=campaign["seed"]).commands
    return np.column_stack([c["x"], c["y"], c["theta"]])


def designed_poses(campaign: dict) -> tuple[np.ndarray, int, dict]:
    """The designed identification poses of a campaign (n, 3, home first, in visiting
    order), the frames per pose, and a record of the design (criterion, the random plan it
    was sized against, its poses).

    ``identification.design.poses`` poses, or (null) the fewest whose worst-parameter
    Cramér–Rao σ of ``design.model`` is no larger than that of ``identification.poses``
    random poses: a first design at a third of them sizes the next by σ ∝ 1/√n until one
    reaches the bound, then bisection to within 1 % of the fewest that do; with
    ``design.time_budget`` the most poses whose plan fits that fraction of the random plan's
    rig time (:func:`_fill_budget`). Criterion ``discrepancy``: the MV design of that count,
    exchanged for the least expected prediction error (:func:`_polish`).
    """
    p = campaign["identification"]
    d = p["design"]
    noise = noise_model(campaign)
    if noise is None:
        raise ValueError(
            "identification.design.noise_um: the rig declares no noise model; expected pose and frame (µm)"
        )
    if d["criterion"] == "discrepancy":
        from calflow.xytheta.design.discrepancy import kernel

        kernel(campaign)  # refused before any design when it is not given
    tm = time_model(campaign)
    phi, free = _phi(campaign, d["model"])
    lo = np.array([p["x_um"][0], p["y_um"][0], p["theta_deg"][0]], dtype=float)
    hi = np.array([p["x_um"][1], p["y_um"][1], p["theta_deg"][1]], dtype=float)
    pool = candidates(int(d["candidates"]), p["x_um"], p["y_um"], p["theta_deg"], campaign["seed"])
    rq = _random_poses(campaign, p["poses"])
    ref_time = tm.moves_s(rq).mean() + tm.dwell_s
    ref = design.crlb_sigma(design.pose_jacobians(rq, phi, free), noise.sigma(1))
    base = "MV" if d["criterion"] == "discrepancy" else d["criterion"]  # discrepancy: the MV design, polished

    def make(n):
        poses = design_poses(n - 1, pool, phi, free, base, ref, d["space_filling"], lo, hi)
        return _visit(campaign, poses, ref, noise, tm)

    def finish(
        q, frames, ratio
    ):  # the design as the plan takes it: polished for the least bias under discrepancy
        return (
            _polish(campaign, q, ratio, pool, ref, noise, tm, lo, hi)
            if base != d["criterion"]
            else (q, frames, ratio, {})
        )

    def final(n):
        return finish(*make(n))

    if d.get("poses"):
        q, frames, ratio, record = final(int(d["poses"]))
    else:
        n, cap = max(len(free) + 2, (len(rq) + 2) // 3), len(pool) + 1
        miss, reach = 0, None  # the most poses known to miss the bound, the fewest known to reach it
        for _ in range(40):
            q, frames, ratio = make(min(n, cap))
            if ratio <= 1.0 or n >= cap:
                reach, best = n, (q, frames, ratio)
            else:
                miss = n
            if reach is not None and reach - miss <= max(1, reach // 100):  # within 1 % of the fewest
                break
            n = (miss + reach) // 2 if reach is not None else max(miss + 1, int(np.ceil(n * ratio**2)))
        q, frames, ratio = best
        filled = None
        if d.get("time_budget") is not None:
            filled = _fill_budget(final, best, float(d["time_budget"]) * tm.plan_s(rq), tm, cap)
        q, frames, ratio, record = filled if filled is not None else finish(q, frames, ratio)
    record = {
        **record,
        "criterion": d["criterion"],
        "model": d["model"],
        "candidates": int(len(pool)),
        "time_budget": d.get("time_budget"),
        "random_rig_time_h": tm.plan_s(rq) / 3600.0,
        "space_filling": float(d["space_filling"]),
        "sized_against_random_poses": int(len(rq)),
        "sigma_ratio_max_vs_random": ratio,
        "random_time_per_pose_s": float(ref_time),
    }
    return q, frames, record


def _fill_budget(final, reach, budget_s: float, tm: TimeModel, cap: int):
    """The final design (``final(n)`` → (q, frames, ratio, record)) of the most rows whose rig
    time is within ``budget_s`` (s), at least the rows of ``reach`` = (q, frames, ratio), the
    fewest reaching the bound; None when none fits (``reach`` already overruns). The count is
    scaled by budget / time per pose, and cut by the excess when a design overruns (a tour's
    time does not follow the count exactly); at most ``cap`` rows (every candidate and home)."""
    if tm.plan_s(reach[0], reach[1]) > budget_s:
        return None
    per = tm.plan_s(reach[0], reach[1]) / len(reach[0])
    n, best = min(int(np.floor(budget_s / per)), cap), None
    for _ in range(6):
        if n < len(reach[0]) or (best is not None and n <= len(best[0])):
            break
        trial = final(n)
        t = tm.plan_s(trial[0], trial[1])
        per = t / len(trial[0])
        if t <= budget_s:
            best, n = trial, min(int(np.floor(budget_s / per)), cap)
        else:
            n -= int(np.ceil((t - budget_s) / per)) + 1
    return best


def _polish(campaign: dict, q, ratio, pool, ref, noise, tm, lo, hi):
    """The MV design ``q`` (home first) exchanged for the least expected prediction error under the
    campaign's discrepancy (:mod:`calflow.xytheta.design.discrepancy`), σ ≤ max(1, ratio)·ref."""
    from calflow.xytheta.design import discrepancy as dd

    d = campaign["identification"]["design"]
    phi, free = _phi(campaign, d["model"])
    kern = dd.kernel(campaign)
    rows = np.flatnonzero((pool[:, None, :] == q[None, 1:, :]).all(axis=2).any(axis=1))
    idx = dd.polish(
        pool, rows, phi, free, kern, noise.sigma(1), ref * max(1.0, ratio), lo, hi, campaign["seed"]
    )
    before = dd.expected_error(q, phi, free, kern, noise.sigma(1), lo, hi, campaign["seed"])
    q, frames, ratio = _visit(campaign, pool[idx], ref, noise, tm)
    after = dd.expected_error(q, phi, free, kern, noise.sigma(1), lo, hi, campaign["seed"])
    record = {
        "discrepancy": {
            "amplitude_um": list(kern.amplitude),
            "length": list(kern.length),
            "from": d["discrepancy"].get("from", "config"),
            "bias_um2_before": before["bias"],
            "bias_um2": after["bias"],
            "variance_um2": after["variance"],
            "swapped_poses": int(len(np.setdiff1d(idx, rows))),
        }
    }
    return q, frames, ratio, record


def _visit(campaign: dict, poses, ref, noise: NoiseModel, tm: TimeModel):
    """Poses as the plan visits them — home first, then :func:`order` — with the frames per pose
    that maximise information per second and the worst ratio of Cramér–Rao σ to ``ref``."""
    d = campaign["identification"]["design"]
    phi, free = _phi(campaign, d["model"])
    q = np.vstack([np.zeros((1, 3)), poses[order(poses, tm)]])
    frames = frames_per_pose(noise, float(tm.moves_s(q).mean() + tm.dwell_s), tm.frame_s, d["frames_max"])
    s = design.crlb_sigma(design.pose_jacobians(q, phi, free), noise.sigma(frames))
    return q, frames, float(np.max(s / ref))


def identification_plan(campaign: dict):
    """The ``optimal`` identification plan (a :class:`calflow.plan.Plan`) and its design record
    with the bound of :func:`bound` — written into the run's attributes before acquisition."""
    from calflow.plan import Plan

    p = campaign["identification"]
    q, frames, record = designed_poses(campaign)
    rows, measured = (
        approach(q, p["design"]["approach_um"])
        if p["design"]["approach_um"] > 0
        else (q, np.ones(len(q), bool))
    )
    n = len(rows)
    plan = Plan(
        name="identification",
        commands={"x": rows[:, 0], "y": rows[:, 1], "theta": rows[:, 2]},
        pose=np.arange(n),
        cycle=np.zeros(n, dtype=int),
        direction=np.where(measured, 0, -1).astype(int),
        dwell_s=p["dwell_s"] + (frames - 1) * time_model(campaign).frame_s,
        average_last_s=None if frames == 1 else frames * time_model(campaign).frame_s,
    )
    return plan, {**record, **bound(campaign, rows, frames)}
