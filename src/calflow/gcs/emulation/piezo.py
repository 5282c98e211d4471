"""An E-727 / E-709-class piezo nanopositioning controller emulation (closed loop, µm).

What differs from the C-863 emulation (:mod:`calflow.gcs.emulation.controller`):

* axes are closed-loop piezo axes in **µm** with an absolute capacitive sensor: nothing to
  reference (``FRF?`` is 1 from power-up), travel ``TMN?``..``TMX?`` (default 0-100 µm);
* motion is the closed loop's response to a ``MOV`` step (no trapezoid; ``VEL`` is
  accepted and reported but does not shape the step): first order,
  ``p(t) = target + (start - target) exp(-(t - t0) / servo_tau)``, or, with
  ``natural_hz`` > 0, the second-order step of natural frequency ``natural_hz`` and damping
  ``damping`` < 1 that the simulated nano rigs' physics uses
  (:func:`calflow.rigs.servo.closed_loop_step`, overshoot ``exp(-pi d / sqrt(1 - d^2))``);
* ``POS?`` is the capacitive sensor: the position plus white sensor noise
  (``sensor_noise``, µm rms), quantised to ``sensor_resolution`` µm. The stage's
  nonlinearity against a length standard is not visible to it: only an external sensor (an
  interferometer, the ``gcs`` rig's sensor plug-in) sees it, as in the lab;
* ``ONT?`` follows the settling rule with the piezo controllers' parameter IDs
  ``0x07000900`` (settling window, µm) and ``0x07000901`` (settling time, s), ``SPA``/``SPA?``;
* the data recorder (:mod:`calflow.gcs.emulation.datarecorder`): ``DRC``/``DRC?``, ``DRT``/``DRT?``,
  ``RTR``/``RTR?``, ``DRL?``, ``DRR?``, ``TNR?``; "current position" points carry the
  same sensor noise as ``POS?``.

Fault injection is the server's (:class:`calflow.gcs.emulation.emulator.Faults`): serve it with
``GCSEmulator(controller=PiezoController(...))`` or :func:`piezo_emulator`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from calflow.gcs.emulation.axis import AxisConfig, SimAxis
from calflow.gcs.emulation.controller import EmulatedController, _Err, _unit
from calflow.gcs.emulation.datarecorder import OPTIONS, DataRecorder, RecorderError, format_array
from calflow.gcs.emulation.emulator import Faults, GCSEmulator
from calflow.gcs.wire.protocol import split_command


@dataclass(frozen=True)
class PiezoAxisConfig(AxisConfig):
    """One closed-loop piezo axis (µm, s). ``velocity``/``accel`` are not used for motion."""

    tmn: float = 0.0
    tmx: float = 100.0
    velocity: float = 1000.0
    max_velocity: float = 1e5
    accel: float = 1e7
    needs_reference: bool = False
    settle_window: float = 0.01
    settle_time: float = 0.01
    servo_tau: float = 0.002
    natural_hz: float = 0.0  # > 0: second-order step (natural frequency, Hz) ...
    damping: float = 0.7  # ... and damping ratio, 0 < damping < 1
    sensor_noise: float = 0.0003
    sensor_resolution: float = 0.0001

    def __post_init__(self) -> None:
        super().__post_init__()
        if not (self.servo_tau > 0 and self.sensor_noise >= 0 and self.sensor_resolution >= 0):
            raise ValueError("piezo axis needs servo_tau > 0, sensor_noise >= 0 and sensor_resolution >= 0")
        if not (self.natural_hz >= 0 and 0 < self.damping < 1):
            raise ValueError("piezo axis needs natural_hz >= 0 and 0 < damping < 1")

    def step(self, since: np.ndarray) -> np.ndarray:
        """Unit step response ``since`` s after the move started (array; 0 before it)."""
        since = np.asarray(since, dtype=float)
        if self.natural_hz > 0:
            from calflow.rigs.servo import closed_loop_step

            return np.asarray(closed_loop_step(since, self.natural_hz, self.damping), dtype=float)
        return np.where(since < 0, 0.0, 1.0 - np.exp(-np.clip(since, 0.0, None) / self.servo_tau))

    def entry_after(self, distance: float, window: float) -> float:
        """Seconds after the move's start from which ``|distance| (1 - step)`` stays within
        ``window``: exact for the first order; for the second order, where the decay
        envelope ``exp(-d w t) / sqrt(1 - d^2)`` enters the window (the step's last crossing
        is at most that late)."""
        d = abs(distance)
        if d <= window:
            return 0.0
        if self.natural_hz > 0:
            zeta, w = self.damping, 2.0 * math.pi * self.natural_hz
            return max(0.0, math.log(d / (window * math.sqrt(1.0 - zeta * zeta))) / (zeta * w))
        return self.servo_tau * math.log(d / window)


class PiezoAxis(SimAxis):
    """A piezo axis: the closed loop's step response, with its history for the data recorder."""

    config: PiezoAxisConfig

    def __init__(self, name: str, config: AxisConfig | None = None) -> None:
        super().__init__(name, config or PiezoAxisConfig())
        p = self.config.start_position
        self._segments: list[tuple[float, float, float]] = [(-math.inf, p, p)]  # (t0, from, to)

    def _along(self, t: np.ndarray, key: int) -> np.ndarray:
        """Position (key 0) or target (key 1) at simulation times ``t`` (array)."""
        t = np.asarray(t, dtype=float)
        out = np.empty_like(t)
        starts = np.array([s[0] for s in self._segments])
        idx = np.searchsorted(starts, t, side="right") - 1
        for i in np.unique(idx):
            t0, a, b = self._segments[max(int(i), 0)]
            m = idx == i
            out[m] = b if key or t0 == -math.inf else a + (b - a) * self.config.step(t[m] - t0)
        return out

    def positions_at(self, t: np.ndarray) -> np.ndarray:
        return self._along(t, 0)

    def targets_at(self, t: np.ndarray) -> np.ndarray:
        return self._along(t, 1)

    def position(self, now: float) -> float:
        return float(self._along(np.array([now]), 0)[0])

    def moving(self, now: float) -> bool:
        return abs(self._target - self.position(now)) > self.settle_window

    def window_entry(self) -> float:
        if self._t0 == -math.inf:
            return self._t0
        return self._t0 + self.config.entry_after(self._target - self._start, self.settle_window)

    def move(self, target: float, now: float, *, extra_time: float = 0.0) -> float:
        start = self.position(now)
        self._start, self._target, self._t0 = start, float(target), now
        self._segments.append((now, start, self._target))
        self._t1 = self.window_entry()
        return self._t1 - now

    def stop(self, now: float) -> None:
        self.move(self.position(now), now)

    def forget_before(self, t: float) -> None:
        """Drop history older than the segment in force at ``t`` (bounded memory)."""
        keep = max(i for i, s in enumerate(self._segments) if s[0] <= t)
        del self._segments[:keep]


