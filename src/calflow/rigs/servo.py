"""The step response of a closed-loop positioning axis, shared by the simulated stages and
the controller emulations.

A PI loop on the axis's sensor, in a digital controller, makes the stage follow a commanded
step like a second-order system of natural frequency f_n and damping ratio zeta < 1,
y(t) = 1 - exp(-zeta w t) [cos(w_d t) + zeta / sqrt(1 - zeta^2) sin(w_d t)],
w = 2 pi f_n, w_d = w sqrt(1 - zeta^2) (e.g. Ogata, *Modern Control Engineering*, 5th ed.,
Sec. 5-3): peak overshoot exp(-pi zeta / sqrt(1 - zeta^2)) of the step at t = pi / w_d,
inside +-2 % after about 4 / (zeta w). Time in s.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["closed_loop_step"]


def closed_loop_step(since_move_s, natural_hz: float, damping: float):
    """Unit step response y(t) of the closed loop ``since_move_s`` after the move started
    (module docstring): 0 before the move, -> 1 after it; ``natural_hz`` = 0 is an ideal
    stage (y = 1 at once). Underdamped: 0 < ``damping`` < 1. A float for a scalar time."""
    w = 2.0 * math.pi * natural_hz
    root = math.sqrt(1.0 - damping * damping)
    if np.ndim(since_move_s) == 0:  # one reading: plain floats
        t = float(since_move_s)
        if t < 0.0:
            return 0.0
        if natural_hz <= 0 or damping * w * t > 745.0:  # exp underflows to 0: exactly settled
            return 1.0
        return 1.0 - math.exp(-damping * w * t) * (
            math.cos(w * root * t) + damping / root * math.sin(w * root * t)
        )
    t = np.asarray(since_move_s, dtype=float)
    if natural_hz <= 0:
        return np.where(t < 0.0, 0.0, 1.0)
    tp = np.clip(t, 0.0, 745.0 / (damping * w))  # beyond: settled (and no inf * 0)
    y = 1.0 - np.exp(-damping * w * tp) * (np.cos(w * root * tp) + damping / root * np.sin(w * root * tp))
    return np.where(t < 0.0, 0.0, np.where(t >= 745.0 / (damping * w), 1.0, y))
