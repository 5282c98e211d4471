"""The simulated laser tracker as a sensor of calflow's ``gcs`` rig.

Driving a C-887 emulator (:mod:`calflow_hexapod.stage.c887`) with the ``gcs`` rig, the controller's
``POS?`` is encoder-true: the pose its nominal kinematics computes from the legs' encoders.
This sensor is the physical world behind it: from each settled ``POS?`` pose it recovers the
encoders' leg lengths (the nominal inverse kinematics about the controller's pivot, whole
counts), follows each leg's approach direction, and puts the platform where the simulated
physics puts it (:func:`calflow_hexapod.stage.rig.attained`); it then reads the laser tracker and
the thermometers as :class:`calflow_hexapod.stage.rig.SimulatedHexapod` does. A run through the
emulator therefore sees the physics of the simulated rig with the controller's timing,
limits and faults. Options: the simulated rig's (``seed``, ``stream``, the
:class:`~calflow_hexapod.stage.physics.HexapodTruth` fields) and ``pivot_um`` (R, S, T in µm,
as set with ``SPI``).
"""

from __future__ import annotations

import zlib
from collections.abc import Mapping

import numpy as np

from calflow.errors import OptionError, RigError
from calflow_hexapod.models.geometry import AXES
from calflow_hexapod.models.kinematics import inverse
from calflow_hexapod.stage import tracker
from calflow_hexapod.stage.c887 import PIVOT_LIMIT_MM
from calflow_hexapod.stage.physics import HexapodTruth, check_options
from calflow_hexapod.stage.rig import (
    SENSORS,
    THERMOMETER_NOISE_DEGC,
    THERMOMETERS,
    Environment,
    HexapodState,
    attained,
)


class SimulatedTracker:
    """The simulated tracker and thermometers read at the controller's settled poses."""

    sensors = SENSORS
    thermometers = THERMOMETERS

    def __init__(
        self,
        truth: HexapodTruth,
        seed: int = 0,
        stream: str = "",
        pivot_um=(0.0, 0.0, 0.0),
    ) -> None:
        self.truth_model = truth
        self._rng = np.random.default_rng(np.random.SeedSequence([int(seed), zlib.crc32(stream.encode())]))
        self._geometry = truth.geometry()
        self._env = Environment(truth)
        self._state = HexapodState(truth)
        self._controller = truth.nominal().with_pivot(np.asarray(pivot_um, dtype=float))
        s = self._state  # at home, as the simulated rig starts: no repeatability draw yet
        self._pose = attained(
            truth,
            self._geometry,
            s.encoders[None],
            s.direction[None],
            self._env.leg(np.array([0.0])),
            np.zeros((1, 6)),
            np.zeros((1, 6)),
        )[0]

    def _pose_of(self, positions: Mapping[str, float]) -> np.ndarray:
        try:
            return np.array([float(positions[a]) for a in AXES])
        except KeyError as exc:
            raise RigError(f"simulated tracker: positions lack joint {exc.args[0]!r}") from None

    def moved(self, settled: Mapping[str, float], started: float) -> None:
        """After a move: the encoders behind the settled ``POS?`` pose, the legs' directions,
        one repeatability draw, the platform's true pose at the leg temperature of ``started``."""
        cmd = self._pose_of(settled)
        enc = self.truth_model.quantise(inverse(self._controller, cmd))
        s = self._state
        s.step(cmd, enc)
        jitter = self._rng.standard_normal(6)
        self._pose = attained(
            self.truth_model,
            self._geometry,
            enc[None],
            s.direction[None],
            self._env.leg(np.array([float(started)])),
            cmd[None],
            jitter[None],
        )[0]

    def read(self, positions: Mapping[str, float], time_s: float) -> dict[str, float]:
        """The tracker's pose of the probe and the thermometers at rig time ``time_s`` (s)."""
        if np.any(np.abs(self._pose_of(positions) - self._state.cmd) > 1e-6):
            self.moved(positions, time_s)  # a reading without a reported move: the pose it is at
        z, w = self._rng.standard_normal(6), self._rng.standard_normal(2)
        out = {k: float(v[0]) for k, v in tracker.read(self.truth_model, self._pose[None], z[None]).items()}
        t = np.array([float(time_s)])
        out["T1"] = float(np.round(self._env.air(t)[0] + THERMOMETER_NOISE_DEGC * w[0], 3))
        out["T2"] = float(np.round(self._env.leg(t)[0] + THERMOMETER_NOISE_DEGC * w[1], 3))
        return out

    def truth(self) -> dict:
        """The sensor's true physics, for tests and reports only."""
        return {"sensor": "simulated_tracker", **self.truth_model.as_dict()}


def check_tracker_options(seed: int = 0, stream: str = "", pivot_um=(0.0, 0.0, 0.0), **physics) -> dict:
    """The tracker sensor's options checked (the family's option check, run at load): the
    simulated rig's (:func:`~calflow_hexapod.stage.physics.check_options`) and ``pivot_um``,
    3 finite numbers (µm) within the range the controller accepts for its pivot
    (:data:`~calflow_hexapod.stage.c887.PIVOT_LIMIT_MM`: the sensor's pivot is the one set with
    ``SPI``, so one the controller refuses is a typo). Raises :class:`~calflow.errors.OptionError` naming the option."""
    o = check_options(seed, stream, **physics)
    ok = isinstance(pivot_um, (list, tuple)) and len(pivot_um) == 3
    ok = ok and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v) for v in pivot_um
    )
    if not ok:
        raise OptionError("pivot_um", "3 finite numbers (µm: R, S, T)", pivot_um)
    limit_um = PIVOT_LIMIT_MM * 1000.0
    if any(abs(v) > limit_um for v in pivot_um):
        raise OptionError(
            "pivot_um", f"R, S, T within ±{limit_um:.0f} µm, the controller's pivot range (SPI)", pivot_um
        )
    return {**o, "pivot_um": tuple(float(v) for v in pivot_um)}


def simulated_tracker(
    seed: int = 0, stream: str = "", pivot_um=(0.0, 0.0, 0.0), **physics
) -> SimulatedTracker:
    """Factory of the simulated tracker sensor; ``physics`` overrides :class:`HexapodTruth` fields."""
    o = check_tracker_options(seed, stream, pivot_um, **physics)
    seed, stream, pivot = o.pop("seed"), o.pop("stream"), np.asarray(o.pop("pivot_um"))
    return SimulatedTracker(HexapodTruth(**o), seed=seed, stream=stream, pivot_um=pivot)
