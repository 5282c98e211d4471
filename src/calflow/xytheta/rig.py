"""Simulated XYΘ micro-robot under a vision sensor (thesis Sec. 4.3–4.5).

The simulator stands in for the thesis hardware (two PI M-111 lead-screw stages and a
SmarAct rotation stage under a microscope reading a pseudo-periodic pattern). Its
physics (:mod:`calflow.xytheta.rig_physics`, one named term per effect) is richer than
the calibration models: lead-screw errors, lost motion that depends on the approach
distance, scale, straightness, yaw and thermal expansion of the stages, the Θ stage's
angular errors and axis runout, a vision sensor with noise, a per-pose decoding error,
rare gross errors, resolution and thermal drift. Time is virtual; a seed makes a run
reproducible to the byte.

The vision reading is the camera point M in the pattern frame, Eq. (4.26).
"""

from __future__ import annotations

import zlib
from typing import Mapping

import numpy as np

from calflow.errors import RigError
from calflow.xytheta.rig_physics import XYThetaTruth, check_options

__all__ = ["SimulatedXYTheta", "XYThetaTruth", "check_options", "simulated_xytheta"]


class SimulatedXYTheta:
    """The simulated XYΘ rig; implements the rig protocol (DESIGN.md)."""

    joints = ("x", "y", "theta")
    replayable = True  # deterministic given its seed: acquisition may replay it to resume
    sensors = ("meas_x", "meas_y", "meas_theta")
    thermometers = ("T1",)

    def __init__(self, truth: XYThetaTruth, seed: int = 0, stream: str = ""):
        self.truth_model = truth
        seq = np.random.SeedSequence([int(seed), zlib.crc32(stream.encode())])
        self._rng = np.random.default_rng(seq)
        self._time = 0.0
        self._cmd = np.zeros(3)
        self._dir = np.ones(3)  # approach direction of X, Y, Θ: home is approached forward
        self._lash = np.full(2, 0.5 * truth.backlash_um)  # nut play of X and Y (µm)
        self._pose = self._attain(self._cmd)
        self._closed = False

    def _attain(self, cmd: np.ndarray) -> np.ndarray:
        t = self.truth_model
        x_P, y_P, theta_a = t.tool_point(cmd[0], cmd[1], cmd[2], dir_theta=self._dir[2], lash=tuple(self._lash),
                                         temperature_degC=float(t.room_temperature(self._time)))
        jitter = self._rng.normal(0.0, t.stage_repeatability_um, 2)
        return np.array([float(x_P) + jitter[0], float(y_P) + jitter[1], float(theta_a)])

    def move(self, command: Mapping[str, float]) -> None:
        if self._closed:
            raise RigError("simulated xytheta rig: move() after close()")
        try:
            new = np.array([float(command[j]) for j in self.joints])
        except KeyError as exc:
            raise RigError(f"simulated xytheta rig: command lacks joint {exc.args[0]!r}") from None
        delta = new - self._cmd
        t = self.truth_model
        half = 0.5 * t.backlash_um
        for k in (0, 1, 2):
            if delta[k] != 0:
                self._dir[k] = np.sign(delta[k])
        for k in (0, 1):  # lost motion: the play is taken up over the first backlash of travel
            if delta[k] != 0:
                self._lash[k] = (np.clip(self._lash[k] + delta[k], -half, half) if t.lost_motion
                                 else half * self._dir[k])
        self._time += max(abs(delta[0]), abs(delta[1])) / t.velocity_um_s
        self._time += abs(delta[2]) / t.velocity_deg_s + t.settle_s
        self._cmd = new
        self._pose = self._attain(new)

    def wait(self, seconds: float) -> None:
        self._time += max(0.0, float(seconds))

    def read(self) -> dict[str, float]:
        t = self.truth_model
        temperature = float(t.room_temperature(self._time))
        noise = self._rng.normal(0.0, t.sensor_noise_um, 2)
        gross = t.gross_error(*self._rng.random(2))
        x_m, y_m = t.vision(self._pose[0], self._pose[1], self._pose[2], temperature, noise, gross)
        theta_m = self._pose[2] + self._rng.normal(0.0, t.sensor_theta_noise_deg)
        return {
            "time": self._time,
            "meas_x": float(x_m),
            "meas_y": float(y_m),
            "meas_theta": float(theta_m),
            "T1": round(temperature + self._rng.normal(0.0, 0.005), 3),
        }

    def close(self) -> None:
        self._closed = True

    def truth(self) -> dict:
        """The rig's true physics, for tests and reports only."""
        return {"rig": "simulated_xytheta", **self.truth_model.as_dict()}


def simulated_xytheta(seed: int = 0, stream: str = "", **physics) -> SimulatedXYTheta:
    """Factory of the simulated XYΘ rig; ``physics`` overrides :class:`XYThetaTruth` fields."""
    o = check_options(seed, stream, **physics)
    seed, stream = o.pop("seed"), o.pop("stream")
    return SimulatedXYTheta(XYThetaTruth(**o), seed=seed, stream=stream)


simulated_xytheta.check_options = check_options  # the config check calls it (calflow.rigs.plugin)
