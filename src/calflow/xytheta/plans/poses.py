"""Plans of the XYΘ campaign (thesis Sec. 4.5.5, Fig. 4.22, Table 4.7)."""

from __future__ import annotations

import numpy as np

from calflow.plan import Plan

# Table 4.7: validation targets in the world frame (x_T, y_T in µm, Θ_T in degrees).
TABLE_4_7 = np.array(
    [
        [-1200, -200, 1],
        [-1600, -200, 2],
        [-2000, -200, 3],
        [-2000, -300, 4],
        [-1600, -300, 5],
        [-1200, -300, 4],
        [-1200, -400, 3],
        [-1600, -400, 2],
        [-2000, -400, 1],
    ],
    dtype=float,
)


def identification(
    n_poses: int = 1200,
    x_range=(0.0, 4000.0),
    y_range=(0.0, 2000.0),
    theta_range=(0.0, 5.0),
    seed: int = 0,
    dwell_s: float = 1.0,
) -> Plan:
    """Random joint poses over the given ranges (µm, µm, degree), Sec. 4.5.5.

    Row 0 is the home pose (0, 0, 0), whose reading defines the world frame (Eq. 4.27);
    rows 1..n_poses are uniform random poses. The thesis takes 1200 poses (Fig. 4.21).
    """
    if n_poses < 2:
        raise ValueError(f"identification.poses: expected at least 2, got {n_poses}")
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 4_5_5]))
    lo = np.array([x_range[0], y_range[0], theta_range[0]], dtype=float)
    hi = np.array([x_range[1], y_range[1], theta_range[1]], dtype=float)
    q = np.vstack([np.zeros(3), lo + (hi - lo) * rng.random((n_poses, 3))])
    n = len(q)
    return Plan(
        name="identification",
        commands={"x": q[:, 0], "y": q[:, 1], "theta": q[:, 2]},
        pose=np.arange(n),
        cycle=np.zeros(n, dtype=int),
        direction=np.zeros(n, dtype=int),
        dwell_s=dwell_s,
    )


def validation_targets(targets=None) -> np.ndarray:
    """Validation targets (M, 3): x_T, y_T (µm), Θ_T (degree); Table 4.7 by default."""
    t = TABLE_4_7 if targets is None else np.asarray(targets, dtype=float)
    if t.ndim != 2 or t.shape[1] != 3:
        raise ValueError(f"validation.targets: expected rows of [x_um, y_um, theta_deg], got shape {t.shape}")
    return t


def heldout_targets(n_targets: int, x_range, y_range, theta_range, nominal, seed: int) -> np.ndarray:
    """Held-out validation targets (n, 3): x_T, y_T (µm, world frame), Θ_T (degree).

    Joint poses are drawn uniformly over the identification workspace (``x_range``,
    ``y_range`` in µm less 5 % at each edge, ``theta_range`` in degree, Θ continuous) from their own random
    stream, then put in the world frame by Eq. (4.18) with the ``nominal`` parameters
    (the campaign's ``identification.initial``, not an identified model), so every model
    is validated on the same targets. A continuous draw never repeats an identification
    pose or a table angle; the summary checks it from the run datasets.
    """
    from calflow.xytheta.models.kinematics import forward

    if n_targets < 1:
        raise ValueError(f"validation.heldout.targets: expected at least 1, got {n_targets}")
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 9_283]))
    lo = np.array([x_range[0], y_range[0], theta_range[0]], dtype=float)
    hi = np.array([x_range[1], y_range[1], theta_range[1]], dtype=float)
    margin = 0.05 * (hi - lo) * np.array([1.0, 1.0, 0.0])  # X, Y only: the identified geometry
    lo, hi = lo + margin, hi - margin  # differs from the nominal one by its errors (≈ 0.1 mm here)
    q = lo + (hi - lo) * rng.random((int(n_targets), 3))
    x_T, y_T = forward(q[:, 0], q[:, 1], q[:, 2], nominal)
    return np.column_stack([x_T, y_T, q[:, 2]])


def validation(inverse, targets=None, cycles: int = 30, dwell_s: float = 1.0) -> Plan:
    """ISO 9283 validation: home, then ``cycles`` visits of P1..PM in sequence (Fig. 4.23).

    ``inverse(x_T, y_T, theta_T) -> (X, Y)`` is the model's inverse kinematics
    (Eq. 4.19); the rotation joint is commanded to Θ_T.
    """
    t = validation_targets(targets)
    m = len(t)
    if cycles < 2:
        raise ValueError(f"validation.cycles: expected at least 2, got {cycles}")
    tt = np.tile(t, (cycles, 1))
    X, Y = inverse(tt[:, 0], tt[:, 1], tt[:, 2])
    nan = np.array([np.nan])
    return Plan(
        name="validation",
        commands={
            "x": np.concatenate([[0.0], X]),
            "y": np.concatenate([[0.0], Y]),
            "theta": np.concatenate([[0.0], tt[:, 2]]),
        },
        targets={
            "x": np.concatenate([nan, tt[:, 0]]),
            "y": np.concatenate([nan, tt[:, 1]]),
            "theta": np.concatenate([nan, tt[:, 2]]),
        },
        pose=np.concatenate([[0], np.tile(np.arange(1, m + 1), cycles)]),
        cycle=np.concatenate([[0], np.repeat(np.arange(cycles), m)]),
        direction=np.zeros(1 + m * cycles, dtype=int),
        dwell_s=dwell_s,
    )
