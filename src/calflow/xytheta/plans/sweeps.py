"""Plans of the XY-stage error study and of the angle-residual run (thesis Sec. 4.4, 4.5.5).

* :func:`characterisation` — one stage swept forward and backward in steps, the other
  joints held at 0 (Sec. 4.4.1, Fig. 4.6–4.9).
* :func:`square` — the 4 × 4 mm square AB BC CD DA of Fig. 4.12 (Sec. 4.4.2).
* :func:`random_points` — the ten random targets of Table 4.3 (Fig. 4.15).
* :func:`angle_sweep` — the angle characterisation of Sec. 4.5.5 as calflow runs it by
  default: at a few positions that are no validation target, Θ swept forward and
  backward in fine steps through a base model's inverse, to tabulate f_ax(Θ), f_ay(Θ).
* :func:`angle_residuals` / :func:`angle_residual_plan` — the thesis's own run (Fig. 4.26):
  the Table 4.7 positions visited at 5 angles, for the opt-in position-angle table.

Targets of :func:`square` and :func:`random_points` are *stage-frame* coordinates in µm:
x_T ≈ X, y_T ≈ Y, compared with the displacement of the vision reading from the home
reading (``calflow.xytheta.tables.characterisation.stage_positions``). Every plan starts with the home
row (0, 0, 0), pose 0, whose reading is the reference.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from calflow.plan import Plan
from calflow.xytheta.plans.poses import TABLE_4_7, validation

# Table 4.3: random targets P1..P10 (x_T, y_T in µm).
TABLE_4_3 = np.array(
    [
        [3471, 2311],
        [6044, 3991],
        [3673, 39],
        [5118, 2738],
        [3643, 2071],
        [8196, 186],
        [1702, 756],
        [3776, 3815],
        [3903, 1390],
        [1035, 35],
    ],
    dtype=float,
)
STROKE_UM = {"x": 9500.0, "y": 4200.0}  # Sec. 4.4.1: the pattern's measuring range

Compensate = Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]


def characterisation(
    axis: str = "x",
    stop_um: float | None = None,
    step_um: float = 5.0,
    cycles: int = 3,
    dwell_s: float = 1.0,
    start_um: float = 0.0,
    overtravel_um: float = 10.0,
) -> Plan:
    """Forward/backward sweeps of one stage (Sec. 4.4.1; thesis: 5 µm steps, 3 cycles).

    Rows: the home row (0, 0, 0) (pose 0, direction 0); then per cycle an approach row at
    ``start_um - overtravel_um``, the forward pass ``start_um .. stop_um`` (direction +1),
    an approach row at ``stop_um + overtravel_um`` and the backward pass
    ``stop_um .. start_um`` (direction -1). The approach rows (direction 0, poses N+1 and
    N+2) make every measured point of a pass really approached in that pass's direction,
    turning points included; ``overtravel_um`` must exceed the backlash (2 µm, Table 4.1).
    The same position has the same pose 1..N in both directions. The other XY joint and
    Θ stay at 0. ``stop_um`` defaults to the stroke: 9500 µm (x) or 4200 µm (y).
    """
    if axis not in ("x", "y"):
        raise ValueError(f"characterisation.axis: expected 'x' or 'y', got {axis!r}")
    stop = STROKE_UM[axis] if stop_um is None else float(stop_um)
    if step_um <= 0 or stop <= start_um:
        raise ValueError(
            f"characterisation: expected step_um > 0 and stop_um > start_um, got "
            f"step {step_um}, start {start_um}, stop {stop}"
        )
    if cycles < 1:
        raise ValueError(f"characterisation.cycles: expected at least 1, got {cycles}")
    if overtravel_um <= 0:
        raise ValueError(f"characterisation.overtravel_um: expected > 0, got {overtravel_um}")
    n = int(round((stop - start_um) / step_um)) + 1
    pos = start_um + step_um * np.arange(n)
    idx = np.arange(1, n + 1)
    q, pose, cyc, direction = [0.0], [0], [0], [0]
    for c in range(cycles):
        for values, poses, d in (
            ([start_um - overtravel_um], [n + 1], 0),
            (pos, idx, 1),
            ([stop + overtravel_um], [n + 2], 0),
            (pos[::-1], idx[::-1], -1),
        ):
            q.extend(values)
            pose.extend(poses)
            cyc.extend([c] * len(values))
            direction.extend([d] * len(values))
    q = np.asarray(q, dtype=float)
    zeros = np.zeros_like(q)
    commands = {
        "x": q if axis == "x" else zeros,
        "y": q if axis == "y" else zeros.copy(),
        "theta": zeros.copy(),
    }
    return Plan(
        name=f"characterisation_{axis}",
        commands=commands,
        pose=np.asarray(pose),
        cycle=np.asarray(cyc),
        direction=np.asarray(direction),
        dwell_s=dwell_s,
    )


def _xy_plan(
    name: str, x_T, y_T, pose, cycle, compensate: Compensate | None, directions: str, dwell_s: float
) -> Plan:
    """Home row + XY targets commanded through ``compensate`` (identity when None)."""
    from calflow.xytheta.tables.position import (  # analysis helpers, no rig
        infer_directions,
        sequential_commands,
    )

    x_T, y_T = np.asarray(x_T, dtype=float), np.asarray(y_T, dtype=float)
    if compensate is None:
        X, Y = x_T.copy(), y_T.copy()
    elif directions == "target":  # Fig. 4.10: compare each target with the previous one
        X, Y = compensate(x_T, y_T, infer_directions(x_T), infer_directions(y_T))
    elif directions == "command":
        X, Y, _, _ = sequential_commands(compensate, x_T, y_T)
    else:
        raise ValueError(f"{name}.directions: expected 'target' or 'command', got {directions!r}")
    nan = np.array([np.nan])
    n = 1 + len(x_T)
    return Plan(
        name=name,
        commands={"x": np.concatenate([[0.0], X]), "y": np.concatenate([[0.0], Y]), "theta": np.zeros(n)},
        targets={"x": np.concatenate([nan, x_T]), "y": np.concatenate([nan, y_T])},
        pose=np.concatenate([[0], pose]),
        cycle=np.concatenate([[0], cycle]),
        direction=np.zeros(n, dtype=int),
        dwell_s=dwell_s,
    )


def square_targets(
    side_um: float = 4000.0, origin_um: float = 10.0, points_per_segment: int = 40
) -> np.ndarray:
    """Stage-frame targets (4·N, 2) of the square A→B→C→D→(A) of Fig. 4.12, µm.

    A = (o, o), B = (o + s, o), C = (o + s, o + s), D = (o, o + s); each segment has
    N points from its first corner (included) towards the next one (excluded).
    """
    if points_per_segment < 1 or side_um <= 0:
        raise ValueError(
            f"square: expected points_per_segment >= 1 and side_um > 0, got {points_per_segment}, {side_um}"
        )
    o, s = float(origin_um), float(side_um)
    corners = np.array([[o, o], [o + s, o], [o + s, o + s], [o, o + s], [o, o]])
    u = np.arange(points_per_segment) / points_per_segment
    return np.vstack([a + u[:, None] * (b - a) for a, b in zip(corners[:-1], corners[1:])])


def square(
    side_um: float = 4000.0,
    origin_um: float = 10.0,
    points_per_segment: int = 40,
    cycles: int = 5,
    compensate: Compensate | None = None,
    directions: str = "command",
    dwell_s: float = 1.0,
) -> Plan:
    """Square-trajectory tracking, Fig. 4.12/4.13: ``cycles`` laps of AB BC CD DA.

    ``compensate(x_T, y_T, direction_x, direction_y) -> (X, Y)`` maps stage-frame targets
    (µm) and approach directions (±1) to joint commands (µm), e.g.
    ``PositionLUT.compensate``; None commands the targets themselves (ex = ey = 0).
    ``directions``: ``"target"`` infers each direction from the previous *target*
    (Fig. 4.10, as in the thesis); ``"command"`` (default) makes them consistent with
    the sign of the *command* change, which is what the stage does (a command that must
    creep back on an axis whose target is constant, e.g. X on BC, reverses it; see
    ``calflow.xytheta.tables.position.sequential_commands``). Pose k = 1..4N is the k-th square point;
    segment = (pose - 1) // N (0 AB, 1 BC, 2 CD, 3 DA). Direction column: 0.
    """
    t = square_targets(side_um, origin_um, points_per_segment)
    if cycles < 1:
        raise ValueError(f"square.cycles: expected at least 1, got {cycles}")
    return _cycled(t, cycles, "square", compensate, directions, dwell_s)


def random_points(
    cycles: int = 5,
    targets=None,
    compensate: Compensate | None = None,
    directions: str = "command",
    dwell_s: float = 1.0,
) -> Plan:
    """Random-point positioning, Table 4.3 / Fig. 4.15: P1..PM in sequence, ``cycles`` times.

    ``targets`` (M, 2) stage-frame x_T, y_T in µm, Table 4.3 by default; ``compensate``
    and ``directions`` as in :func:`square`. Pose i is target P_i.
    """
    t = TABLE_4_3 if targets is None else np.asarray(targets, dtype=float)
    if t.ndim != 2 or t.shape[1] != 2 or len(t) < 1:
        raise ValueError(f"random_points.targets: expected rows of [x_um, y_um], got shape {t.shape}")
    if cycles < 1:
        raise ValueError(f"random_points.cycles: expected at least 1, got {cycles}")
    return _cycled(t, cycles, "random_points", compensate, directions, dwell_s)


def _cycled(
    t: np.ndarray, cycles: int, kind: str, compensate: Compensate | None, directions: str, dwell_s: float
) -> Plan:
    """The M targets ``t`` (M, 2) visited in sequence ``cycles`` times: pose i is target i
    (1..M), cycle c (0-based)."""
    m = len(t)
    tt = np.tile(t, (cycles, 1))
    return _xy_plan(
        kind,
        tt[:, 0],
        tt[:, 1],
        np.tile(np.arange(1, m + 1), cycles),
        np.repeat(np.arange(cycles), m),
        compensate,
        directions,
        dwell_s,
    )


def angle_residuals(targets=None, angles=(1, 2, 3, 4, 5)) -> np.ndarray:
    """Task-space targets (M·K, 3) [x_T µm, y_T µm, Θ_T degree] of Fig. 4.26.

    Each of the M world-frame positions ``targets`` (M, 2) is visited at the K ``angles``
    in turn. Default positions: the distinct (x_T, y_T) of Table 4.7 (a 3 × 3 grid).
    """
    if targets is None:
        _, first = np.unique(TABLE_4_7[:, :2], axis=0, return_index=True)
        xy = TABLE_4_7[np.sort(first), :2]
    else:
        xy = np.asarray(targets, dtype=float)
    if xy.ndim != 2 or xy.shape[1] != 2 or len(xy) < 1:
        raise ValueError(f"angle_residuals.targets: expected rows of [x_um, y_um], got shape {xy.shape}")
    a = np.asarray(angles, dtype=float).ravel()
    if a.size < 1:
        raise ValueError("angle_residuals.angles: expected at least one angle")
    return np.column_stack([np.repeat(xy, a.size, axis=0), np.tile(a, len(xy))])


def angle_residual_plan(
    inverse, targets=None, angles=(1, 2, 3, 4, 5), cycles: int = 3, dwell_s: float = 1.0
) -> Plan:
    """The angle-residual run (Fig. 4.26): :func:`angle_residuals` commanded through
    ``inverse(x_T, y_T, Θ_T) -> (X, Y)`` (Model II or III, Eq. 4.19), home row first."""
    plan = validation(inverse, targets=angle_residuals(targets, angles), cycles=cycles, dwell_s=dwell_s)
    return dataclasses.replace(plan, name="angle_residuals")


def angle_sweep(
    inverse,
    positions,
    theta_range=(0.0, 5.0),
    step_deg: float = 0.1,
    cycles: int = 2,
    dwell_s: float = 1.0,
    overtravel_deg: float = 0.2,
) -> Plan:
    """Angle characterisation (Sec. 4.5.5): Θ swept forward and backward at fixed positions.

    ``positions`` (M, 2) are world-frame points x_T, y_T (µm); at each, per cycle: an
    approach row at Θ_lo − ``overtravel_deg`` (direction 0), the forward pass Θ_lo..Θ_hi in
    ``step_deg`` steps (direction +1), an approach row at Θ_hi + ``overtravel_deg`` and the
    backward pass (direction −1) — like the XY sweeps, so every tabulated angle is
    approached in its pass's direction. Commands come from ``inverse(x_T, y_T, Θ_T)``
    (the base model, Eq. 4.19). Pose k ≥ 1 indexes (position, angle); home row first.
    """
    xy = np.asarray(positions, dtype=float)
    if xy.ndim != 2 or xy.shape[1] != 2 or len(xy) < 1:
        raise ValueError(f"angle_residuals.targets: expected rows of [x_um, y_um], got shape {xy.shape}")
    lo, hi = (float(v) for v in theta_range)
    if not (step_deg > 0 and hi > lo):
        raise ValueError(
            f"angle_residuals: expected step_deg > 0 and theta_deg ordered, got {step_deg}, {theta_range}"
        )
    if cycles < 2:
        raise ValueError(f"angle_residuals.cycles: expected at least 2, got {cycles}")
    n = int(round((hi - lo) / step_deg)) + 1
    angles = np.linspace(lo, hi, n)
    rows = [(np.nan, np.nan, 0.0, 0, 0, 0)]  # x_T, y_T, Θ_T, pose, cycle, direction
    for m, (x, y) in enumerate(xy):
        first = 1 + m * (n + 2)
        for c in range(cycles):
            rows.append((x, y, lo - overtravel_deg, first + n, c, 0))
            rows += [(x, y, a, first + k, c, 1) for k, a in enumerate(angles)]
            rows.append((x, y, hi + overtravel_deg, first + n + 1, c, 0))
            rows += [(x, y, a, first + k, c, -1) for k, a in reversed(list(enumerate(angles)))]
    r = np.array(rows, dtype=float)
    X, Y = inverse(r[1:, 0], r[1:, 1], r[1:, 2])
    return Plan(
        name="angle_residuals",
        commands={"x": np.concatenate([[0.0], X]), "y": np.concatenate([[0.0], Y]), "theta": r[:, 2].copy()},
        targets={"x": r[:, 0], "y": r[:, 1], "theta": np.concatenate([[np.nan], r[1:, 2]])},
        pose=r[:, 3].astype(int),
        cycle=r[:, 4].astype(int),
        direction=r[:, 5].astype(int),
        dwell_s=dwell_s,
    )
