"""Simulated XYΘ micro-robot under a vision sensor (thesis Sec. 4.3–4.5).

The simulator stands in for the thesis hardware (two PI M-111 lead-screw stages and a
SmarAct rotation stage under a microscope reading a pseudo-periodic pattern). Its
physics (:mod:`calflow.xytheta.stage.physics`, one named term per effect) is richer than
the calibration models: lead-screw errors, lost motion that depends on the approach
distance, scale, straightness, yaw and thermal expansion of the stages, the Θ stage's
angular errors and axis runout, a vision sensor with noise, a per-pose decoding error,
rare gross errors, resolution and thermal drift. Time is virtual; a seed makes a run
reproducible to the byte.

The vision reading is the camera point M in the pattern frame, Eq. (4.26). With
``sensor: images`` it is read through rendered frames of the coded pattern and the
decoder instead of the noise model (:mod:`calflow.xytheta.stage.images`); the stage's own
random draws are the same whichever sensor reads it.
"""

from __future__ import annotations

import zlib
from collections.abc import Mapping

import numpy as np

from calflow.rigs.simulated.commands import joint_commands
from calflow.xytheta.stage.physics import XYThetaTruth, check_options

NAME = "simulated xytheta rig"  # how its errors name it

__all__ = ["SimulatedXYTheta", "XYThetaTruth", "check_options", "simulated_xytheta"]


