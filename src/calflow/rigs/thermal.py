"""Room-temperature profiles and first-order thermal lags for the simulated nano rigs.

Times are virtual seconds of *profile time* (the campaign clock: a rig started with
``start_offset_s = 37 * 3600`` reads the profile from hour 37). Temperatures are degC.

Profiles (all deterministic given ``seed``, vectorised over time):

* ``"constant"`` – the base temperature, exactly.
* ``"metrology"`` – the temperature-controlled metrology room of Sec. 5.3.3 / Fig. 5.10:
  slow wander (periods ~0.7 h to ~1.2 days, random phases) that stays within
  ``±amplitude_c`` (default 0.05 °C) of the base temperature, by construction.
* ``"lab5day"`` – the ordinary laboratory of Fig. 5.19: regular daily swings with a
  peak-to-valley of ``daily_swing_c`` (default 0.25 °C, within 0.2–0.3 °C day to day) for
  the first ``step_start_h`` (default 50 h), then a smooth change of ``step_c``
  (default -1.1 °C, a cooling) over ``step_duration_h`` (default 12 h) while the daily
  swings continue, so the temperature range of the latter days is ~1.3 °C as in
  Fig. 5.19. These describe the room (the input), taken from the text of Sec. 5.3.3;
  what the stage does with it is the thermal network's business.

:class:`LinearBank` integrates any linear network driven by the room (the lumped thermal
network of the nano family's rigs) exactly for a
piecewise-linear input on a fixed grid, interpolated linearly between grid points;
:class:`LagBank` is its special case of independent first-order lags. The grid is anchored in profile time (not rig time), so two rigs started at
different offsets see the same structure temperatures at the same campaign time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ["PROFILES", "RoomProfile", "room_profile", "LinearBank", "LagBank"]

PROFILES = ("constant", "metrology", "lab5day")

_DEFAULTS: dict[str, dict[str, float]] = {
    "constant": {},
    "metrology": {"amplitude_c": 0.05},
    "lab5day": {
        "daily_swing_c": 0.25,  # peak-to-valley of one day's swing (Fig. 5.19: 0.2-0.3 °C)
        "swing_variation": 0.12,  # relative day-to-day variation of the swing
        "peak_hour": 15.0,  # hour of the day (profile time) of the warmest moment
        "step_c": -1.1,  # change after the regular period (+ swings: 1.3 °C range, Fig. 5.19)
        "step_start_h": 50.0,
        "step_duration_h": 12.0,
        "wander_c": 0.01,  # small irregular wander on top
    },
}

# Periods (h) of the components of the metrology-room wander.
_METROLOGY_PERIODS_H = (0.7, 1.9, 4.3, 9.7, 29.0)
_WANDER_PERIODS_H = (2.3, 6.1, 17.0)


@dataclass(frozen=True)
class RoomProfile:
    """Room temperature T(t) in degC at profile time t in seconds (vectorised).

    Build with :func:`room_profile`; ``describe()`` gives a JSON-serialisable summary.
    """

    name: str
    base_c: float
    seed: int
    params: dict = field(default_factory=dict)
    _amps: np.ndarray = field(default=None, repr=False, compare=False)  # type: ignore[assignment]
    _phases: np.ndarray = field(default=None, repr=False, compare=False)  # type: ignore[assignment]

    def __call__(self, t_s):
        t = np.asarray(t_s, dtype=float)
        if self.name == "constant":
            return np.full(t.shape, self.base_c) if t.ndim else float(self.base_c)
        t_h = t / 3600.0
        if self.name == "metrology":
            dev = _sines(t_h, _METROLOGY_PERIODS_H, self._amps, self._phases)
            out = self.base_c + dev
        else:  # lab5day
            p = self.params
            n = len(_WANDER_PERIODS_H)
            wander = _sines(t_h, _WANDER_PERIODS_H, self._amps[:n], self._phases[:n])
            # day-to-day variation of the swing amplitude: a slow (period 3.1 d) modulation
            mod = 1.0 + p["swing_variation"] * math.sqrt(2.0) * np.sin(
                2 * np.pi * t_h / 74.0 + self._phases[n]
            )
            theta = 2 * np.pi * (t_h - p["peak_hour"] + 6.0) / 24.0
            daily = 0.5 * p["daily_swing_c"] * mod * np.sin(theta)
            s = np.clip((t_h - p["step_start_h"]) / max(p["step_duration_h"], 1e-9), 0.0, 1.0)
            step = p["step_c"] * 0.5 * (1.0 - np.cos(np.pi * s))
            out = self.base_c + daily + wander + step
        return out if t.ndim else float(out)

    def describe(self) -> dict:
        """JSON-serialisable description (name, base, seed, parameters)."""
        return {
            "name": self.name,
            "base_c": float(self.base_c),
            "seed": int(self.seed),
            "params": {k: float(v) for k, v in self.params.items()},
        }


def _sines(t_h, periods_h, amps, phases):
    out = np.zeros(np.shape(t_h))
    for period, amp, phase in zip(periods_h, amps, phases):
        out = out + amp * np.sin(2 * np.pi * t_h / period + phase)
    return out


def room_profile(name: str, *, base_c: float = 20.5, seed: int = 0, **params) -> RoomProfile:
    """Build the room-temperature profile ``name`` (one of :data:`PROFILES`).

    ``base_c`` (degC) is the temperature the profile starts from / wanders around;
    ``seed`` fixes the random phases and weights (same seed, same profile). Extra
    keyword ``params`` override the profile's defaults (see the module docstring);
    an unknown parameter raises ``ValueError`` naming it.
    """
    if name not in PROFILES:
        raise ValueError(f"unknown temperature profile {name!r}; expected one of {PROFILES}")
    merged = dict(_DEFAULTS[name])
    for key, value in params.items():
        if key not in merged:
            raise ValueError(
                f"unknown parameter {key!r} for temperature profile {name!r}; "
                f"expected one of {sorted(merged)}"
            )
        merged[key] = float(value)
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 5_19]))
    amps = phases = np.zeros(0)
    if name == "metrology":
        # Dirichlet weights summing to 95 % of the amplitude: |dev| < amplitude always.
        w = rng.dirichlet(np.ones(len(_METROLOGY_PERIODS_H)))
        amps = 0.95 * merged["amplitude_c"] * w
        phases = rng.uniform(0, 2 * np.pi, len(_METROLOGY_PERIODS_H))
    elif name == "lab5day":
        n = len(_WANDER_PERIODS_H)
        amps = merged["wander_c"] * rng.dirichlet(np.ones(n))
        phases = rng.uniform(0, 2 * np.pi, n + 1)
    return RoomProfile(name, float(base_c), int(seed), merged, amps, phases)


class LinearBank:
    """States of a linear network ``dx/dt = A x + b T_room(t)`` on a fixed time grid.

    ``A`` (1/s, n x n) and ``b`` (1/s, n) describe the network; the room profile drives it.
    The state is integrated exactly for a room temperature that is linear between grid
    points (first-order hold, step ``dt_s``, default 30 s: the matrix exponential of the
    augmented system, Franklin, Powell & Workman, *Digital Control of Dynamic Systems*,
    Sec. 6.3), starting in equilibrium with the room ``warmup_s`` before ``min(0,
    earliest_s)`` (every node of a network that conducts to the room settles at the room's
    temperature). Values between grid points are interpolated linearly. The grid is anchored
    in profile time and extended lazily in whole days, so evaluation is cheap and
    independent of the order of queries. ``bank(t)`` returns ``t.shape + (n,)`` in degC.
    """

    _BLOCK = 2880  # grid points added per extension (one day at 30 s)

    def __init__(self, room, A, b, *, dt_s: float = 30.0, earliest_s: float = 0.0, warmup_s: float = 86400.0):
        from scipy.linalg import expm

        A = np.atleast_2d(np.asarray(A, dtype=float))
        b = np.asarray(b, dtype=float).reshape(-1)
        n = A.shape[0]
        if A.shape != (n, n) or b.size != n or not np.all(np.isfinite(A)) or not np.all(np.isfinite(b)):
            raise ValueError("LinearBank needs a finite square A (n x n) and b of n values")
        self.room = room
        self.dt = float(dt_s)
        self.t0 = math.floor((min(0.0, float(earliest_s)) - float(warmup_s)) / 3600.0) * 3600.0
        m = np.zeros((n + 2, n + 2))
        m[:n, :n], m[:n, n], m[n, n + 1] = A * self.dt, b * self.dt, 1.0
        e = expm(m)
        # x[k+1] = phi x[k] + g0 u[k] + g1 (u[k+1] - u[k])
        self._phi, self._g0, self._g1 = e[:n, :n].T.copy(), e[:n, n].copy(), e[:n, n + 1].copy()
        lam, V = np.linalg.eig(self._phi)
        ok = np.all(np.abs(lam.imag) < 1e-12) and np.linalg.cond(V) < 1e8
        self._modes = (lam.real, V.real, np.linalg.inv(V.real)) if ok else None
        u0 = float(room(self.t0))
        self._u_last = u0
        self._y = np.full((1, n), u0)

    def _run(self, x0: np.ndarray, drive: np.ndarray) -> np.ndarray:
        """States after each step of ``x[k+1] = x[k] phi + drive[k]`` (row vectors): one scalar
        recursion per mode of phi (scipy.signal.lfilter), or step by step if phi has no real
        well-conditioned eigenbasis."""
        if self._modes is not None:
            from scipy.signal import lfilter  # here, not at import: scipy.signal costs ~1 s to import

            lam, V, Vi = self._modes
            m0, dm = x0 @ V, drive @ V
            out = np.empty_like(dm)
            for i, a in enumerate(lam):
                out[:, i], _ = lfilter([1.0], [1.0, -a], dm[:, i], zi=[a * m0[i]])
            return out @ Vi
        block = np.empty_like(drive)
        x = x0
        for k in range(drive.shape[0]):
            x = x @ self._phi + drive[k]
            block[k] = x
        return block

    @property
    def t_end(self) -> float:
        """Last profile time (s) covered by the grid."""
        return self.t0 + (self._y.shape[0] - 1) * self.dt

    def _extend_to(self, t_max: float) -> None:
        while self.t_end < t_max:
            n0 = self._y.shape[0]
            u = np.asarray(self.room(self.t0 + self.dt * np.arange(n0, n0 + self._BLOCK)), dtype=float)
            du = np.diff(np.concatenate(([self._u_last], u)))
            drive = np.outer(u - du, self._g0) + np.outer(du, self._g1)  # u[k] g0 + (u[k+1]-u[k]) g1
            block = self._run(self._y[-1], drive)
            self._y = np.concatenate((self._y, block))
            self._u_last = float(u[-1])

    def __call__(self, t_s) -> np.ndarray:
        t = np.asarray(t_s, dtype=float)
        self._extend_to(float(np.max(t)) + self.dt)
        pos = np.clip((t - self.t0) / self.dt, 0.0, None)
        i = np.minimum(pos.astype(np.int64), self._y.shape[0] - 2)
        w = (pos - i)[..., None]
        return self._y[i] * (1.0 - w) + self._y[i + 1] * w

    def at(self, t_s: float) -> np.ndarray:
        """Fast scalar evaluation: the node temperatures (degC) at one profile time."""
        t = float(t_s)
        if t + self.dt > self.t_end:
            self._extend_to(t + self.dt)
        pos = max((t - self.t0) / self.dt, 0.0)
        i = int(pos)
        w = pos - i
        return self._y[i] * (1.0 - w) + self._y[i + 1] * w


class LagBank(LinearBank):
    """Independent first-order lags ``dT_k/dt = (T_room(t) - T_k) / tau_k`` of a room profile
    (``taus_s`` in s), starting in equilibrium ``warmup_taus`` time constants early."""

    def __init__(
        self, room, taus_s, *, dt_s: float = 30.0, earliest_s: float = 0.0, warmup_taus: float = 12.0
    ):
        taus = np.asarray(taus_s, dtype=float)
        if taus.ndim != 1 or not np.all(taus > 0):
            raise ValueError("LagBank time constants must be a 1-D array of positive seconds")
        self.taus = taus
        super().__init__(
            room,
            np.diag(-1.0 / taus),
            1.0 / taus,
            dt_s=dt_s,
            earliest_s=earliest_s,
            warmup_s=warmup_taus * float(taus.max()),
        )
