"""Simulated XYΘ micro-robot under a vision sensor (thesis Sec. 4.3–4.5).

The simulator stands in for the thesis hardware (two PI M-111 lead-screw stages and a
SmarAct rotation stage under a microscope reading a pseudo-periodic pattern). Its
physics is richer than the calibration models: lead-screw errors with the 400 µm
thread pitch that differ forward and backward and couple into the other axis
(Fig. 4.8, 4.9), backlash, angle-dependent errors of the Θ stage (Sec. 4.5.5),
intrinsic stage repeatability, and a vision sensor with resolution, noise and thermal
drift (Table 3.3). Time is virtual; a seed makes a run reproducible to the byte.

The vision reading is the camera point M in the pattern frame, Eq. (4.26).
"""

from __future__ import annotations

import zlib
from dataclasses import asdict, dataclass
from typing import Mapping

import numpy as np

from calflow.errors import OptionError, RigError, UnknownOptionError
from calflow.xytheta.kinematics import Parameters, forward, pattern_from_world


@dataclass(frozen=True)
class XYThetaTruth:
    """True physics of the simulated XYΘ rig (units in the field names)."""

    x_R_um: float = 9572.9
    y_R_um: float = 7795.9
    alpha_deg: float = 177.69
    beta_deg: float = -0.11
    thread_pitch_um: float = 400.0
    lead_fwd_um: tuple[float, float] = (4.0, 3.0)  # X, Y lead-screw error amplitude, forward
    lead_bwd_um: tuple[float, float] = (6.0, 4.5)  # backward (Fig. 4.8: same period, other size)
    lead_phase_rad: tuple[float, float] = (0.6, 2.1)
    coupling_um: tuple[float, float] = (1.5, 1.2)  # X motion into y, Y motion into x
    backlash_um: float = 2.0
    stage_repeatability_um: float = 0.5  # 1 sigma per move and axis (Fig. 4.7: ~1 µm over 3 cycles)
    f_ax_cubic_um: float = 0.2  # angle-dependent error f_ax = c Θ³ + runout, µm/deg³ (~20 µm at 5°)
    f_ay_cubic_um: float = -0.15
    runout_um: float = 12.0  # stick-slip runout amplitude of the Θ stage, period 2.5°
    tilt_coupling_um_per_deg: float = 0.5  # rotation × XY-stage tilt (pitch/roll along the strokes)
    tilt_period_um: tuple[float, float] = (1600.0, 1300.0)
    camera_x_um: float = 20.0  # camera point M in the world frame: the pattern origin corner,
    camera_y_um: float = 400.0  # so the X stroke and 3.8 mm of Y are in reach despite α (Sec. 4.4.1)
    pattern_range_um: tuple[float, float] = (9500.0, 4200.0)
    sensor_noise_um: float = 0.05
    sensor_resolution_um: float = 0.01
    sensor_theta_noise_deg: float = 2e-4
    drift_um_per_degC: tuple[float, float] = (0.157, 1.357)  # Table 3.3
    room_temperature_degC: float = 21.0
    room_swing_degC: float = 0.3  # daily swing amplitude
    velocity_um_s: float = 1000.0
    velocity_deg_s: float = 10.0
    settle_s: float = 0.5

    @property
    def parameters(self) -> Parameters:
        return Parameters(self.x_R_um, self.y_R_um, self.alpha_deg, self.beta_deg)

    def lead_error(self, axis: int, q, direction):
        """Lead-screw error of joint ``axis`` (0 = X, 1 = Y) at command ``q`` (µm)."""
        amp = np.where(np.asarray(direction) < 0, self.lead_bwd_um[axis], self.lead_fwd_um[axis])
        phase = 2 * np.pi * np.asarray(q) / self.thread_pitch_um + self.lead_phase_rad[axis]
        backlash = np.where(np.asarray(direction) < 0, -0.5, 0.5) * self.backlash_um
        return amp * np.sin(phase) + backlash

    def coupling_error(self, axis: int, q):
        """Error induced on the other axis by motion of joint ``axis``, same period (Fig. 4.9)."""
        phase = 2 * np.pi * np.asarray(q) / self.thread_pitch_um + self.lead_phase_rad[axis] + 0.8
        return self.coupling_um[axis] * np.sin(phase)

    def angle_error(self, theta, X=0.0, Y=0.0):
        """Angle-dependent displacement (f_ax, f_ay) of the pattern point, µm.

        A cubic and a stick-slip runout of the Θ stage, plus the rotation's coupling with
        the tilt of the XY stages under it (which varies along X and Y): the part of the
        angle-dependent error that depends on position, so a table in Θ alone (Models
        IV, V) cannot hold all of it — "angle-dependent errors include a part of
        position-dependent errors" (Sec. 4.5.5).
        """
        theta = np.asarray(theta, dtype=float)
        runout = self.runout_um * np.sin(2 * np.pi * theta / 2.5)
        c = self.tilt_coupling_um_per_deg * theta
        tilt_x = c * np.sin(2 * np.pi * np.asarray(X) / self.tilt_period_um[0] + 0.4)
        tilt_y = c * np.cos(2 * np.pi * np.asarray(Y) / self.tilt_period_um[1] + 1.1)
        return self.f_ax_cubic_um * theta**3 + runout + tilt_x, self.f_ay_cubic_um * theta**3 - runout + tilt_y

    def tool_point(self, X, Y, theta, dir_x=1, dir_y=1):
        """Noise-free tool point (µm) reached for joint commands approached in ``dir_*``."""
        Xa = np.asarray(X) + self.lead_error(0, X, dir_x) + self.coupling_error(1, Y)
        Ya = np.asarray(Y) + self.lead_error(1, Y, dir_y) + self.coupling_error(0, X)
        f_ax, f_ay = self.angle_error(theta, X, Y)
        return forward(Xa, Ya, theta, self.parameters, f_ax=f_ax, f_ay=f_ay)

    def exact_inverse(self, x_T, y_T, theta, dir_x, dir_y, iterations: int = 50):
        """Joint commands that put the noise-free tool point exactly on the targets.

        For tests only (the oracle validation of issue 4): it uses the rig's truth.
        Solved by Newton iteration on the truth's forward map with the given approach
        directions.
        """
        from calflow.xytheta.kinematics import inverse

        x_T, y_T = np.asarray(x_T, dtype=float), np.asarray(y_T, dtype=float)
        X, Y = inverse(x_T, y_T, theta, self.parameters)
        for _ in range(iterations):
            px, py = self.tool_point(X, Y, theta, dir_x, dir_y)
            rx, ry = x_T - px, y_T - py
            h = 1e-3
            jxx = (self.tool_point(X + h, Y, theta, dir_x, dir_y)[0] - px) / h
            jyx = (self.tool_point(X + h, Y, theta, dir_x, dir_y)[1] - py) / h
            jxy = (self.tool_point(X, Y + h, theta, dir_x, dir_y)[0] - px) / h
            jyy = (self.tool_point(X, Y + h, theta, dir_x, dir_y)[1] - py) / h
            det = jxx * jyy - jxy * jyx
            X, Y = X + (jyy * rx - jxy * ry) / det, Y + (-jyx * rx + jxx * ry) / det
            if np.max(np.abs(rx)) < 1e-9 and np.max(np.abs(ry)) < 1e-9:
                break
        return X, Y

    def vision(self, x_P, y_P, theta, temperature_degC, noise_um):
        """The vision reading (x_m, y_m) of the camera point in the pattern frame, µm.

        Eq. (4.26) for the tool point (x_P, y_P) at angle Θ, plus the thermal drift of
        Table 3.3, the given noise (two draws), the sensor's resolution; NaN when the
        camera sees no pattern (outside its measuring range).
        """
        x_m, y_m = pattern_from_world(x_P, y_P, theta, self.camera_x_um, self.camera_y_um)
        drift = (temperature_degC - self.room_temperature_degC) * np.asarray(self.drift_um_per_degC)
        res = self.sensor_resolution_um
        x_m = float(np.round((x_m + drift[0] + noise_um[0]) / res) * res)
        y_m = float(np.round((y_m + drift[1] + noise_um[1]) / res) * res)
        if not (0 <= x_m <= self.pattern_range_um[0] and 0 <= y_m <= self.pattern_range_um[1]):
            return float("nan"), float("nan")  # the camera sees no pattern: no decodable reading
        return x_m, y_m

    def room_temperature(self, t_s):
        """Room temperature (degC) at virtual time ``t_s``: a daily swing."""
        return self.room_temperature_degC + self.room_swing_degC * np.sin(2 * np.pi * np.asarray(t_s) / 86400.0)


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
        self._dir = np.ones(2)
        self._pose = self._attain(self._cmd)
        self._closed = False

    def _attain(self, cmd: np.ndarray) -> np.ndarray:
        t = self.truth_model
        x_P, y_P = t.tool_point(cmd[0], cmd[1], cmd[2], self._dir[0], self._dir[1])
        jitter = self._rng.normal(0.0, t.stage_repeatability_um, 2)
        return np.array([float(x_P) + jitter[0], float(y_P) + jitter[1], cmd[2]])

    def move(self, command: Mapping[str, float]) -> None:
        if self._closed:
            raise RigError("simulated xytheta rig: move() after close()")
        try:
            new = np.array([float(command[j]) for j in self.joints])
        except KeyError as exc:
            raise RigError(f"simulated xytheta rig: command lacks joint {exc.args[0]!r}") from None
        delta = new - self._cmd
        for k in (0, 1):
            if delta[k] != 0:
                self._dir[k] = np.sign(delta[k])
        t = self.truth_model
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
        x_m, y_m = t.vision(self._pose[0], self._pose[1], self._pose[2], temperature, noise)
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
        return {"rig": "simulated_xytheta", **asdict(self.truth_model)}


