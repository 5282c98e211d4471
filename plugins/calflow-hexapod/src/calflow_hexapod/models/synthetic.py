"""Synthetic hexapod data with only the calibration model's own errors, for tests and benchmarks.

A C-887-class controller turns a commanded pose into leg lengths λ through its nominal
geometry; the hexapod's legs then have the lengths the model gives them
(:meth:`calflow_hexapod.models.ladder.Parameters.leg_lengths`) plus Gaussian leg noise; the platform
settles where the true geometry's forward kinematics puts it; the instrument reads the target's
pose in its own frame with Gaussian noise per axis. No other physics: that is the simulated
rig's business. Simulated truth is for tests and benchmarks; identification never reads it.
"""

from __future__ import annotations

import numpy as np

from calflow_hexapod.models import kinematics
from calflow_hexapod.models.calibration import reading
from calflow_hexapod.models.geometry import H811_TRAVEL, Geometry
from calflow_hexapod.models.ladder import NAMES, Parameters

#: Size of each error of a simulated hexapod (1 σ): joint centres 50 µm, leg offsets 20 µm,
#: leg scales 100 ppm; the frames (instrument placement) 2 mm and 1°, 0.5 mm and 0.5°.
ERRORS = {"joint_um": 50.0, "offset_um": 20.0, "scale": 1e-4, "frame": (2000.0, 1.0), "tool": (500.0, 0.5)}


def random_poses(n: int, rng: np.random.Generator, fraction: float = 0.5, travel=H811_TRAVEL) -> np.ndarray:
    """n poses (µm, degree) uniform in ± ``fraction`` of the datasheet travel per axis."""
    return rng.uniform(-1.0, 1.0, (n, 6)) * fraction * np.asarray(travel, dtype=float)


def perturbed(
    rng: np.random.Generator, nominal: Parameters | None = None, only=None, errors=ERRORS
) -> Parameters:
    """A hexapod drawn about ``nominal`` with the errors of ``errors``; ``only`` (names) limits the
    draw to those parameters (the others keep their nominal value)."""
    nominal = nominal or Parameters.nominal()
    frame_t, frame_r = errors["frame"]
    tool_t, tool_r = errors["tool"]
    sizes = np.concatenate(
        [
            [frame_t] * 3,
            [frame_r] * 3,
            [tool_t] * 3,
            [tool_r] * 3,
            [errors["joint_um"]] * 36,
            [errors["offset_um"]] * 6,
            [errors["scale"]] * 6,
            [0.0],
        ]
    )
    step = rng.normal(0.0, 1.0, sizes.size) * sizes
    if only is not None:
        step[[k for k, name in enumerate(NAMES) if name not in set(only)]] = 0.0
    return Parameters.from_vector(nominal.vector() + step)


def simulate(
    truth: Parameters,
    commands,
    controller: Geometry,
    rng: np.random.Generator,
    sigma_pose=(0.0,) * 6,
    sigma_leg_um: float = 0.0,
    temperature=None,
) -> tuple[np.ndarray, np.ndarray]:
    """(measured target poses M (n, 6), commanded leg lengths λ (n, 6)) for commanded poses
    ``commands`` (n, 6) about the controller's pivot; ``sigma_pose`` (µm ×3, degree ×3) and
    ``sigma_leg_um`` the Gaussian noise of the instrument and of the legs."""
    commands = np.asarray(commands, dtype=float)
    lam = kinematics.inverse(controller, commands)
    lengths = truth.leg_lengths(lam, controller.zero_lengths, temperature)
    lengths = lengths + rng.normal(0.0, 1.0, lengths.shape) * sigma_leg_um
    measured = reading(truth, controller, lengths, commands)
    return measured + rng.normal(0.0, 1.0, commands.shape) * np.asarray(sigma_pose, dtype=float), lam
