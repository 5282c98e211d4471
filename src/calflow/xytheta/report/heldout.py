"""What a held-out validation of the XYΘ models can and cannot tell (Sec. 4.5.5, ISO 9283).

The rig's repeatability floor pooled over the held-out targets, the adequacy test of a
model's fit against it, and whether the held-out targets are disjoint from every pose the
identification and the tables saw.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from calflow.data.io import jsonable


def repeatability_floor(metrics: list[xr.Dataset]) -> dict:
    """The sensor-and-stage floor (µm per reading and axis): the pooled within-target scatter
    of every validation run, with its degrees of freedom."""
    pairs = [(m.attrs.get("within_target_std_um"), m.attrs.get("within_target_dof", 0)) for m in metrics]
    pairs = [(float(s), int(d)) for s, d in pairs if s is not None and np.isfinite(s) and d > 0]
    dof = sum(d for _, d in pairs)
    if not dof:
        return {"floor_um": None, "dof": 0}
    return {"floor_um": float(np.sqrt(sum(s**2 * d for s, d in pairs) / dof)), "dof": int(dof)}


def adequacy(sigma_fit, n_poses, n_free: int, floor: dict, alpha: float = 0.01) -> dict:
    """Lack-of-fit test of a model: its residual σ̂ against the repeatability floor.

    χ²/dof = σ̂²_fit / σ²_floor is 1 when the model leaves only noise; the F-test with
    (2(n−1) − p, floor dof) degrees of freedom rejects adequacy when p < ``alpha``. An
    inadequate model's parameters absorb unmodelled errors, and their σ (which assume the
    residuals are noise) understate their error.
    """
    if sigma_fit is None or not floor.get("floor_um") or not n_poses:
        return {
            "chi2_dof": None,
            "p_value": None,
            "adequate": None,
            "statement": "No repeatability floor was measured: calflow cannot tell whether the model fits.",
        }
    from scipy.special import fdtrc  # scipy.stats.f.sf's function, without importing scipy.stats

    ratio = float(sigma_fit) ** 2 / floor["floor_um"] ** 2
    df1 = max(1, 2 * (int(n_poses) - 1) - n_free)
    p = float(fdtrc(df1, floor["dof"], ratio))
    ok = p >= alpha
    statement = (
        "The residuals are at the repeatability floor: the model fits, and its parameter σ can be trusted."
        if ok
        else f"The model does not fit: its residuals are {np.sqrt(ratio):.1f} times the repeatability floor "
        f"({float(sigma_fit):.2f} against {floor['floor_um']:.2f} µm). Its parameters absorb errors it does "
        f"not model, and their σ understate their real error."
    )
    return {
        "chi2_dof": jsonable(ratio),
        "p_value": jsonable(p),
        "adequate": bool(ok),
        "sigma_fit_um": jsonable(float(sigma_fit)),
        "floor_um": jsonable(floor["floor_um"]),
        "floor_dof": floor["dof"],
        "fit_dof": df1,
        "alpha": alpha,
        "statement": statement,
    }


def disjointness(
    heldout_runs: list[xr.Dataset],
    training_runs: list[xr.Dataset],
    tol_um: float = 1.0,
    tol_deg: float = 1e-3,
) -> dict:
    """Do held-out commands repeat any identification or table pose? From the run datasets.

    A held-out sample coincides with a training sample when their X and Y commands are
    within ``tol_um`` and their Θ commands within ``tol_deg``.
    """

    def joints(ds):
        sel = ds["pose"].values > 0
        return np.column_stack([ds[f"cmd_{j}"].values[sel] for j in ("x", "y", "theta")]).astype(float)

    if not heldout_runs or not training_runs:
        return {"coincident_samples": None}
    train = np.vstack([joints(r) for r in training_runs])
    order = np.argsort(train[:, 2])
    train = train[order]
    coincident = 0
    for run in heldout_runs:
        for q in joints(run):
            lo, hi = np.searchsorted(train[:, 2], [q[2] - tol_deg, q[2] + tol_deg])
            if hi > lo:
                d = np.hypot(train[lo:hi, 0] - q[0], train[lo:hi, 1] - q[1])
                coincident += int(np.any(d <= tol_um))
    return {
        "coincident_samples": coincident,
        "tolerance": {"xy_um": tol_um, "theta_deg": tol_deg},
        "checked_samples": int(sum((r["pose"].values > 0).sum() for r in heldout_runs)),
        "training_samples": int(len(train)),
    }