# Options that are magnitudes (>= 0) and those that must be > 0; the rest may take any sign.
_NON_NEGATIVE = ("backlash_um", "stage_repeatability_um", "sensor_noise_um", "sensor_theta_noise_deg",
                 "room_swing_degC", "settle_s")
_POSITIVE = ("thread_pitch_um", "sensor_resolution_um", "velocity_um_s", "velocity_deg_s", "pattern_range_um",
             "tilt_period_um")


def _number(key: str, value, bound: str | None):
    ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))
    ok = ok and bool(np.isfinite(value))
    ok = ok and (bound is None or (value > 0 if bound == ">" else value >= 0))
    if not ok:
        expected = {None: "a finite number", ">": "a finite number > 0", ">=": "a finite number >= 0"}[bound]
        raise OptionError(key, expected, value)
    return float(value)


def check_options(seed=0, stream: str = "", **physics) -> dict:
    """The options of the simulated XYΘ rig checked and converted; raises :class:`OptionError`
    naming the option: unknown names, non-numbers, NaN/inf, negative magnitudes (noise,
    resolution, backlash, repeatability), non-positive velocities, pitch and ranges."""
    fields = XYThetaTruth.__dataclass_fields__
    for key in physics:
        if key not in fields:
            raise UnknownOptionError(key, f"expected one of: seed, stream, {', '.join(sorted(fields))}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise OptionError("seed", "an integer >= 0", seed)
    if not isinstance(stream, str):
        raise OptionError("stream", "a string", stream)
    out = {}
    for key, value in physics.items():
        bound = ">" if key in _POSITIVE else ">=" if key in _NON_NEGATIVE else None
        default = fields[key].default
        if isinstance(default, tuple):
            if not isinstance(value, (list, tuple)) or len(value) != len(default):
                raise OptionError(key, f"a list of {len(default)} numbers", value)
            for v in value:
                try:
                    _number(key, v, bound)
                except OptionError:
                    expected = {None: "finite", ">": "finite and > 0", ">=": "finite and >= 0"}[bound]
                    raise OptionError(key, f"a list of {len(default)} numbers, each {expected}", value) from None
            out[key] = tuple(float(v) for v in value)
        else:
            out[key] = _number(key, value, bound)
    return {"seed": int(seed), "stream": stream, **out}


def simulated_xytheta(seed: int = 0, stream: str = "", **physics) -> SimulatedXYTheta:
    """Factory of the simulated XYΘ rig; ``physics`` overrides :class:`XYThetaTruth` fields."""
    o = check_options(seed, stream, **physics)
    seed, stream = o.pop("seed"), o.pop("stream")
    return SimulatedXYTheta(XYThetaTruth(**o), seed=seed, stream=stream)


simulated_xytheta.check_options = check_options  # the config check calls it (calflow.rigs.plugin)
