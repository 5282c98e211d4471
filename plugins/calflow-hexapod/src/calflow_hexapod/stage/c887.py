"""A C-887-class hexapod controller emulation for calflow's GCS 2.0 emulator.

What differs from the single-axis C-863 emulation (:mod:`calflow.gcs.emulation.controller`):

* six pose axes ``X Y Z`` (mm) and ``U V W`` (degree) of one platform, with the H-811.I2
  datasheet travel per axis (``TMN?``/``TMX?``); the hexapod is referenced as a whole
  (``FRF`` with any axes references all six; ``FRF?`` answers for each);
* ``MOV`` checks the per-axis travel *and* the legs' stroke at the whole target pose (the
  axes not named keep their targets): a target outside either is refused with GCS error 7
  (PI_CNTR_POS_OUT_OF_LIMITS) and nothing moves (MS249E §8.2: a line that cannot be fully
  executed is not executed at all); servo off or not referenced: error 5;
* ``POS?`` is **encoder-true**: the controller turns the trajectory's pose into six leg
  lengths through its own nominal geometry about the current pivot
  (:func:`calflow_hexapod.models.kinematics.inverse`), holds each leg's encoder at a whole count of
  ``resolution_um``, and reports the pose its nominal forward kinematics computes from those
  encoder lengths (:func:`calflow_hexapod.models.kinematics.forward`). It sees none of the real
  hexapod's joint, leg or instrument errors — only an external instrument does;
* ``SPI {<R|S|T> <mm>}`` / ``SPI? [{<R|S|T>}]``: the pivot point in the platform frame
  (PI MS207E, "pivot point"; the coordinates R, S, T of the C-887's GCS). Rotations in
  ``MOV`` are about it. Setting it while U, V or W is not 0 is refused with error 9
  (PI_CNTR_SET_PIVOT_NOT_POSSIBLE); a coordinate other than R, S, T is a syntax error (1);
* ``VLS <v>`` / ``VLS?``: the platform's system velocity (mm/s, and degree/s for U V W), out
  of range: error 8 (PI_CNTR_VEL_OUT_OF_LIMITS);
* ``ONT?`` is the base's settling rule per axis; ``#5`` / ``#7`` / ``STP`` / ``#24``,
  ``SVO``, ``VEL``, ``ERR?``, ``SPA`` as the base controller.

Serve it with ``GCSEmulator(controller=HexapodController(...))`` or
:func:`calflow_hexapod.stage.emulate.campaign_emulator`. pipython's GCS dialect for hexapods
(``MOV``, ``qPOS``, ``qONT``, ``SPI``, ``qSPI``, ``FRF``, ``qFRF``) maps one to one onto these
commands.
"""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np

from calflow.gcs.emulation.axis import AxisConfig, SimAxis
from calflow.gcs.emulation.controller import EmulatedController
from calflow.gcs.emulation.controller import GCSCommandError as _Err
from calflow_hexapod.models.geometry import AXES, H811_TRAVEL, Geometry, h811
from calflow_hexapod.models.kinematics import forward, inverse
from calflow_hexapod.stage.workspace import leg_stroke_um

AXIS_IDS = tuple(a.upper() for a in AXES)  # the C-887's axis identifiers
SCALE = {
    "x": 1000.0,
    "y": 1000.0,
    "z": 1000.0,
    "u": 1.0,
    "v": 1.0,
    "w": 1.0,
}  # µm or degree per unit
PIVOT = ("R", "S", "T")
PIVOT_LIMIT_MM = 1000.0


def axis_configs(travel=H811_TRAVEL, velocity_mm_s: float = 5.0, velocity_deg_s: float = 5.0) -> dict:
    """One :class:`AxisConfig` per axis: ± ``travel`` (µm, degree → mm, degree), referenced at
    0, velocities of the H-811.I2 class (max. 10 mm/s), settling window of 2 encoder counts."""
    out = {}
    for k, (ax, name) in enumerate(zip(AXES, AXIS_IDS)):
        lim = float(travel[k]) / SCALE[ax]
        v = velocity_mm_s if k < 3 else velocity_deg_s
        out[name] = AxisConfig(
            tmn=-lim,
            tmx=lim,
            velocity=v,
            max_velocity=2 * v,
            accel=10 * v,
            ref_position=0.0,
            needs_reference=True,
            settle_window=1e-5,
            settle_time=0.01,
            counts_per_unit=1e5,  # 10 nm or 10 µ° counts of the pose axes
        )
    return out


