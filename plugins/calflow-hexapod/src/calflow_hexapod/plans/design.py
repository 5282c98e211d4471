"""The designed identification plan of the hexapod campaign and the bound written before it.

The information of a pose comes from the loop-closure residuals of the models
(:func:`calflow_hexapod.models.loop.closure`: six leg equations per pose, ∂r/∂φ). The core's design
(:mod:`calflow.identification.design`) treats an unknown constant offset per reading axis as
a nuisance; for the six leg equations that offset *is* the leg offset δl_i, so the design and
its Cramér–Rao bound cover a model's identifiable parameters other than the leg offsets, with
the offsets estimated alongside. The noise of a leg equation is the instrument's, carried by
∂r/∂M (Wampler, Hollerbach & Arai 1995), plus the legs' repeatability, averaged over the
candidate pool into one σ per equation — an approximation: the six equations of a pose are
in truth correlated; the identification's own σ (written after the fit) are the exact ones.

Config (``identification``): ``plan: random | optimal``, ``poses``, ``fraction`` of the travel,
``dwell_s``, ``initial: {frame, tool}`` (the lab's rough knowledge of the instrument's frame
and the probe on the platform, µm and degree), ``design: {criterion, model, candidates,
space_filling, poses, noise: {position_um, angle_deg, leg_um}}``.
"""

from __future__ import annotations

import numpy as np

from calflow.identification import design
from calflow_hexapod.models.geometry import h811
from calflow_hexapod.models.identification import identifiable
from calflow_hexapod.models.kinematics import inverse
from calflow_hexapod.models.ladder import LADDER, NAMES, OFFSET, Parameters
from calflow_hexapod.models.loop import closure
from calflow_hexapod.plans.noise import noise_model
from calflow_hexapod.plans.poses import target_of, workspace_poses


def nominal_parameters(campaign: dict) -> Parameters:
    """The campaign's nominal model: the H-811-class geometry with ``identification.initial``'s frames."""
    init = campaign["identification"].get("initial") or {}
    return Parameters.nominal(frame=init.get("frame"), tool=init.get("tool"))


def jacobians(q: np.ndarray, phi: Parameters, free, noise: dict) -> np.ndarray:
    """Whitened ∂r/∂φ_free (n, 6, p) of command poses ``q`` (n, 6) at parameters ``phi``: per
    equation over the pool's mean σ (module docstring), so the information is for σ = 1."""
    ctl = h811()
    lam = inverse(ctl, q)
    _, J, A = closure(phi, target_of(q, phi, ctl), lam, ctl.zero_lengths)
    s = np.array([noise["position_um"]] * 3 + [noise["angle_deg"]] * 3) ** 2
    C = np.einsum("nij,j,nkj->nik", A, s, A) + noise["leg_um"] ** 2 * np.eye(6)
    sigma = float(np.sqrt(np.mean(np.trace(C, axis1=1, axis2=2) / 6)))
    return J[..., [NAMES.index(f) for f in free]] / sigma


def model_free(campaign: dict, model: str) -> tuple[str, ...]:
    """The free parameters of a campaign's model: its ``free`` list, else its rung of :data:`LADDER`
    (``models.<name>.rung``, the name when absent)."""
    spec = (campaign.get("models") or {}).get(model) or {}
    free = spec.get("free") or LADDER.get(spec.get("rung", model))
    if free is None:
        raise ValueError(
            f"models.{model}: expected a 'free' list or a model of the ladder ({', '.join(LADDER)})"
        )
    return tuple(free)


def design_free(phi: Parameters, free, pool: np.ndarray, noise: dict) -> tuple[str, ...]:
    """The parameters of ``free`` the design bounds: those identifiable on the pool (the
    identification's QR analysis), less the leg offsets (the nuisance)."""
    J = jacobians(pool, phi, NAMES, noise)
    kept, _, _ = identifiable(J.reshape(-1, len(NAMES)), tuple(free))
    return tuple(f for f in kept if f not in OFFSET)


def move_times(q: np.ndarray, velocity_um_s: float, velocity_deg_s: float, settle_s: float) -> np.ndarray:
    """Time (s) of each move of the sequence ``q`` (n, 6) from the previous row (row 0 from home)."""
    d = np.abs(np.diff(np.vstack([np.zeros(6), q]), axis=0))
    return np.maximum(d[:, :3].max(1) / velocity_um_s, d[:, 3:].max(1) / velocity_deg_s) + settle_s


