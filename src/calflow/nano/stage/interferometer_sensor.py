"""The simulated interferometer and thermocouples of the nano stages, as a ``gcs`` rig sensor.

``simulated_interferometer`` (registered by the nano family as a built-in sensor of the
``gcs`` rig, :mod:`calflow.gcs.sensors`) is the physical world behind the piezo controller
emulation (:mod:`calflow.gcs.emulation.piezo`, :mod:`calflow.nano.stage.emulate`): a simulated nano rig
(:func:`calflow.nano.stage.rig.nano1d` / :func:`~calflow.nano.stage.rig.nano2d`, the same physics as the
``simulated`` rig — geometry, hysteresis, thermal drift, walk, creep, repeatability,
settling, interferometer noise, Sec. 5.2-5.4) moved to the positions the controller's
capacitive sensor reports and read at the ``gcs`` rig's times. It uses only the rig's
public interface (``move``, ``wait``, ``read``, ``stream``, ``time``).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from calflow.errors import RigError

STAGES = ("nano1d", "nano2d")


class SimulatedInterferometer:
    """A simulated nano rig driven by the ``gcs`` rig's moves and clock (module doc)."""

    def __init__(self, rig: Any) -> None:
        self.rig = rig
        self.sensors = tuple(rig.sensors)
        self.thermometers = tuple(rig.thermometers)

    def _advance(self, time_s: float) -> None:
        """Bring the simulated rig's clock to ``time_s`` (it never goes back)."""
        if time_s > self.rig.time:
            self.rig.wait(time_s - self.rig.time)

    def _positions(self, positions: Mapping[str, Any]) -> dict[str, Any]:
        try:
            return {j: positions[j] for j in self.rig.joints}
        except KeyError as exc:
            raise RigError(f"simulated_interferometer sensor: no position of joint {exc.args[0]!r}") from None

    def moved(self, positions: Mapping[str, float], time_s: float) -> None:
        """The stage was commanded at ``time_s`` and settled at ``positions`` (µm)."""
        self._advance(time_s)
        try:
            self.rig.move({j: float(v) for j, v in self._positions(positions).items()})
        except ValueError as exc:
            raise RigError(f"simulated_interferometer sensor: {exc}") from None

    def read(self, positions: Mapping[str, float], time_s: float) -> dict[str, float]:
        self._positions(positions)
        self._advance(time_s)
        reading = self.rig.read()
        return {k: float(reading[k]) for k in (*self.sensors, *self.thermometers)}

    def stream(self, times: np.ndarray, positions: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Readings at equally spaced ``times`` (s), as the rig's own ``stream`` gives them."""
        self._positions(positions)
        times = np.asarray(times, dtype=float)
        if times.size == 0:
            return {k: np.empty(0) for k in (*self.sensors, *self.thermometers)}
        dt = float(times[1] - times[0]) if times.size > 1 else 1.0
        self._advance(float(times[0]) - dt)
        chunks = list(self.rig.stream(dt * times.size, rate_hz=1.0 / dt))
        return {
            k: np.concatenate([c[k] for c in chunks])[: times.size]
            for k in (*self.sensors, *self.thermometers)
        }

    def record_move(self, positions: Mapping[str, float], times: np.ndarray) -> dict[str, np.ndarray]:
        """The stage, commanded at ``times[0]`` to ``positions`` (µm, where the controller
        settled), read at equally spaced ``times`` (s) from the move's start: the simulated
        rig's own ``record_move`` (its closed loop's step response, Sec. 5.2)."""
        cmd = {j: float(v) for j, v in self._positions(positions).items()}
        times = np.asarray(times, dtype=float)
        self._advance(float(times[0]) if times.size else self.rig.time)
        dt = float(times[1] - times[0]) if times.size > 1 else 1.0
        try:
            chunks = list(self.rig.record_move(cmd, dt * times.size, rate_hz=1.0 / dt))
        except ValueError as exc:
            raise RigError(f"simulated_interferometer sensor: {exc}") from None
        return {
            k: np.concatenate([c[k] for c in chunks])[: times.size] if chunks else np.empty(0)
            for k in (*self.sensors, *self.thermometers)
        }

    def close(self) -> None:
        self.rig.close()


def check_sensor_options(stage: str = "nano1d", **options: Any) -> dict:
    """The sensor's options checked as its stage's (the family's option check), no rig built."""
    from calflow.errors import OptionError
    from calflow.nano.stage import rig as nano_rig

    if stage not in STAGES:
        raise OptionError("stage", f"one of {', '.join(STAGES)}", stage)
    return getattr(nano_rig, f"check_{stage}")(**options)


def simulated_interferometer(stage: str = "nano1d", **options: Any) -> SimulatedInterferometer:
    """Built-in sensor ``simulated_interferometer``: ``stage`` (nano1d | nano2d) and the
    simulated rig's options (seed, world_seed, start_offset_s, physics)."""
    from calflow.nano.stage import rig as nano_rig

    if stage not in STAGES:
        raise ValueError(f"stage must be one of {', '.join(STAGES)}, got {stage!r}")
    return SimulatedInterferometer(getattr(nano_rig, stage)(**options))
