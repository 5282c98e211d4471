"""Hexapod geometry and the pose convention of a C-887-class controller.

**Pose.** A pose is (X, Y, Z, U, V, W): X, Y, Z the translation in µm along the axes of the
spatially fixed work frame, U, V, W rotations in degree about the X, Y and Z axes. PI's
hexapod manuals (H-820 MS207E, H-850 MS202E, H-845 MS222E, sec. "Motion") state that the
rotational axes meet at the pivot point and *move with the platform*, and that a rotation
is "calculated from the individual rotations in the order U -> V -> W". Rotations about
moving axes in the order U, V, W compose as

    R(U, V, W) = Rx(U) · Ry(V) · Rz(W),

the same matrix as rotating first by W about the fixed Z, then V about the fixed Y, then U
about the fixed X. The pivot point c (µm, set by the controller's ``SPI`` command, its R S T
coordinates) is expressed in the platform frame, which coincides with the work frame at the
zero pose. A point p of the platform (platform frame, µm) is then at

    x = R (p − c) + c + t,    t = (X, Y, Z),

so a pure rotation leaves the pivot where it is and a pure translation moves every point by t.

**Nominal geometry.** :func:`h811` is an H-811-class geometry (a six-leg 6-6 platform with its
joints paired on two circles). PI's H-811.I2 datasheet gives the magnitudes it reproduces —
travel ±17 mm in X and Y, ±6.5 mm in Z, ±10° about X and Y, ±21° about Z, a base plate of
136 mm diameter and a height of about 115 mm — but not the joint positions: the joint radii,
pair angles and heights below are chosen to fit those outer dimensions, so the geometry is
of the H-811 class, not PI's drawing. A calibration identifies the real one.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

DEG = np.pi / 180.0
#: Pose coordinates, in the order of the controller's axes (µm, µm, µm, degree, degree, degree).
AXES = ("x", "y", "z", "u", "v", "w")
AXIS_UNITS = {"x": "um", "y": "um", "z": "um", "u": "degree", "v": "degree", "w": "degree"}


def _axis(angle_rad: np.ndarray, k: int) -> np.ndarray:
    """Rotation matrices (..., 3, 3) by ``angle_rad`` about axis k (0 x, 1 y, 2 z)."""
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    R = np.zeros(np.shape(angle_rad) + (3, 3))
    i, j = [(1, 2), (2, 0), (0, 1)][k]
    R[..., k, k] = 1.0
    R[..., i, i] = c
    R[..., j, j] = c
    R[..., i, j] = -s
    R[..., j, i] = s
    return R


def _axis_derivative(angle_rad: np.ndarray, k: int) -> np.ndarray:
    """d/dangle (per radian) of :func:`_axis`."""
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    D = np.zeros(np.shape(angle_rad) + (3, 3))
    i, j = [(1, 2), (2, 0), (0, 1)][k]
    D[..., i, i] = -s
    D[..., j, j] = -s
    D[..., i, j] = -c
    D[..., j, i] = c
    return D


def rotation(u, v, w) -> np.ndarray:
    """R = Rx(U) Ry(V) Rz(W) (…, 3, 3) for U, V, W in degree (the U → V → W order of PI's manuals)."""
    u, v, w = np.broadcast_arrays(*(np.asarray(a, dtype=float) * DEG for a in (u, v, w)))
    return _axis(u, 0) @ _axis(v, 1) @ _axis(w, 2)


def rotation_derivatives(u, v, w) -> np.ndarray:
    """∂R/∂U, ∂R/∂V, ∂R/∂W of :func:`rotation`, per degree, stacked on a leading axis (3, …, 3, 3)."""
    u, v, w = np.broadcast_arrays(*(np.asarray(a, dtype=float) * DEG for a in (u, v, w)))
    X, Y, Z = _axis(u, 0), _axis(v, 1), _axis(w, 2)
    return DEG * np.stack(
        [_axis_derivative(u, 0) @ Y @ Z, X @ _axis_derivative(v, 1) @ Z, X @ Y @ _axis_derivative(w, 2)]
    )


def angles(R: np.ndarray) -> np.ndarray:
    """(U, V, W) in degree (…, 3) of rotation matrices R = Rx(U) Ry(V) Rz(W), |V| < 90°."""
    R = np.asarray(R, dtype=float)
    v = np.arcsin(np.clip(R[..., 0, 2], -1.0, 1.0))
    u = np.arctan2(-R[..., 1, 2], R[..., 2, 2])
    w = np.arctan2(-R[..., 0, 1], R[..., 0, 0])
    return np.stack([u, v, w], axis=-1) / DEG


def transform(pose, pivot=(0.0, 0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """(R, t) (…, 3, 3), (…, 3) of poses (…, 6) (µm, degree) about ``pivot`` (µm): x = R p + t."""
    pose = np.asarray(pose, dtype=float)
    c = np.asarray(pivot, dtype=float)
    R = rotation(pose[..., 3], pose[..., 4], pose[..., 5])
    return R, pose[..., :3] + c - R @ c


def pose_of(R: np.ndarray, t: np.ndarray, pivot=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Inverse of :func:`transform`: the poses (…, 6) (µm, degree) of x = R p + t about ``pivot``."""
    c = np.asarray(pivot, dtype=float)
    return np.concatenate([t - c + R @ c, angles(R)], axis=-1)


def compose(R1, t1, R2, t2) -> tuple[np.ndarray, np.ndarray]:
    """(R1, t1) ∘ (R2, t2): x ↦ R1 (R2 x + t2) + t1."""
    return R1 @ R2, (R1 @ t2[..., None])[..., 0] + t1


def invert(R, t) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of x ↦ R x + t."""
    Rt = np.swapaxes(R, -1, -2)
    return Rt, -(Rt @ t[..., None])[..., 0]


@dataclass(frozen=True)
class Geometry:
    """Joint centres of a 6-6 hexapod, µm.

    ``base`` (6, 3): base joints b_i in the work frame; ``platform`` (6, 3): platform joints
    p_i in the platform frame (the work frame at the zero pose); ``pivot`` (3,): the pivot
    point c in the platform frame (``SPI`` R S T). Leg i joins b_i to p_i.
    """

    base: np.ndarray
    platform: np.ndarray
    pivot: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self) -> None:
        for name in ("base", "platform"):
            a = np.asarray(getattr(self, name), dtype=float)
            if a.shape != (6, 3) or not np.all(np.isfinite(a)):
                raise ValueError(
                    f"geometry: {name} must be 6 finite joint centres (6 × 3 µm), got shape {a.shape}"
                )
            object.__setattr__(self, name, a)
        c = np.asarray(self.pivot, dtype=float)
        if c.shape != (3,) or not np.all(np.isfinite(c)):
            raise ValueError(f"geometry: pivot must be 3 finite coordinates (µm), got {self.pivot!r}")
        object.__setattr__(self, "pivot", c)

    def with_pivot(self, pivot) -> Geometry:
        """The same joints about another pivot point (µm), as ``SPI`` sets it."""
        return Geometry(self.base, self.platform, np.asarray(pivot, dtype=float))

    @property
    def zero_lengths(self) -> np.ndarray:
        """Leg lengths (6,) µm at the zero pose, λ₀."""
        return np.linalg.norm(self.platform - self.base, axis=-1)


def hexagon(radius_um: float, centres_deg, half_gap_deg: float, z_um: float) -> np.ndarray:
    """Six joints on a circle of ``radius_um`` at height ``z_um``, paired ±``half_gap_deg`` about
    each of three ``centres_deg`` (µm)."""
    a = np.repeat(np.asarray(centres_deg, dtype=float), 2) + np.tile([-half_gap_deg, half_gap_deg], 3)
    a = a * DEG
    return np.stack([radius_um * np.cos(a), radius_um * np.sin(a), np.full(6, z_um)], axis=-1)


def h811(pivot=(0.0, 0.0, 0.0)) -> Geometry:
    """The nominal H-811-class geometry (µm): base joints on a 55 mm radius paired ±10° about
    0°, 120°, 240°, 102 mm below the work frame's origin (the platform's top centre at the zero
    pose); platform joints on a 38 mm radius, 12 mm below the top, paired about 60°, 180°, 300°
    so that each leg runs from a base pair to the neighbouring platform pair (legs of about
    96 mm, 22° from vertical). Magnitudes from PI's H-811.I2 datasheet (see the module)."""
    base = hexagon(55_000.0, (0.0, 120.0, 240.0), 10.0, -102_000.0)
    top = hexagon(38_000.0, (-60.0, 60.0, 180.0), 10.0, -12_000.0)
    # leg 2k leaves the base pair k at its − joint for the platform pair before it (its + joint);
    # leg 2k + 1 leaves at the + joint for the platform pair after it (its − joint)
    platform = top[[1, 2, 3, 4, 5, 0]]
    return Geometry(base, platform, np.asarray(pivot, dtype=float))


#: Workspace of the H-811.I2 datasheet, per axis (µm, degree): ± these about the zero pose.
H811_TRAVEL = np.array([17_000.0, 17_000.0, 6_500.0, 10.0, 10.0, 21.0])
