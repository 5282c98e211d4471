"""The run of an interim check: few targets commanded through the reference's exported bundle.

An interim check verifies the stage *through the compensation it runs*: the bundle of the
reference calibration's model (``results/<reference>/export/<model>/``, read by
:class:`calflow.xytheta.export.compensator.Compensator`) commands the targets in closed
loop, exactly as the export's closed-loop check does (:func:`calflow.xytheta.export.
verification.export_plan`, bundle path only): the home pose first (it defines the world
frame, Eq. 4.27), then ``cycles`` visits of each target.

Targets sensitive to what drifts. With the commands fixed by the old parameters, a change
δφ of the stage moves the reached tool point by J(q)·δφ, J the forward Jacobian of
Eq. (4.18) at the commanded joints q (:func:`~calflow.xytheta.models.kinematics.
forward_jacobian`); at home J = 0, so the world frame does not absorb it. The check watches
α and x_R — what a re-mount or a crash moves (α turns the whole workspace, x_R shows at
Θ ≠ 0) — scaled by the change it must see (``drift``: 0.01° and 20 µm by default). From a
grid of joint poses over the reference's identification workspace, targets are added
greedily to maximise the smallest eigenvalue of Σ (J_i D)ᵀ(J_i D), D = diag(drift): an
E-optimal choice, so that no combination of the two drifts stays hidden (Pukelsheim,
*Optimal Design of Experiments*, 1993, Sec. 6.4). Each target is the tool point the
reference model predicts at its grid pose (Eq. 4.18 without the tables).

Acquired sequentially (:func:`sequential`): at the end of each cycle from the second on,
Wald's test on the visits so far (:func:`calflow.xytheta.report.interim.check_test`, H0 the
reference's own closed-loop check ``results/<reference>/runs/export_<model>.nc``) decides,
and the rig stops at the first decision — a clear check costs two cycles, not all of them.
"""

from __future__ import annotations

import dataclasses
import json
import os

import numpy as np

from calflow.configuration import layout
from calflow.errors import CalflowError
from calflow.plan import Acquisition

DRIFT = {"x_R": 20.0, "alpha": 0.01}  # µm, degree: the re-mount the check is designed to see
WATCHED = ("x_R", "alpha")
INDEX = {"x_R": 0, "y_R": 1, "alpha": 2, "beta": 3}  # columns of forward_jacobian
GRID = (9, 7, 5)  # joint grid X × Y × Θ of the candidates
MARGIN = 0.05  # fraction of each range kept clear of the workspace's edges (table corrections)


def candidates(x_um, y_um, theta_deg, grid=GRID, margin: float = MARGIN) -> np.ndarray:
    """Joint poses (N, 3): X, Y (µm), Θ (degree) on a grid inside the workspace ranges."""
    axes = []
    for (lo, hi), n in zip((x_um, y_um, theta_deg), grid):
        pad = margin * (hi - lo)
        axes.append(np.linspace(lo + pad, hi - pad, n))
    X, Y, T = np.meshgrid(*axes, indexing="ij")
    return np.column_stack([X.ravel(), Y.ravel(), T.ravel()])


def scaled_jacobian(q: np.ndarray, params, drift: dict[str, float] = DRIFT) -> np.ndarray:
    """(N, 2, k): ∂(x_P, y_P)/∂φ_w · drift_w at joint poses q, for the watched parameters (µm)."""
    from calflow.xytheta.models.kinematics import forward_jacobian

    jx, jy = forward_jacobian(q[:, 0], q[:, 1], q[:, 2], params)
    cols = [INDEX[p] for p in drift]
    scale = np.array([drift[p] for p in drift], float)
    return np.stack([jx[:, cols] * scale, jy[:, cols] * scale], axis=1)


def sensitive_poses(q: np.ndarray, params, count: int, drift: dict[str, float] = DRIFT) -> np.ndarray:
    """Indices of ``count`` poses of q chosen greedily for the largest smallest eigenvalue of
    the summed information Σ (J_i D)ᵀ(J_i D) (ties: the larger trace)."""
    if count > len(q):
        raise ValueError(f"interim check: {count} targets asked, {len(q)} candidate poses")
    G = scaled_jacobian(q, params, drift)
    info = np.einsum("nij,nik->njk", G, G)  # per-candidate (k, k) information, µm²
    k = info.shape[-1]
    total, chosen = np.zeros((k, k)), []
    for _ in range(count):
        trial = total + info
        score = np.linalg.eigvalsh(trial)[:, 0] + 1e-9 * np.trace(trial, axis1=1, axis2=2)
        score[chosen] = -np.inf
        best = int(np.argmax(score))
        chosen.append(best)
        total = trial[best]
    return np.array(chosen, dtype=int)