class PiezoController(EmulatedController):
    """E-727 / E-709-class GCS 2.0 controller (module doc). ``seed`` fixes the sensor noise."""

    IDN = "(c)2024 calflow, E-727-EMU, 0000000000, 0.1.0"
    AXIS = PiezoAxis
    AXIS_CONFIG = PiezoAxisConfig
    PARAMETERS = {0x07000900: ("settle_window", _unit), 0x07000901: ("settle_time", _unit)}
    READ_ONLY: dict = {}
    HELP = [
        *EmulatedController.HELP,
        "DRC {<RecTableID> <Source> <RecOption>}",
        "DRC?",
        "DRT <RecTableID> <TriggerSource> <Value>",
        "DRT?",
        "RTR <Rate>",
        "RTR?",
        "DRL? [{<RecTableID>}]",
        "DRR? [<StartPoint> [<NumberOfPoints> [{<RecTableID>}]]]",
        "TNR?",
    ]

    def __init__(
        self,
        axes: Any = None,
        *,
        time_scale: float = 1.0,
        seed: int = 0,
        recorder: DataRecorder | None = None,
        idn: str | None = None,
    ) -> None:
        super().__init__(
            axes if axes is not None else {"1": PiezoAxisConfig()}, time_scale=time_scale, idn=idn
        )
        self.seed = int(seed)
        self.recorder = recorder or DataRecorder()
        self._rng = np.random.default_rng([self.seed, 0])
        self._moved: float | None = None  # simulation time of this command's MOV

    def handle(self, line: str) -> list[str] | None:
        name, _ = split_command(line)
        with self.lock:
            self._moved = None
            reply = super().handle(line)
            moved = self._moved is not None
            now = self._moved if moved else self.now()  # a MOV's recording starts with the move
            started = name != "DRT" and self.recorder.command_seen(moved, now)
            if started or moved:  # keep the history a recording can still ask for
                keep = now if self.recorder.start is None else self.recorder.start
                for ax in self.axes.values():
                    ax.forget_before(keep)
            return reply

    @staticmethod
    def _sense(ax: PiezoAxis, values: np.ndarray, rng: np.random.Generator, skip: int = 0) -> np.ndarray:
        """The capacitive sensor's reading of true positions ``values`` (µm); the noise is
        the generator's draws after the first ``skip``."""
        noise = rng.standard_normal(skip + values.size)[skip:]
        v = values + ax.config.sensor_noise * noise
        q = ax.config.sensor_resolution
        return np.round(v / q) * q if q > 0 else v

    def measured(self, ax: PiezoAxis, now: float) -> float:  # type: ignore[override]
        return float(self._sense(ax, np.array([ax.position(now)]), self._rng)[0]) + 0.0

    def _c_MOV(self, args: list[str], now: float) -> None:
        super()._c_MOV(args, now)
        self._moved = now

    # ------------------------------------------------------------------ data recorder
    def _recorder(self, op, *args):
        try:
            return op(*args)
        except RecorderError as exc:
            raise _Err(exc.args[0]) from None

    def _c_DRC(self, args: list[str], now: float) -> None:
        if not args or len(args) % 3:
            raise _Err(1)
        triples = [(self._int(t), s, self._int(o)) for t, s, o in zip(args[0::3], args[1::3], args[2::3])]
        backup = dict(self.recorder.config)
        try:
            for table, source, option in triples:
                self._recorder(self.recorder.configure, table, source, option, set(self.axes))
        except _Err:
            self.recorder.config = backup  # all or nothing (MS249E §8.2)
            raise

    def _q_DRC(self, args: list[str], now: float) -> list[str]:
        tables = [self._int(a) for a in args] or list(range(1, self.recorder.tables + 1))
        out = []
        for t in tables:
            self._recorder(self.recorder.check_table, t)
            source, option = self.recorder.config.get(t, ("0", 0))
            out.append(f"{t}={source} {option}")
        return out

    def _c_DRT(self, args: list[str], now: float) -> None:
        if len(args) != 3:
            raise _Err(1)
        self._recorder(self.recorder.arm, self._int(args[0]), self._int(args[1]))

    def _q_DRT(self, args: list[str], now: float) -> list[str]:
        return [f"0={self.recorder.trigger} 0"]

    def _c_RTR(self, args: list[str], now: float) -> None:
        if len(args) != 1:
            raise _Err(1)
        self._recorder(self.recorder.set_rate, self._int(args[0]))

    def _q_RTR(self, args: list[str], now: float) -> list[str]:
        return [str(self.recorder.rate)]

    def _q_TNR(self, args: list[str], now: float) -> list[str]:
        return [str(self.recorder.tables)]

    def _q_DRL(self, args: list[str], now: float) -> list[str]:
        tables = [self._int(a) for a in args] or sorted(self.recorder.config)
        for t in tables:
            self._recorder(self.recorder.check_table, t)
        n = self.recorder.recorded(now)
        return [f"{t}={n if t in self.recorder.config else 0}" for t in tables]

    def _q_DRR(self, args: list[str], now: float) -> list[str]:
        rec = self.recorder
        n_rec = rec.recorded(now)
        first = self._int(args[0]) if args else 1
        count = self._int(args[1]) if len(args) > 1 else n_rec - first + 1
        tables = [self._int(a) for a in args[2:]] or sorted(t for t, (_, o) in rec.config.items() if o)
        for t in tables:
            self._recorder(rec.check_table, t)
        if (
            first < 1
            or count < 0
            or first + count - 1 > n_rec
            or not tables
            or any(rec.config.get(t, ("", 0))[1] == 0 for t in tables)
        ):
            raise _Err(17)
        times = rec.times(first, count) if count else np.empty(0)
        columns, names = [], []
        for t in tables:
            source, option = rec.config[t]
            ax = self.axes[source]
            if option == 1:
                values = ax.targets_at(times)
            else:  # the sensor's noise of point k is fixed by (seed, recording, table, k)
                rng = np.random.default_rng([self.seed, rec.recordings, t])
                values = self._sense(ax, ax.positions_at(times), rng, skip=first - 1)
            columns.append(values)
            names.append(f"{OPTIONS[option]} of axis {source}")
        return format_array(
            columns,
            names,
            rec.sample_time,
            f"{self.IDN.split(',')[1].strip()} data recorder, {count} points from point {first}",
        )

    @staticmethod
    def _int(text: str) -> int:
        try:
            return int(text)
        except ValueError:
            raise _Err(1) from None


def piezo_emulator(
    axes: Any = None, *, port: int = 0, time_scale: float = 1.0, seed: int = 0, faults: Faults | None = None
) -> GCSEmulator:
    """An (unstarted) TCP emulator of an E-727-class controller on 127.0.0.1."""
    return GCSEmulator(
        port=port, faults=faults, controller=PiezoController(axes, time_scale=time_scale, seed=seed)
    )
