"""The simulated 6-DoF hexapod under a laser tracker: calflow's rig protocol.

Joints are the controller's pose axes ``x``, ``y``, ``z`` (µm) and ``u``, ``v``, ``w``
(degree), commanded as a C-887-class controller takes them (pivot at the platform frame's
origin). A move runs what the controller and the legs do:

1. the controller's inverse kinematics through its **nominal** geometry
   (:func:`calflow_hexapod.models.kinematics.inverse` of :meth:`HexapodTruth.nominal`) gives six
   leg lengths; the servo holds each leg's encoder at a whole count of it (quantisation);
2. the true legs differ from the encoders' lengths by the offsets, the screw-pitch scale,
   the play on the side of the leg's last motion, thermal expansion, the compression under
   the payload and a random repeatability (:mod:`calflow_hexapod.stage.physics`);
3. the platform goes where the true legs put it on the true joints: the forward kinematics
   (:func:`calflow_hexapod.models.kinematics.forward`) of the true geometry.

``read`` gives the laser tracker's pose of the probe (:mod:`calflow_hexapod.stage.tracker`) and
two thermometers: ``T1`` the room's air, ``T2`` on a leg (5 mK noise, 1 mK resolution).
Time is virtual; a seed and a stream make a run reproducible to the byte. The rig's truth
(:meth:`SimulatedHexapod.truth`) is for tests and reports only.
"""

from __future__ import annotations

import zlib
from collections.abc import Mapping

import numpy as np

from calflow.errors import RigError
from calflow.rigs.simulated.commands import joint_commands
from calflow.rigs.thermal import LagBank, room_profile
from calflow_hexapod.models.geometry import AXES
from calflow_hexapod.models.kinematics import forward, inverse
from calflow_hexapod.stage import tracker
from calflow_hexapod.stage.physics import HexapodTruth, check_options
from calflow_hexapod.stage.workspace import reachable

NAME = "simulated hexapod rig"  # how its errors name it

__all__ = [
    "SENSORS",
    "THERMOMETERS",
    "HexapodTruth",
    "SimulatedHexapod",
    "check_options",
    "simulated_hexapod",
]

SENSORS = tuple(f"meas_{a}" for a in AXES)
THERMOMETERS = ("T1", "T2")
THERMOMETER_NOISE_DEGC = 0.005


class Environment:
    """The room (``T1``) and the legs' temperature (``T2``, a first-order lag of ``leg_lag_s``)
    at rig times (s), from the truth's room profile (:mod:`calflow.rigs.thermal`)."""

    def __init__(self, truth: HexapodTruth) -> None:
        self.offset = truth.start_offset_s
        self.room = room_profile(truth.room_profile, base_c=truth.room_base_degC, seed=truth.room_seed)
        self.legs = LagBank(self.room, [truth.leg_lag_s], earliest_s=self.offset)

    def air(self, t_s) -> np.ndarray:
        return np.asarray(self.room(np.asarray(t_s, dtype=float) + self.offset), dtype=float)

    def leg(self, t_s) -> np.ndarray:
        return np.asarray(self.legs(np.asarray(t_s, dtype=float) + self.offset), dtype=float)[..., 0]


class HexapodState:
    """What a sequence of moves leaves: encoder leg lengths, each leg's last direction, time.

    Shared by the simulated rig and the tracker sensor of the ``gcs`` rig
    (:mod:`calflow_hexapod.stage.sensor`), so both see the same physics for the same moves."""

    def __init__(self, truth: HexapodTruth) -> None:
        self.truth = truth
        self.nominal = truth.nominal()
        self.encoders = truth.quantise(self.nominal.zero_lengths)
        self.direction = np.ones(6)  # home is approached extending every leg
        self.cmd = np.zeros(6)
        self.time = 0.0

    def travel_s(self, new: np.ndarray) -> float:
        """Virtual time (s) of a move from the last command to ``new``: the slower of the
        translation and the rotation at the truth's velocities, plus settling."""
        d = np.abs(np.asarray(new, dtype=float) - self.cmd)
        t = self.truth
        return (
            max(
                float(d[:3].max()) / t.velocity_um_s,
                float(d[3:].max()) / t.velocity_deg_s,
            )
            + t.settle_s
        )

    def step(self, new: np.ndarray, encoders: np.ndarray | None = None) -> None:
        """Move to command ``new`` (6,): the encoders' lengths (the nominal inverse kinematics,
        quantised, unless given), each leg's direction where it moved, the time."""
        enc = (
            self.truth.quantise(inverse(self.nominal, new))
            if encoders is None
            else np.asarray(encoders, float)
        )
        delta = enc - self.encoders
        self.direction = np.where(delta > 0, 1.0, np.where(delta < 0, -1.0, self.direction))
        self.time += self.travel_s(new)
        self.encoders, self.cmd = enc, np.asarray(new, dtype=float).copy()


