"""Simulated axis motion model used by the GCS emulator.

Models what a GCS 2.0 controller (PI MS249E, C-863.12 User Manual v1.2.1, §8) exposes per
axis: soft travel limits (``TMN?``/``TMX?``), velocity (``VEL``), servo state (``SVO``),
referenced state (``FRF``/``FNL``/``FPL``, answered by ``FRF?``), commanded target
(``MOV``/``MOV?``), trajectory position and on-target state (``POS?``/``ONT?``), and the
moving / referencing flags behind ``#5`` and ``#7``.

On target (``ONT?``) follows the controllers' settling rule (MS249E §8, ONT?; parameters
"Settling Window" and "Settling Time"): the axis is on target once its position has stayed
within ``settle_window`` (axis units) of the target for ``settle_time`` seconds, with the
servo on. Both are per axis and can be changed at run time (``SPA``, see
:mod:`calflow.gcs.emulation.controller`).

Motion follows a symmetric trapezoidal velocity profile (acceleration ``accel``, cruise
velocity ``VEL``), so the move time is ``d/v + v/a`` for long moves and ``2*sqrt(d/a)`` for
short ones. All times are *simulation* seconds supplied by the caller; the emulator maps
wall-clock time to simulation time with its ``time_scale`` factor so tests run fast.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

from calflow.gcs.wire.protocol import check_axis


@dataclass(frozen=True)
class AxisConfig:
    """Static description of one simulated axis (defaults: a PI M-111-like stage in mm).

    ``ref_position`` is where the reference switch is (FRF moves there and sets the
    position counter); ``start_position`` is the counter value at power-up. Set
    ``needs_reference=False`` for stages with absolute sensors (e.g. a P-625 piezo stage),
    which are referenced from the start.
    """

    tmn: float = -7.5
    tmx: float = 7.5
    velocity: float = 1.5
    max_velocity: float = 2.0
    accel: float = 10.0
    ref_position: float = 0.0
    start_position: float = 0.0
    ref_overhead: float = 0.3
    needs_reference: bool = True
    servo: bool = False
    settle_window: float = 0.0005
    settle_time: float = 0.01
    counts_per_unit: float = 20000.0  # encoder: 50 nm counts on a stage in mm (Table 4.1)

    def __post_init__(self) -> None:
        if not (self.settle_window > 0 and self.settle_time >= 0 and self.counts_per_unit > 0):
            raise ValueError(
                "axis needs settle_window > 0, settle_time >= 0 and counts_per_unit > 0, "
                f"got {self.settle_window}, {self.settle_time}, {self.counts_per_unit}"
            )
        if not self.tmn < self.tmx:
            raise ValueError(f"axis travel limits need tmn < tmx, got {self.tmn}, {self.tmx}")
        if not (0 < self.velocity <= self.max_velocity and self.accel > 0):
            raise ValueError("axis needs 0 < velocity <= max_velocity and accel > 0")
        if not self.tmn <= self.ref_position <= self.tmx:
            raise ValueError(f"ref_position {self.ref_position} outside [{self.tmn}, {self.tmx}]")

    @classmethod
    def from_mapping(cls, data: dict[str, Any]) -> AxisConfig:
        known = {f.name for f in fields(cls)}
        unknown = set(data) - known
        if unknown:
            raise ValueError(f"unknown axis setting(s) {sorted(unknown)}; known: {sorted(known)}")
        return cls(**data)


def axis_configs(axes: Any, kind: type[AxisConfig] = AxisConfig) -> dict[str, AxisConfig]:
    """Normalise an axes spec: None, "1,2", ["1", "2"], or {name: ``kind`` | dict}."""
    if axes is None:
        return {"1": kind()}
    if isinstance(axes, str):
        axes = [a.strip() for a in axes.split(",") if a.strip()]
    if isinstance(axes, Mapping):
        items = [
            (k, v if isinstance(v, AxisConfig) else kind.from_mapping(dict(v or {}))) for k, v in axes.items()
        ]
    else:
        items = [(k, kind()) for k in axes]
    if not items:
        raise ValueError("the emulator needs at least one axis")
    return {check_axis(k): cfg for k, cfg in items}


def profile_time(distance: float, velocity: float, accel: float) -> float:
    """Duration of a trapezoidal (or triangular) move over ``distance``."""
    d = abs(distance)
    if d == 0.0:
        return 0.0
    if d >= velocity * velocity / accel:
        return d / velocity + velocity / accel
    return 2.0 * math.sqrt(d / accel)


def profile_distance(t: float, distance: float, velocity: float, accel: float) -> float:
    """Distance covered after ``t`` seconds of a move over ``distance`` (same sign as it)."""
    d, sign = abs(distance), math.copysign(1.0, distance)
    total = profile_time(d, velocity, accel)
    if t <= 0.0:
        return 0.0
    if t >= total:
        return distance
    v_peak = min(velocity, math.sqrt(d * accel))
    t_acc = v_peak / accel
    if t < t_acc:
        s = 0.5 * accel * t * t
    elif t <= total - t_acc:
        s = 0.5 * accel * t_acc * t_acc + v_peak * (t - t_acc)
    else:
        rest = total - t
        s = d - 0.5 * accel * rest * rest
    return sign * min(max(s, 0.0), d)


class SimAxis:
    """State and trajectory of one axis. Not thread-safe: the emulator holds its lock."""

    def __init__(self, name: str, config: AxisConfig | None = None) -> None:
        self.name = name
        self.config = config or AxisConfig()
        self.servo = self.config.servo
        self.referenced = not self.config.needs_reference
        self.velocity = self.config.velocity
        self.settle_window = self.config.settle_window
        self.settle_time = self.config.settle_time
        self._start = self._target = self.config.start_position
        self._t0 = self._t1 = -math.inf  # at rest since power-up: on target
        self._referencing = False

    # ---------------------------------------------------------------- state queries
    def update(self, now: float) -> None:
        """Finish a reference move whose trajectory has ended."""
        if self._referencing and now >= self._t1:
            self._referencing = False
            self.referenced = True

    def position(self, now: float) -> float:
        """Commanded trajectory position at simulation time ``now``."""
        if now >= self._t1:
            return self._target
        return self._start + profile_distance(
            now - self._t0, self._target - self._start, self._move_velocity, self.config.accel
        )

    def target(self) -> float:
        return self._target

    def moving(self, now: float) -> bool:
        self.update(now)
        return now < self._t1 or self._referencing

    def referencing(self, now: float) -> bool:
        self.update(now)
        return self._referencing

    def window_entry(self) -> float:
        """Simulation time at which the position entered the settle window for good.

        The trapezoidal profile approaches its target monotonically, so the entry is the
        root of ``|target - position(t)| = settle_window`` on the move, found by bisection.
        """
        if abs(self._target - self._start) <= self.settle_window:
            return self._t0
        lo, hi = self._t0, self._t1
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            if abs(self._target - self.position(mid)) <= self.settle_window:
                hi = mid
            else:
                lo = mid
        return hi

    def on_target(self, now: float) -> bool:
        """ONT?: not referencing, inside the window for ``settle_time`` s (at power-up: on)."""
        if self.referencing(now):
            return False
        return now >= self.window_entry() + self.settle_time

    def within_limits(self, value: float) -> bool:
        return self.config.tmn <= value <= self.config.tmx

    # ---------------------------------------------------------------- actions
    def move(self, target: float, now: float, *, extra_time: float = 0.0) -> float:
        """Start a move to ``target`` (re-planned from the current position); returns duration."""
        self.update(now)
        start = self.position(now)
        self._move_velocity = self.velocity
        self._start, self._target, self._t0 = start, float(target), now
        duration = profile_time(self._target - start, self.velocity, self.config.accel)
        self._t1 = now + duration + extra_time
        if extra_time:  # searching the switch: hold still first, then travel
            self._t0 = now + extra_time
        return duration + extra_time

    def reference(self, now: float, where: float | None = None) -> float:
        """Start a reference move (FRF: to the switch; FNL/FPL: to a limit)."""
        dest = self.config.ref_position if where is None else where
        duration = self.move(dest, now, extra_time=self.config.ref_overhead)
        self.referenced, self._referencing = False, True
        return duration

    def stop(self, now: float) -> None:
        """Halt at the current position (#24/STP, or servo switched off); aborts referencing."""
        here = self.position(now)
        self._start = self._target = here
        self._t0 = self._t1 = now
        if self._referencing:
            self._referencing = False
            self.referenced = False

    _move_velocity: float = AxisConfig.velocity