class HexapodController(EmulatedController):
    """The C-887-class controller: GCS semantics of the six pose axes (module docstring)."""

    HELP: ClassVar[list[str]] = [
        *EmulatedController.HELP,
        "SPI {<PPCoordinate> <PPValue>}",
        "SPI? [{<PPCoordinate>}]",
        "VLS <SystemVelocity>",
        "VLS?",
    ]
    IDN = "(c)2024 calflow, C-887.52-EMU, 0000000000, 0.1.0"

    def __init__(
        self,
        *,
        time_scale: float = 1.0,
        geometry: Geometry | None = None,
        resolution_um: float = 0.005,
        travel=H811_TRAVEL,
        velocity_mm_s: float = 5.0,
        velocity_deg_s: float = 5.0,
        idn: str | None = None,
    ) -> None:
        super().__init__(
            axis_configs(travel, velocity_mm_s, velocity_deg_s),
            time_scale=time_scale,
            idn=idn,
        )
        self.nominal = h811() if geometry is None else geometry
        self.resolution_um = float(resolution_um)
        self.pivot_um = np.zeros(3)
        self._cache: tuple[float, np.ndarray] | None = None

    # ------------------------------------------------------------------ the legs
    def geometry(self) -> Geometry:
        """The controller's nominal geometry about its current pivot."""
        return self.nominal.with_pivot(self.pivot_um)

    def encoder_legs(self, pose) -> np.ndarray:
        """Encoder leg lengths (µm) the servo holds for a pose (µm, degree): whole counts of
        ``resolution_um`` of each leg's stroke from its zero-pose length."""
        legs = inverse(self.geometry(), np.asarray(pose, dtype=float))
        if self.resolution_um <= 0:
            return legs
        l0 = self.nominal.zero_lengths
        return l0 + np.round((legs - l0) / self.resolution_um) * self.resolution_um

    def _pose(self, now: float, targets: bool = False) -> np.ndarray:
        """The trajectory's pose (µm, degree) at ``now``, or the axes' targets."""
        return np.array(
            [
                (ax.target() if targets else ax.position(now)) * SCALE[name.lower()]
                for name, ax in self.axes.items()
            ]
        )

    def encoder_pose(self, now: float) -> np.ndarray:
        """What ``POS?`` reports (µm, degree): the nominal forward kinematics of the encoders."""
        if self._cache is None or self._cache[0] != now:
            cmd = self._pose(now)
            self._cache = (
                now,
                forward(self.geometry(), self.encoder_legs(cmd), start=cmd),
            )
        return self._cache[1]

    def measured(self, ax: SimAxis, now: float) -> float:
        k = AXIS_IDS.index(ax.name)
        return float(self.encoder_pose(now)[k]) / SCALE[AXES[k]]

    def reachable(self, pose) -> bool:
        """The pose (µm, degree, about the pivot) keeps every leg within its stroke."""
        legs = inverse(self.geometry(), np.asarray(pose, dtype=float)) - self.nominal.zero_lengths
        return bool(np.all(np.abs(legs) <= leg_stroke_um() + 1e-9))

    # ------------------------------------------------------------------ commands
    def _c_FRF(self, args: list[str], now: float, where: str = "ref") -> None:
        """FRF: the legs are referenced together; any named axis references all six."""
        self._select(args)  # unknown axes: error 15
        if where != "ref":
            raise _Err(2)  # FNL/FPL: no limit-switch referencing on a hexapod
        if any(not ax.servo for ax in self.axes.values()):
            raise _Err(5)
        self._cache = None
        for ax in self.axes.values():
            ax.reference(now)

    def _c_MOV(self, args: list[str], now: float) -> None:
        pairs = self._pairs(args, float)
        if any(not ax.servo or not ax.referenced or ax.referencing(now) for ax in self.axes.values()):
            raise _Err(5)
        if any(not ax.within_limits(v) for ax, v in pairs):
            raise _Err(7)
        target = self._pose(now, targets=True)
        for ax, v in pairs:
            k = AXIS_IDS.index(ax.name)
            target[k] = v * SCALE[AXES[k]]
        if not self.reachable(target):
            raise _Err(7)
        self._cache = None
        for ax, v in pairs:
            ax.move(v, now)

    def _q_SPI(self, args: list[str], now: float) -> list[str]:
        names = [a.upper() for a in args] or list(PIVOT)
        if any(n not in PIVOT for n in names):
            raise _Err(1)
        return [f"{n}={self.pivot_um[PIVOT.index(n)] / 1000.0:.6f}" for n in names]

    def _c_SPI(self, args: list[str], now: float) -> None:
        if not args or len(args) % 2:
            raise _Err(1)
        new = self.pivot_um.copy()
        for name, raw in zip(args[0::2], args[1::2]):
            if name.upper() not in PIVOT:
                raise _Err(1)
            try:
                value = float(raw)
            except ValueError:
                raise _Err(1) from None
            if not math.isfinite(value):
                raise _Err(1)
            if abs(value) > PIVOT_LIMIT_MM:
                raise _Err(17)
            new[PIVOT.index(name.upper())] = value * 1000.0
        rotated = [self.axes[n] for n in ("U", "V", "W")]
        if any(ax.target() != 0.0 or ax.position(now) != 0.0 for ax in rotated):
            raise _Err(9)
        self._cache = None
        self.pivot_um = new

    def _q_VLS(self, args: list[str], now: float) -> list[str]:
        if args:
            raise _Err(1)
        return [f"{self.axes['X'].velocity:.6f}"]

    def _c_VLS(self, args: list[str], now: float) -> None:
        """VLS: the platform's system velocity (mm/s for X Y Z, the same number in degree/s for
        U V W), within every axis's maximum; error 8 otherwise."""
        if len(args) != 1:
            raise _Err(1)
        try:
            v = float(args[0])
        except ValueError:
            raise _Err(1) from None
        if not (math.isfinite(v) and all(0 < v <= ax.config.max_velocity for ax in self.axes.values())):
            raise _Err(8)
        for ax in self.axes.values():
            ax.velocity = v