def attained(truth: HexapodTruth, geometry, encoders, direction, leg_temperature, cmd, jitter) -> np.ndarray:
    """True platform poses (n, 6) for encoder lengths (n, 6) µm approached in ``direction``
    (n, 6), leg temperatures (n,) degC, from the commands ``cmd`` (n, 6) (the Newton start) and
    standard normal draws ``jitter`` (n, 6) of the legs' repeatability."""
    legs = truth.true_legs(encoders, direction, leg_temperature, cmd) + truth.leg_repeatability_um * jitter
    return forward(geometry, legs, start=cmd)


class SimulatedHexapod:
    """The simulated hexapod rig; implements calflow's rig protocol."""

    joints = AXES
    sensors = SENSORS
    thermometers = THERMOMETERS
    replayable = True  # deterministic given its seed: acquisition may replay it to resume

    def __init__(self, truth: HexapodTruth, seed: int = 0, stream: str = "") -> None:
        self.truth_model = truth
        self._rng = np.random.default_rng(np.random.SeedSequence([int(seed), zlib.crc32(stream.encode())]))
        self._geometry = truth.geometry()
        self._env = Environment(truth)
        self._state = HexapodState(truth)
        self._pose = self._attain_rows(
            self._state.encoders[None],
            self._state.direction[None],
            np.array([0.0]),
            np.zeros((1, 6)),
            np.zeros((1, 6)),
        )[0]
        self._closed = False

    def _attain_rows(self, enc, direction, t_s, cmd, jitter) -> np.ndarray:
        return attained(
            self.truth_model,
            self._geometry,
            enc,
            direction,
            self._env.leg(t_s),
            cmd,
            jitter,
        )

    def _command(self, command: Mapping[str, float]) -> np.ndarray:
        return joint_commands(NAME, "move", self._closed, self.joints, command)

    def _check_reachable(self, cmd: np.ndarray) -> None:
        """Refuse commands outside the workspace, as the C-887 does (GCS error 7)."""
        ok = reachable(np.atleast_2d(cmd))
        if not ok.all():
            row = np.atleast_2d(cmd)[int(np.argmin(ok))]
            raise RigError(
                f"simulated hexapod rig: command {dict(zip(self.joints, (round(float(v), 4) for v in row)))} is "
                "outside the workspace (a coordinate's travel or a leg's stroke; the C-887 refuses it with "
                "GCS error 7)"
            )

    def move(self, command: Mapping[str, float]) -> None:
        new = self._command(command)
        self._check_reachable(new)
        self._state.step(new)
        jitter = self._rng.standard_normal(6)
        s = self._state
        self._pose = self._attain_rows(
            s.encoders[None],
            s.direction[None],
            np.array([s.time]),
            new[None],
            jitter[None],
        )[0]

    def wait(self, seconds: float) -> None:
        self._state.time += max(0.0, float(seconds))

    def read(self) -> dict[str, float]:
        if self._closed:
            raise RigError("simulated hexapod rig: read() after close()")
        z, w = self._rng.standard_normal(6), self._rng.standard_normal(2)
        r = self._sense(self._pose[None], np.array([self._state.time]), z[None], w[None])
        return {k: float(v[0]) for k, v in r.items()}

    def _sense(self, pose, t_s, z, w) -> dict[str, np.ndarray]:
        """Readings at true poses (n, 6) and times (n,) from the tracker's draws ``z`` (n, 6)
        and the thermometers' ``w`` (n, 2)."""
        out = {
            "time": np.asarray(t_s, dtype=float),
            **tracker.read(self.truth_model, pose, z),
        }
        for k, (name, temp) in enumerate((("T1", self._env.air(t_s)), ("T2", self._env.leg(t_s)))):
            out[name] = np.round(temp + THERMOMETER_NOISE_DEGC * w[:, k], 3)
        return out

    def visit(self, commands: Mapping[str, np.ndarray], dwell_s: float) -> dict[str, np.ndarray]:
        """``move`` to each row of ``commands`` (arrays by joint), ``wait(dwell_s)``, ``read``:
        the same readings, final state and random draws as those calls one by one, with the
        kinematics solved once over all rows (the acquisition runner's fast path)."""
        cmd = joint_commands(NAME, "visit", self._closed, self.joints, commands)
        if len(cmd):
            self._check_reachable(cmd)
        n, s, rng = len(cmd), self._state, self._rng
        enc, direction, t_move, t_read = (
            np.empty((n, 6)),
            np.empty((n, 6)),
            np.empty(n),
            np.empty(n),
        )
        jitter, z, w = np.empty((n, 6)), np.empty((n, 6)), np.empty((n, 2))
        legs = self.truth_model.quantise(inverse(s.nominal, cmd)) if n else np.empty((0, 6))
        for i in range(n):  # the sequential part: state and draws, in the order move/read take them
            s.step(cmd[i], legs[i])
            enc[i], direction[i], t_move[i] = s.encoders, s.direction, s.time
            jitter[i] = rng.standard_normal(6)
            self.wait(dwell_s)
            t_read[i] = s.time
            z[i], w[i] = rng.standard_normal(6), rng.standard_normal(2)
        if n == 0:
            return self._sense(np.empty((0, 6)), t_read, z, w)
        poses = self._attain_rows(enc, direction, t_move, cmd, jitter)
        self._pose = poses[-1].copy()
        return self._sense(poses, t_read, z, w)

    def positions(self) -> dict[str, float]:
        """The controller's encoder-true pose (``POS?``): the nominal forward kinematics of the
        encoders' leg lengths — blind to every error of the legs and joints."""
        s = self._state
        return dict(
            zip(
                self.joints,
                (float(v) for v in forward(s.nominal, s.encoders, start=s.cmd)),
            )
        )

    def close(self) -> None:
        self._closed = True

    def truth(self) -> dict:
        """The rig's true physics, for tests and reports only."""
        g = self._geometry
        return {
            "rig": "simulated_hexapod",
            **self.truth_model.as_dict(),
            "base_um": g.base.tolist(),
            "platform_um": g.platform.tolist(),
            "leg_offsets_um": self.truth_model.leg_offsets().tolist(),
            "leg_scales": self.truth_model.leg_scales().tolist(),
        }