class SimulatedXYTheta:
    """The simulated XYΘ rig; implements the rig protocol (docs/rigs.md)."""

    joints = ("x", "y", "theta")
    replayable = True  # deterministic given its seed: acquisition may replay it to resume
    sensors = ("meas_x", "meas_y", "meas_theta")
    thermometers = ("T1",)

    def __init__(self, truth: XYThetaTruth, seed: int = 0, stream: str = "", sensor: dict | None = None):
        self.truth_model = truth
        self.images = None
        if sensor and sensor.get("sensor") == "images":
            from calflow.xytheta.stage.images import IMAGE_CHANNELS, ImageSensor

            self.images = ImageSensor(truth, sensor, seed=seed, stream=stream)
            self.sensors = (*type(self).sensors, *IMAGE_CHANNELS)
        seq = np.random.SeedSequence([int(seed), zlib.crc32(stream.encode())])
        self._rng = np.random.default_rng(seq)
        self._time = 0.0
        self._cmd = np.zeros(3)
        self._dir = np.ones(3)  # approach direction of X, Y, Θ: home is approached forward
        self._lash = np.full(2, 0.5 * truth.backlash_um)  # nut play of X and Y (µm)
        self._pose = self._attain(self._cmd)
        self._closed = False

    def _attain(self, cmd: np.ndarray) -> np.ndarray:
        jitter = self._rng.standard_normal(2)  # the draws of normal(0, repeatability, 2)
        pose = self._poses(
            cmd[None, :], self._dir[None, 2], self._lash[None, :], np.array([self._time]), jitter[None, :]
        )
        return pose[0]

    def _poses(self, cmd, dir_theta, lash, time_s, jitter) -> np.ndarray:
        """Attained tool points and angles, (n, 3), of commands ``cmd`` (n, 3) with Θ
        approached in ``dir_theta``, nut plays ``lash`` (n, 2) µm, at virtual times
        ``time_s`` (s), with standard normal draws ``jitter`` (n, 2) for the repeatability."""
        t = self.truth_model
        x_P, y_P, theta_a = t.tool_point(
            cmd[:, 0],
            cmd[:, 1],
            cmd[:, 2],
            dir_theta=dir_theta,
            lash=(lash[:, 0], lash[:, 1]),
            temperature_degC=t.room_temperature(time_s),
        )
        s = t.stage_repeatability_um
        return np.column_stack([x_P + (0.0 + s * jitter[:, 0]), y_P + (0.0 + s * jitter[:, 1]), theta_a])

    def _step(self, new: np.ndarray) -> None:
        """The state a move to ``new`` leaves: approach directions, nut plays, virtual time."""
        t = self.truth_model
        half = 0.5 * t.backlash_um
        for k in (0, 1, 2):
            delta = float(new[k]) - float(self._cmd[k])
            if delta != 0:
                self._dir[k] = 1.0 if delta > 0 else -1.0
                if k < 2:  # lost motion: the play is taken up over the first backlash of travel
                    self._lash[k] = (
                        min(max(float(self._lash[k]) + delta, -half), half)
                        if t.lost_motion
                        else half * self._dir[k]
                    )
        dx, dy, dt = (abs(float(new[k]) - float(self._cmd[k])) for k in (0, 1, 2))
        self._time += max(dx, dy) / t.velocity_um_s
        self._time += dt / t.velocity_deg_s + t.settle_s
        self._cmd = new

    def move(self, command: Mapping[str, float]) -> None:
        new = joint_commands(NAME, "move", self._closed, self.joints, command)
        self._step(new)
        self._pose = self._attain(new)

    def wait(self, seconds: float) -> None:
        self._time += max(0.0, float(seconds))

    def read(self) -> dict[str, float]:
        noise, u, w = self._rng.standard_normal(2), self._rng.random(2), self._rng.standard_normal(2)
        r = self._sense(self._pose[None, :], np.array([self._time]), noise[None, :], u[None, :], w[None, :])
        return {k: float(v[0]) for k, v in r.items()}

    def _sense(self, pose, time_s, noise, u, w) -> dict[str, np.ndarray]:
        """Readings of the rig at poses ``pose`` (n, 3) and times ``time_s`` (s), from the
        standard normal draws ``noise`` (n, 2) of the vision noise, the uniform draws ``u``
        (n, 2) of the gross errors and the standard normal draws ``w`` (n, 2) of the Θ
        sensor's and the thermometer's noise."""
        t = self.truth_model
        temperature = t.room_temperature(time_s)
        if self.images is not None:  # frames rendered at the camera point and decoded
            x_m, y_m = t.camera_point(pose[:, 0], pose[:, 1], pose[:, 2], temperature)
            thermometer = temperature + (0.0 + 0.005 * w[:, 1])
            return {
                "time": np.asarray(time_s, dtype=float),
                **self.images.read(x_m, y_m, pose[:, 2]),
                "T1": np.array([round(float(v), 3) for v in thermometer]),
            }
        gross = t.gross_error(u[:, 0], u[:, 1])
        s = t.sensor_noise_um
        x_m, y_m = t.vision(
            pose[:, 0],
            pose[:, 1],
            pose[:, 2],
            temperature,
            (0.0 + s * noise[:, 0], 0.0 + s * noise[:, 1]),
            gross,
        )
        thermometer = temperature + (0.0 + 0.005 * w[:, 1])
        return {
            "time": np.asarray(time_s, dtype=float),
            "meas_x": x_m,
            "meas_y": y_m,
            "meas_theta": pose[:, 2] + (0.0 + t.sensor_theta_noise_deg * w[:, 0]),
            "T1": np.array([round(float(v), 3) for v in thermometer]),
        }

    def visit(self, commands: Mapping[str, np.ndarray], dwell_s: float) -> dict[str, np.ndarray]:
        """``move`` to each row of ``commands`` (arrays by joint), ``wait(dwell_s)``, ``read``:
        the same readings (arrays by key), final state and random draws as those calls one
        by one, with the physics computed once over all rows (the acquisition runner's fast
        path for open-loop plans)."""
        cmd = joint_commands(NAME, "visit", self._closed, self.joints, commands)
        n = len(cmd)
        dir_theta, lash, t_move, t_read = np.empty(n), np.empty((n, 2)), np.empty(n), np.empty(n)
        jitter, noise, u, w = np.empty((n, 2)), np.empty((n, 2)), np.empty((n, 2)), np.empty((n, 2))
        rng = self._rng
        for i in range(n):  # the sequential part: state and draws, in the order move/read take them
            self._step(cmd[i].copy())
            dir_theta[i], lash[i], t_move[i] = self._dir[2], self._lash, self._time
            jitter[i] = rng.standard_normal(2)
            self.wait(dwell_s)
            t_read[i] = self._time
            noise[i], u[i], w[i] = rng.standard_normal(2), rng.random(2), rng.standard_normal(2)
        if n == 0:
            return self._sense(np.empty((0, 3)), t_read, noise, u, w)
        poses = self._poses(cmd, dir_theta, lash, t_move, jitter)
        self._pose = poses[-1].copy()
        return self._sense(poses, t_read, noise, u, w)

    def close(self) -> None:
        self._closed = True

    def truth(self) -> dict:
        """The rig's true physics, for tests and reports only (with the image sensor's
        options when it reads through images)."""
        out = {"rig": "simulated_xytheta", **self.truth_model.as_dict()}
        if self.images is not None:
            out["sensor"] = dict(self.images.options)
        return out


def simulated_xytheta(seed: int = 0, stream: str = "", **physics) -> SimulatedXYTheta:
    """Factory of the simulated XYΘ rig; ``physics`` overrides :class:`XYThetaTruth` fields,
    ``sensor``/``camera``/``pattern`` choose how the vision sensor reads (stage.images)."""
    o = check_options(seed, stream, **physics)
    seed, stream, sensor = o.pop("seed"), o.pop("stream"), o.pop("sensor", None)
    return SimulatedXYTheta(XYThetaTruth(**o), seed=seed, stream=stream, sensor=sensor)


simulated_xytheta.check_options = (
    check_options  # the config check calls it (calflow.configuration.rig_factory)
)
