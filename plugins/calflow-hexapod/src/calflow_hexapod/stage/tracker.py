"""The measuring instrument of the simulated hexapod: a laser tracker with a 6-D probe.

A Leica AT960-class absolute laser tracker follows a 6-D probe (T-Mac class) fixed on the
platform and reports the probe's pose — position of its reflector and orientation — in a
*measurement frame* the tracker software sets up roughly aligned with the hexapod's base.
The readings ``meas_x``, ``meas_y``, ``meas_z`` (µm) and ``meas_u``, ``meas_v``, ``meas_w``
(degree, the C-887's U → V → W convention) are that pose: M⁻¹ · P · T, P the platform's
true pose, M the measurement frame in the base frame (``frame_*``), T the probe in the
platform frame (``tool_*``).

Error model, from the tracker's specification under ISO 10360-10:2021 (Leica AT960/AT500
user manual, "Laser Tracker Subsystem Specifications"): maximum permissible errors of the
absolute distance meter e_ADM = ±(10 µm + 0.3 µm/m) along the beam and transverse
e_T = ±(15 µm + 6 µm/m) across it, at the distance D from the station; of the T-Mac's
orientation ±0.01° (Leica T-Mac TMC30 data sheet). The manual states typical errors are
half the MPE; we read that half as a 2σ (k = 2) bound, so each MPE gives a random error of
σ = MPE/4 per reading. The angle encoders' own errors make part of the transverse error
systematic — a smooth function of the beam's azimuth and elevation, the same at every
visit: ``tracker_systematic_um`` with a period of 0.5° of beam angle. *Unmodelled*.
Positions are rounded to the ADM's 0.1 µm display resolution.
"""

from __future__ import annotations

import numpy as np

from calflow_hexapod.models.geometry import angles, rotation
from calflow_hexapod.stage.physics import HexapodTruth

SYSTEMATIC_PERIOD_DEG = 0.5  # period of the angle-encoder error in beam angle
ELEVATION_DEG = 10.0  # the beam looks down on the hexapod at this angle


def frames(
    truth: HexapodTruth,
) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]:
    """``((R_M, t_M), (R_T, t_T))``: the measurement frame in the base frame and the probe
    frame in the platform frame (rotations and µm)."""
    return (
        (
            rotation(*truth.frame_rotation_deg),
            np.asarray(truth.frame_offset_um, dtype=float),
        ),
        (
            rotation(*truth.tool_rotation_deg),
            np.asarray(truth.tool_offset_um, dtype=float),
        ),
    )


def probe_pose(truth: HexapodTruth, platform_pose) -> tuple[np.ndarray, np.ndarray]:
    """The probe's true position (n, 3, µm) and rotation (n, 3, 3) in the measurement frame
    for platform poses (n, 6: x, y, z µm of the platform frame's origin, u, v, w degree)."""
    pose = np.atleast_2d(np.asarray(platform_pose, dtype=float))
    (RM, tM), (RT, tT) = frames(truth)
    R = rotation(pose[:, 3], pose[:, 4], pose[:, 5])
    p_base = pose[:, :3] + R @ tT
    return (p_base - tM) @ RM, np.einsum("ji,njk,kl->nil", RM, R, RT)


def station(truth: HexapodTruth) -> np.ndarray:
    """The tracker station's position in the measurement frame (µm): ``tracker_distance_m``
    from the origin along −X, looking down at :data:`ELEVATION_DEG`."""
    e = np.radians(ELEVATION_DEG)
    return truth.tracker_distance_m * 1e6 * np.array([-np.cos(e), 0.0, np.sin(e)])


def beam_basis(truth: HexapodTruth, p: np.ndarray):
    """Per point (n, 3): the beam's unit vector, a horizontal and a vertical transverse unit
    vector, its azimuth and elevation (degree) and length D (m)."""
    d = p - station(truth)
    D = np.linalg.norm(d, axis=1)
    e = d / D[:, None]
    h = np.cross(np.array([0.0, 0.0, 1.0]), e)
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    v = np.cross(e, h)
    az, el = (
        np.degrees(np.arctan2(d[:, 1], d[:, 0])),
        np.degrees(np.arcsin(d[:, 2] / D)),
    )
    return e, h, v, az, el, D * 1e-6


def systematic(truth: HexapodTruth, p: np.ndarray) -> np.ndarray:
    """The angle encoders' systematic error at points ``p`` (n, 3, µm), a displacement across
    the beam: ``tracker_systematic_um`` · sin of azimuth and of elevation over a 0.5° period.
    *Unmodelled*."""
    _, h, v, az, el, _ = beam_basis(truth, p)
    k = 2 * np.pi / SYSTEMATIC_PERIOD_DEG
    a = truth.tracker_systematic_um
    return a * (np.sin(k * az + 0.4)[:, None] * h + np.sin(k * el + 1.1)[:, None] * v)


def sigmas(truth: HexapodTruth, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """σ of a reading at points ``p``: along the beam and across it (µm, n each), and of each
    orientation angle (degree): MPE/4 (module docstring)."""
    D = beam_basis(truth, p)[5]
    return (
        (truth.tracker_adm_um + truth.tracker_adm_um_per_m * D) / 4.0,
        (truth.tracker_transverse_um + truth.tracker_transverse_um_per_m * D) / 4.0,
        truth.tracker_angle_mdeg * 1e-3 / 4.0,
    )


def read(truth: HexapodTruth, platform_pose, z: np.ndarray) -> dict[str, np.ndarray]:
    """Tracker readings (arrays by sensor name) at true platform poses (n, 6) from the standard
    normal draws ``z`` (n, 6): along the beam, two across it, three orientation angles."""
    p, R = probe_pose(truth, platform_pose)
    z = np.atleast_2d(np.asarray(z, dtype=float))
    e, h, v, _, _, _ = beam_basis(truth, p)
    s_r, s_t, s_a = sigmas(truth, p)
    p = (
        p
        + systematic(truth, p)
        + (s_r * z[:, 0])[:, None] * e
        + (s_t * z[:, 1])[:, None] * h
        + (s_t * z[:, 2])[:, None] * v
    )
    res = truth.tracker_resolution_um
    if res > 0:
        p = np.round(p / res) * res
    noise = rotation(s_a * z[:, 3], s_a * z[:, 4], s_a * z[:, 5])
    uvw = angles(noise @ R)
    return {
        "meas_x": p[:, 0],
        "meas_y": p[:, 1],
        "meas_z": p[:, 2],
        "meas_u": uvw[:, 0],
        "meas_v": uvw[:, 1],
        "meas_w": uvw[:, 2],
    }