def simulated_hexapod(seed: int = 0, stream: str = "", **physics) -> SimulatedHexapod:
    """Factory of the simulated hexapod rig; ``physics`` overrides :class:`HexapodTruth` fields."""
    o = check_options(seed, stream, **physics)
    seed, stream = o.pop("seed"), o.pop("stream")
    return SimulatedHexapod(HexapodTruth(**o), seed=seed, stream=stream)


simulated_hexapod.check_options = (
    check_options  # the config check calls it (calflow.configuration.rig_factory)
)


def truth_parameters(truth: HexapodTruth):
    """The rig's truth in the models' parameters (:class:`calflow_hexapod.models.ladder.Parameters`):
    frames, joints, leg offsets and scales, the legs' expansion coefficient (1/K) — for tests and
    reports only. Effects no model represents (play, compliance, the tracker's systematic
    error, quantisation) have no parameter."""
    from calflow_hexapod.models.ladder import Parameters

    g = truth.geometry()
    return Parameters(
        np.array([*truth.frame_offset_um, *truth.frame_rotation_deg]),
        np.array([*truth.tool_offset_um, *truth.tool_rotation_deg]),
        g.base,
        g.platform,
        truth.leg_offsets(),
        truth.leg_scales(),
        truth.expansion_ppm_per_degC * 1e-6,
    )
