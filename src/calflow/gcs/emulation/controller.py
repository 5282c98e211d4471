"""The emulated controller behind :class:`calflow.gcs.emulation.emulator.GCSEmulator`: GCS 2.0
command semantics (PI MS249E §8), the error register (ERR? returns and clears the last
error, §8.7) and the simulated axes (:mod:`calflow.gcs.emulation.axis`).

Parameters (``SPA {<ItemID> <PamID> <PamValue>}``, ``SPA? [{<ItemID> <PamID>}]``, answered
``<ItemID> <PamID>=<Value>``) are those of the C-863 Mercury (MS249E §9, parameter
overview): 0xE/0xF, the numerator and denominator of the encoder counts per physical unit
(read-only here); 0x36, the settling window in encoder counts; 0x3F, the settling time in
seconds. ``ONT?`` turns true once the position has stayed inside the window for the
settling time (:meth:`calflow.gcs.emulation.axis.SimAxis.on_target`). A subclass lists its own
parameter IDs in ``PARAMETERS`` (the piezo controller: :mod:`calflow.gcs.emulation.piezo`).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Iterable
from typing import Any

from calflow.gcs.emulation.axis import AxisConfig, SimAxis, axis_configs
from calflow.gcs.wire.protocol import NOT_READY, READY, parse_bool, split_command

TruePosition = Callable[[str, float], float]
# parameter ID -> (SimAxis attribute, axis units per parameter unit, or a callable of the axis)
Parameter = tuple[str, Callable[[SimAxis], float]]


def _counts(ax: SimAxis) -> float:
    return 1.0 / ax.config.counts_per_unit


def _unit(ax: SimAxis) -> float:
    return 1.0


def parse_parameter_id(text: str) -> int:
    """A GCS parameter ID, hexadecimal (``0x36``) or decimal (``54``)."""
    return int(text, 16) if text.lower().startswith("0x") else int(text)


class _Err(Exception):
    """A GCS error code raised inside a handler; stored in the error register."""


#: The public name of the error an emulated controller's handler raises (a family's own
#: controller, e.g. a hexapod's, subclasses :class:`EmulatedController` and raises it).
GCSCommandError = _Err


class EmulatedController:
    """Controller state and GCS command semantics, independent of the transport."""

    HELP = [
        "*IDN?",
        "CSV?",
        "SAI? [ALL]",
        "HLP?",
        "ERR?",
        "SVO {<AxisID> <State>}",
        "SVO?",
        "FRF [{<AxisID>}]",
        "FNL [{<AxisID>}]",
        "FPL [{<AxisID>}]",
        "FRF?",
        "VEL {<AxisID> <Velocity>}",
        "VEL?",
        "MOV {<AxisID> <Position>}",
        "MOV?",
        "POS?",
        "ONT?",
        "TMN?",
        "TMX?",
        "SPA {<ItemID> <PamID> <PamValue>}",
        "SPA? [{<ItemID> <PamID>}]",
        "STP",
        "#5",
        "#7",
        "#24",
    ]
    IDN = "(c)2024 calflow, C-863.12-EMU, 0000000000, 0.1.0"
    AXIS: type[SimAxis] = SimAxis
    AXIS_CONFIG: type[AxisConfig] = AxisConfig
    # MS249E parameter overview: settling window (counts) and time (s), counts per unit
    PARAMETERS: dict[int, Parameter] = {0x36: ("settle_window", _counts), 0x3F: ("settle_time", _unit)}
    READ_ONLY: dict[int, Callable[[SimAxis], float]] = {
        0xE: lambda ax: ax.config.counts_per_unit,
        0xF: lambda ax: 1.0,
    }

    def __init__(
        self,
        axes: Any = None,
        *,
        time_scale: float = 1.0,
        true_position: TruePosition | None = None,
        idn: str | None = None,
    ) -> None:
        if not time_scale > 0:
            raise ValueError("time_scale must be > 0")
        self.axes = {n: self.AXIS(n, c) for n, c in axis_configs(axes, self.AXIS_CONFIG).items()}
        self.time_scale, self.true_position = float(time_scale), true_position
        self.idn = idn or self.IDN
        self.error = 0
        self.lock = threading.RLock()
        self._t0 = time.monotonic()

    def now(self) -> float:
        """Simulation time: wall-clock seconds since start times ``time_scale``."""
        return (time.monotonic() - self._t0) * self.time_scale

    # ------------------------------------------------------------------ dispatch
    def handle(self, line: str) -> list[str] | None:
        """Execute one command line; return reply lines, or None if nothing is sent."""
        name, args = split_command(line)
        with self.lock:
            now = self.now()
            try:
                reply = self._axis_query(name, args, now)
                if reply is not None:
                    return reply
                handler = getattr(
                    self,
                    "_q_" + name[:-1].lstrip("*") if name.endswith("?") else "_c_" + name.replace("#", "h"),
                    None,
                )
                if handler is None:
                    raise _Err(2)
                return handler(args, now)
            except _Err as exc:
                self.error = exc.args[0]
                return None

    def _select(self, args: list[str]) -> list[SimAxis]:
        for a in args:
            if a not in self.axes:
                raise _Err(15)
        return [self.axes[a] for a in args] if args else list(self.axes.values())

    def _pairs(self, args: list[str], conv: Callable[[str], Any]) -> list[tuple[SimAxis, Any]]:
        if not args or len(args) % 2:
            raise _Err(1)
        out = []
        for axis, raw in zip(args[0::2], args[1::2]):
            if axis not in self.axes:
                raise _Err(15)
            try:
                value = conv(raw)
            except ValueError:
                raise _Err(1) from None
            if isinstance(value, float) and not math.isfinite(value):
                raise _Err(1)
            out.append((self.axes[axis], value))
        return out

    @staticmethod
    def _answer(axes: Iterable[SimAxis], fn: Callable[[SimAxis], object]) -> list[str]:
        def fmt(v: object) -> str:
            return str(int(v)) if isinstance(v, bool) else f"{v:.6f}" if isinstance(v, float) else str(v)

        return [f"{ax.name}={fmt(fn(ax))}" for ax in axes]

    # ------------------------------------------------------------------ queries
    def _q_IDN(self, args: list[str], now: float) -> list[str]:
        return [self.idn]

    def _q_CSV(self, args: list[str], now: float) -> list[str]:
        return ["2.0"]  # GCS syntax version (MS249E §8, CSV?)

    def _q_SAI(self, args: list[str], now: float) -> list[str]:
        if args and args != ["ALL"]:
            raise _Err(1)
        return list(self.axes)

    def _q_HLP(self, args: list[str], now: float) -> list[str]:
        return ["The following commands are available:", *self.HELP]

    def _q_ERR(self, args: list[str], now: float) -> list[str]:
        code, self.error = self.error, 0
        return [str(code)]

    def _axis_query(self, name: str, args: list[str], now: float) -> list[str] | None:
        """Per-axis queries answering ``axis=value`` (MS249E §8: SVO?, FRF?, POS?, ...)."""
        getters: dict[str, Callable[[SimAxis], object]] = {
            "SVO?": lambda ax: ax.servo,
            "FRF?": lambda ax: (ax.update(now), ax.referenced)[1],
            "VEL?": lambda ax: ax.velocity,
            "MOV?": lambda ax: ax.target(),
            "POS?": lambda ax: self.measured(ax, now),
            "ONT?": lambda ax: ax.on_target(now),
            "TMN?": lambda ax: float(ax.config.tmn),
            "TMX?": lambda ax: float(ax.config.tmx),
        }
        if name not in getters:
            return None
        return self._answer(self._select(args), getters[name])

    def _q_SPA(self, args: list[str], now: float) -> list[str]:
        if len(args) % 2:
            raise _Err(1)
        items = (
            [
                (a, f"0x{p:08X}" if p > 0xFFFF else f"0x{p:X}")
                for a in self.axes
                for p in sorted({**self.READ_ONLY, **self.PARAMETERS})
            ]
            if not args
            else list(zip(args[0::2], args[1::2]))
        )
        out = []
        for axis, raw in items:
            ax, pid = self._parameter(axis, raw)
            if pid in self.PARAMETERS:
                attr, unit = self.PARAMETERS[pid]
                value = getattr(ax, attr) / unit(ax)
            else:
                value = self.READ_ONLY[pid](ax)
            out.append(f"{axis} {raw}={value:.6g}")
        return out

    def _c_SPA(self, args: list[str], now: float) -> None:
        if not args or len(args) % 3:
            raise _Err(1)
        changes = []
        for axis, raw, value in zip(args[0::3], args[1::3], args[2::3]):
            ax, pid = self._parameter(axis, raw)
            if pid not in self.PARAMETERS:
                raise _Err(60)  # PI_CNTR_PARAM_PROTECTION: read-only here
            try:
                v = float(value)
            except ValueError:
                raise _Err(1) from None
            attr, unit = self.PARAMETERS[pid]
            if not math.isfinite(v) or v < 0 or (attr == "settle_window" and v == 0):
                raise _Err(17)  # PI_CNTR_PARAM_OUT_OF_RANGE
            changes.append((ax, attr, v * unit(ax)))
        for ax, attr, v in changes:  # all or nothing (MS249E §8.2)
            setattr(ax, attr, v)

    def _parameter(self, axis: str, raw: str) -> tuple[SimAxis, int]:
        if axis not in self.axes:
            raise _Err(15)
        try:
            pid = parse_parameter_id(raw)
        except ValueError:
            raise _Err(1) from None
        if pid not in self.PARAMETERS and pid not in self.READ_ONLY:
            raise _Err(54)  # PI_CNTR_UNKNOWN_PARAMETER
        return self.axes[axis], pid

    def measured(self, ax: SimAxis, now: float) -> float:
        """``POS?``: what the controller's own sensor reads (the ``true_position`` hook)."""
        hook = self.true_position or (lambda axis, commanded: commanded)
        return float(hook(ax.name, ax.position(now)))

    def _c_h5(self, args: list[str], now: float) -> list[str]:
        mask = sum(1 << i for i, ax in enumerate(self.axes.values()) if ax.moving(now))
        return [f"{mask:X}"]

    def _c_h7(self, args: list[str], now: float) -> list[str]:
        busy = any(ax.referencing(now) for ax in self.axes.values())
        return [NOT_READY if busy else READY]

    # ------------------------------------------------------------------ commands
    def _c_SVO(self, args: list[str], now: float) -> None:
        pairs = self._pairs(args, parse_bool)
        for ax, on in pairs:
            if not on and ax.moving(now):
                ax.stop(now)
            ax.servo = on

    def _c_FRF(self, args: list[str], now: float, where: str = "ref") -> None:
        """FRF: to the reference switch; FNL/FPL: to the negative/positive limit."""
        axes = self._select(args)
        if any(not ax.servo for ax in axes):
            raise _Err(5)
        for ax in axes:
            ax.reference(now, {"ref": None, "neg": ax.config.tmn, "pos": ax.config.tmx}[where])

    def _c_FNL(self, args: list[str], now: float) -> None:
        self._c_FRF(args, now, "neg")

    def _c_FPL(self, args: list[str], now: float) -> None:
        self._c_FRF(args, now, "pos")

    def _c_VEL(self, args: list[str], now: float) -> None:
        pairs = self._pairs(args, float)
        if any(not 0 < v <= ax.config.max_velocity for ax, v in pairs):
            raise _Err(8)
        for ax, v in pairs:
            ax.velocity = v

    def _c_MOV(self, args: list[str], now: float) -> None:
        pairs = self._pairs(args, float)
        if any(not ax.servo or not ax.referenced or ax.referencing(now) for ax, _ in pairs):
            raise _Err(5)
        if any(not ax.within_limits(v) for ax, v in pairs):
            raise _Err(7)
        for ax, v in pairs:
            ax.move(v, now)

    def _c_STP(self, args: list[str], now: float) -> None:
        if args:
            raise _Err(1)
        for ax in self.axes.values():
            ax.stop(now)
        self.error = 10  # MS249E: #24 and STP set error 10, PI_CNTR_STOP

    _c_h24 = _c_STP