def _timing(campaign: dict) -> tuple[float, float, float]:
    from calflow_hexapod.stage.physics import HexapodTruth
    from calflow_hexapod.stage.run_options import simulated_physics

    d = HexapodTruth()
    o = simulated_physics(campaign) or {}
    return (
        float(o.get("velocity_um_s", d.velocity_um_s)),
        float(o.get("velocity_deg_s", d.velocity_deg_s)),
        float(o.get("settle_s", d.settle_s)),
    )


def order(q: np.ndarray, timing) -> np.ndarray:
    """Visiting order of ``q`` (n, 6) from home: nearest neighbour in move time."""
    left, here, out = list(range(len(q))), np.zeros(6), []
    while left:
        d = np.abs(q[left] - here)
        k = left.pop(int(np.argmin(np.maximum(d[:, :3].max(1) / timing[0], d[:, 3:].max(1) / timing[1]))))
        out.append(k)
        here = q[k]
    return np.array(out, dtype=int)


def bound(campaign: dict, q: np.ndarray) -> dict:
    """What a plan of command poses ``q`` (n, 6, home first, in visiting order) promises before
    acquisition: the Cramér–Rao σ of each ladder model's bounded parameters (µm, degree, 1) at the
    nominal model under the noise model, and the virtual rig time (h)."""
    noise = noise_model(campaign)
    p = campaign["identification"]
    timing = _timing(campaign)
    out = {
        "poses": int(len(q)),
        "rig_time_h": float((move_times(q, *timing).sum() + len(q) * p["dwell_s"]) / 3600),
        "noise": noise,
        "crlb_sigma": None,
    }
    if noise is None:
        return out
    phi = nominal_parameters(campaign)
    out["crlb_sigma"] = {}
    for name in campaign.get("models") or LADDER:
        free = design_free(phi, model_free(campaign, name), q, noise)
        s = design.crlb_sigma(jacobians(q, phi, free, noise))
        out["crlb_sigma"][name] = {f: float(v) for f, v in zip(free, s)}
    return out


def designed_poses(campaign: dict) -> tuple[np.ndarray, dict]:
    """The designed identification poses (n, 6, home first, in visiting order) and a record of
    the design: ``design.poses`` (default ``identification.poses``) poses of a pool of
    ``design.candidates`` reachable poses, ⌊``space_filling`` n⌋ of them spread over the
    workspace (greedy maximin), the rest optimal for ``design.criterion`` on ``design.model``'s
    parameters (:func:`calflow.identification.design.optimal_design`), scaled by the bound of
    the random plan of the same size."""
    p = campaign["identification"]
    d = p.get("design") or {}
    noise = noise_model(campaign)
    if noise is None:
        raise ValueError(
            "identification.design.noise: the rig declares no noise model; "
            "expected position_um, angle_deg and leg_um"
        )
    n = int(d.get("poses") or p["poses"])
    rng = np.random.default_rng(np.random.SeedSequence([int(campaign["seed"]), 15]))
    pool = workspace_poses(int(d.get("candidates", 2000)), float(p["fraction"]), rng)
    phi = nominal_parameters(campaign)
    free = design_free(phi, model_free(campaign, d.get("model", "geometric")), pool, noise)
    J = jacobians(pool, phi, free, noise)
    from calflow_hexapod.plans.poses import identification as random_plan

    rq = np.column_stack([random_plan(n, p["fraction"], campaign["seed"]).commands[a] for a in "xyzuvw"])
    ref = design.crlb_sigma(jacobians(rq, phi, free, noise))
    half = float(p["fraction"]) * np.abs(pool).max(0)
    m = int(np.floor(float(d.get("space_filling", 0.2)) * n))
    fixed = design.space_filling(pool, m, -half, half)
    keep = np.setdiff1d(np.arange(len(pool)), fixed)
    result = design.optimal_design(J[keep], n, d.get("criterion", "D"), J[fixed] if m else None, ref)
    poses = np.vstack([pool[fixed], pool[keep][result.index]])
    q = np.vstack([np.zeros(6), poses[order(poses, _timing(campaign))]])
    s = design.crlb_sigma(jacobians(q, phi, free, noise))
    record = {
        "criterion": d.get("criterion", "D"),
        "model": d.get("model", "geometric"),
        "candidates": int(len(pool)),
        "space_filling": m,
        "bounded_parameters": list(free),
        "sigma_ratio_max_vs_random": float(np.max(s / ref)),
    }
    return q, record
