"""What a closed-loop piezo stage leaves of its actuator's nonlinearities (thesis Sec. 5.3.1, 5.3.3).

Lengths in um, time in s. The P-625.1CD is held by a PID loop on its internal capacitive
sensor. The loop removes most of the piezo's hysteresis and creep at the sensor; what the
interferometer still sees comes from the path between the sensor and the measured point.

* Residual hysteresis: a Prandtl-Ishlinskii sum of play operators (Krasnosel'skii &
  Pokrovskii, *Systems with Hysteresis*, 1989) with radii up to ``max_radius_frac`` of the
  stroke, weighted so that after a long approach the forward/backward difference is
  ``hysteresis_nm`` (Sec. 5.3.3: ~10 nm). Short approaches (a step smaller than a radius)
  leave that operator partly reversed, so the error depends on the step, not only on the
  direction.
* Residual creep: the open-loop log creep x(t) = x0 [1 + gamma lg(t / 0.1 s)] of a step
  (PI, *Piezo Mechanics Design Tutorial*: gamma = 1-2 % per time decade) times the loop's
  residual fraction, which is the ratio of the closed-loop hysteresis to the open-loop one
  (10-15 % of the travel for piezo stacks, same source): the loop attenuates both the same.
* Capacitive-sensor nonlinearity: a parallel-plate sensor's 1/gap law left after the
  electronics' linearisation, the deviation of 1/(1 + s) from its chord, scaled to a peak
  to valley of ``linearity_pct`` of the stroke.
* Closed-loop step response: the loop (a PI controller on the sensor, in a digital
  controller) makes the stage follow a commanded step like a second-order system of
  natural frequency f_n and damping ratio zeta < 1,
  y(t) = 1 - exp(-zeta w t) [cos(w_d t) + zeta / sqrt(1 - zeta^2) sin(w_d t)],
  w = 2 pi f_n, w_d = w sqrt(1 - zeta^2) (e.g. Ogata, *Modern Control Engineering*, 5th ed.,
  Sec. 5-3): peak overshoot exp(-pi zeta / sqrt(1 - zeta^2)) of the step at t = pi / w_d,
  inside +-2 % after about 4 / (zeta w).
"""

from __future__ import annotations

import numpy as np

from calflow.rigs.servo import closed_loop_step  # noqa: F401 (the closed loop's step, shared with the GCS emulation)

__all__ = [
    "PlayHysteresis",
    "closed_loop_step",
    "gain_offset_um",
    "residual_creep_um",
    "sensor_nonlinearity_um",
    "loop_residual_pct",
]

_RADII = (0.125, 0.25, 0.5, 1.0)  # fractions of the largest radius


class PlayHysteresis:
    """Residual hysteresis of one axis: ``error(z, x) = sum_i w_i (z_i - x)`` in um."""

    def __init__(self, stroke_um: float, hysteresis_nm: float, max_radius_frac: float = 0.08):
        self.radii = np.array(_RADII) * max_radius_frac * stroke_um
        total = float(np.sum(self.radii))
        self.weights = np.full(self.radii.size, 0.5e-3 * hysteresis_nm / total if total > 0 else 0.0)

    def initial(self, x: float = 0.0) -> np.ndarray:
        """Play states of a stage that has not moved since ``x``."""
        return np.full(self.radii.size, float(x))

    def step(self, z: np.ndarray, x: float) -> np.ndarray:
        """Play states after moving to ``x`` from states ``z``."""
        return np.clip(z, x - self.radii, x + self.radii)

    def long_approach(self, x, direction) -> np.ndarray:
        """Play states after a long approach in ``direction`` (+1, -1; 0: centred), shape x.shape + (n,)."""
        x = np.asarray(x, dtype=float)[..., None]
        return x - np.asarray(direction, dtype=float)[..., None] * self.radii

    def error(self, z, x):
        """Hysteresis error (um) for play states ``z`` (..., n) at position ``x``."""
        return np.sum(self.weights * (np.asarray(z) - np.asarray(x, dtype=float)[..., None]), axis=-1)

    def sequence(self, xs, x0: float = 0.0) -> np.ndarray:
        """Play states after each of the commands ``xs`` in turn, from rest at ``x0``; (len, n)."""
        z = self.initial(x0)
        out = np.empty((len(xs), self.radii.size))
        for k, x in enumerate(np.asarray(xs, dtype=float)):
            z = self.step(z, x)
            out[k] = z
        return out


def loop_residual_pct(
    hysteresis_nm: float, stroke_um: float, open_loop_hysteresis_pct: float = 12.0
) -> float:
    """Percentage of the actuator's nonlinearity the loop leaves at the measured point: closed-loop
    over open-loop hysteresis (module docstring; 12 %: the middle of the 10-15 % class figure)."""
    return 100.0 * 1e-3 * hysteresis_nm / (open_loop_hysteresis_pct * 1e-2 * stroke_um)


def residual_creep_um(step_um, since_move_s, creep_pct_per_decade: float, residual: float, t0_s: float = 0.1):
    """Creep (um) of the last step ``step_um`` ``since_move_s`` after the move started, left by
    the loop: residual x gamma x step x lg(1 + t / t0) (module docstring)."""
    t = np.maximum(np.asarray(since_move_s, dtype=float), 0.0)
    return (
        residual * creep_pct_per_decade * 1e-2 * np.asarray(step_um, dtype=float) * np.log10(1.0 + t / t0_s)
    )


def sensor_nonlinearity_um(s, stroke_um: float, linearity_pct: float):
    """Capacitive-sensor nonlinearity (um) at normalised position ``s`` (module docstring);
    zero at both ends of the stroke, peak to valley ``linearity_pct`` % of the stroke."""
    s = np.asarray(s, dtype=float)
    dev = 1.0 / (1.0 + s) - (1.0 - 0.5 * s)  # deviation from the chord, <= 0, peak at s = sqrt(2) - 1
    peak = 1.0 / (1.0 + (np.sqrt(2.0) - 1.0)) - (1.0 - 0.5 * (np.sqrt(2.0) - 1.0))
    return linearity_pct * 1e-2 * stroke_um * dev / abs(peak)


def gain_offset_um(x, gain_pct: float, offset_nm: float):
    """What an aged stage adds to a reading (um) at command ``x`` (um): its change of gain,
    ``gain_pct`` % of the command, and the shift of its zero ``offset_nm``
    (:mod:`calflow.nano.stage.aging`). ``x`` a float or an array; +0.0 for an unaged stage."""
    return gain_pct * 1e-2 * x + offset_nm * 1e-3