def sensitive_targets(params, count: int, x_um, y_um, theta_deg, drift=DRIFT) -> tuple[np.ndarray, dict]:
    """Targets (count, 3): x_T, y_T (µm, world frame), Θ_T (degree), and a record of the choice:
    the smallest and largest error (µm) the drift gives over them (singular values of the
    stacked scaled Jacobian / √targets: the rms error per visit along the least and most
    visible drift directions)."""
    from calflow.xytheta.models.kinematics import forward

    q = candidates(x_um, y_um, theta_deg)
    idx = sensitive_poses(q, params, count, drift)
    xs, ys = forward(q[idx, 0], q[idx, 1], q[idx, 2], params)
    G = scaled_jacobian(q[idx], params, drift).reshape(-1, len(drift))
    sv = np.linalg.svd(G, compute_uv=False) / np.sqrt(count)
    record = {
        "method": "greedy E-optimal over a joint grid of the reference's workspace",
        "drift": dict(drift),
        "rms_error_um": {"least_visible": float(sv[-1]), "most_visible": float(sv[0])},
        "joints": q[idx].tolist(),
    }
    return np.column_stack([xs, ys, q[idx, 2]]), record


def sequential(test, plan_cycle: np.ndarray):
    """A runner (:class:`calflow.plan.Acquisition`) that stops the check at ``test``'s first
    decision, looked at after each complete cycle (``plan_cycle``: the plan's cycle per row)."""
    from calflow.acquisition.runner import acquire
    from calflow.xytheta.report.interim import MIN_CYCLES, visit_errors, visit_groups

    def stop(readings, partial) -> bool:
        n = len(readings)
        if n >= len(plan_cycle) or plan_cycle[n] == plan_cycle[n - 1]:
            return False  # not at the end of a cycle
        if plan_cycle[n - 1] - plan_cycle.min() + 1 < MIN_CYCLES:
            return False  # before the first look
        run = partial()
        return test.decide(visit_errors(run), visit_groups(run))["decision"] != "undecided"

    def run(plan, rig, meta, journal=None, progress=None, controller=None):
        return acquire(plan, rig, meta, journal, progress, controller, stop=stop)

    return run


def interim_check(c: dict, args) -> Acquisition:
    """``calflow acquire --plan interim_check --export DIR``: the check's targets through the
    bundle of DIR (the reference's export of ``interim_check.model``)."""
    from calflow.data.io import open_dataset
    from calflow.xytheta.export.compensator import Compensator
    from calflow.xytheta.export.verification import export_plan
    from calflow.xytheta.models.kinematics import Parameters
    from calflow.xytheta.report.interim import check_test, reference_rms_um

    if not getattr(args, "export", None):
        raise CalflowError(
            "calflow acquire --plan interim_check: --export DIR (the reference model's export) is required"
        )
    check = c["interim_check"]
    params = Parameters(**Compensator.load(args.export).parameters)
    ws = check["resolved"]["workspace"]  # the reference's identification workspace
    targets, record = sensitive_targets(
        params, check["targets"], ws["x_um"], ws["y_um"], ws["theta_deg"], check["drift"]
    )
    plan, _ = export_plan(args.export, targets, check["cycles"], check["dwell_s"], paths=("bundle",))
    reference = layout.run(check["reference"], f"export_{check['model']}")
    if not os.path.exists(reference):
        raise CalflowError(
            f"calflow acquire --plan interim_check: {reference}: the reference's closed-loop check "
            "(the sequential test's H0) is missing; run the reference campaign first"
        )
    r0 = reference_rms_um(open_dataset(reference, kind="run"))
    return Acquisition(
        dataclasses.replace(plan, name="interim_check"),
        "interim_check",
        check["model"],
        runner=sequential(check_test(c, r0), plan.cycle),
        attrs={
            "interim_reference": check["reference"],
            "export_paths": "bundle",
            "export_cycles": int(check["cycles"]),
            "target_choice": json.dumps(record),
        },
    )
