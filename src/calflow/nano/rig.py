"""Simulated 1-DoF and 2-DoF nanopositioning rigs (thesis Chapter 5, Sec. 5.2-5.4).

Both rigs follow the rig protocol of DESIGN.md (``move``/``wait``/``read``/``close``) on a
virtual clock, plus ``stream`` (raw high-rate samples of a dwell), ``truth()`` and
``true_position()`` for tests and reports. Lengths in um, temperatures in degC, time in s.

Physics of a reading of sensor k (richer than Eq. 5.1-5.3, 5.6 and 5.10 on purpose):

    meas_k = geometry_k(command, approach direction)                 (Fig. 5.1, Sec. 5.4)
           + c_stage_k (1 + kappa s_k) (T_stage - T_ref) + c_frame_k (T_frame - T_ref)
           + walk_k(t) + creep_k(t)          (slow drift that no thermocouple explains)
           + repeatability offset drawn at each move (~35 nm ISO RP, Sec. 5.3.3)
           + settling tail of the last move + white interferometer noise (Table 3.4)
    quantised to the interferometer resolution (0.3 nm, Sec. 3.5.2).

T_stage and T_frame are first-order lags of the room (profiles of Fig. 5.10 / 5.19, see
``calflow.rigs.thermal``) with time constants that no thermocouple shares; thermocouple j
reads ``T_ref + gain_j (lag_j - T_ref) + offset_j`` + noise (~5 mK), quantised to 1 mK.
``s_k`` is the normalised position along the axis, so expansion grows with distance from
the fixed end. The world (room, walk, creep) is fixed by ``world_seed`` and anchored in
campaign time; the noise ``seed`` drives only noise and per-move repeatability.
"""

from __future__ import annotations

import math
from typing import Iterator, Mapping

import numpy as np

from calflow.errors import RigError
from calflow.nano.rig_options import _COMMON, _Walk, check_options
from calflow.rigs.thermal import LagBank, room_profile

__all__ = ["Nano1DRig", "Nano2DRig", "nano1d", "nano2d"]



class _NanoRig:
    """Common machinery of the nano rigs: options, virtual clock, noise, thermal state."""

    joints: tuple[str, ...] = ()
    replayable = True  # deterministic given its seeds: acquisition may replay it to resume
    sensors: tuple[str, ...] = ("meas_x", "meas_y")
    _NAME = ""
    _EXTRA: dict = {}
    _REP_FACTOR: tuple[float, ...] = ()  # repeatability per sensor, relative
    _DRIFT_FACTOR: tuple[float, ...] = ()  # walk and creep per sensor, relative

    def __init__(self, **options):
        o = check_options(self._NAME, {**_COMMON, **self._EXTRA}, len(self.sensors), options)
        n_s, n_tc = len(self.sensors), len(o["thermocouple_tau_h"])
        self.options = o
        self.thermometers = tuple(f"T{j + 1}" for j in range(n_tc))
        self.room = room_profile(o["profile"], base_c=o["base_temperature_c"],
                                 seed=o["world_seed"], **o["profile_params"])
        taus = [o["stage_tau_h"], o["frame_tau_h"], *o["thermocouple_tau_h"]]
        self._bank = LagBank(self.room, np.array(taus) * 3600.0, earliest_s=o["start_offset_s"])
        self._drift_f = np.array(self._DRIFT_FACTOR)
        self._walk = _Walk(o["world_seed"], o["drift_walk_nm_per_sqrt_day"] * 1e-3 * self._drift_f)
        self._c_stage = np.array(o["stage_coeff_um_per_c"])
        self._c_frame = np.array(o["frame_coeff_um_per_c"])
        self._tc_gain = np.array(o["thermocouple_gain"])
        self._tc_off = np.array(o["thermocouple_offset_c"])
        self._q_um = o["interferometer_resolution_nm"] * 1e-3
        self._q_c = o["thermocouple_resolution_mk"] * 1e-3
        self._sig_um = o["interferometer_noise_nm"] * 1e-3
        self._sig_c = o["thermocouple_noise_mk"] * 1e-3
        self._rep_sig = o["repeatability_nm"] * 1e-3 * np.array(self._REP_FACTOR)
        ss = np.random.SeedSequence(o["seed"])
        s_moves, s_reads, self._ss_streams = ss.spawn(3)
        self._rng_moves = np.random.default_rng(s_moves)
        self._rng_reads = np.random.default_rng(s_reads)
        self._t = 0.0
        self._cmd = tuple(0.0 for _ in self.joints)
        self._dir = tuple(0 for _ in self.joints)
        self._rep = np.zeros(n_s)
        self._settle = (-math.inf, tuple(0.0 for _ in self.joints))  # (start time, steps)
        self._closed = False

    # ------------------------------------------------------------------ protocol
    def move(self, command: Mapping[str, float]) -> None:
        """Command every joint (um); returns settled, ``rise_time_s`` later (virtual)."""
        self._check_open()
        unknown = set(command) - set(self.joints)
        if unknown:
            raise ValueError(f"{self._NAME}: unknown joint(s) {sorted(unknown)}; joints are {self.joints}")
        hi = self.options["stroke_um"] + self.options["stroke_margin_um"]
        lo = -self.options["stroke_margin_um"]
        new = []
        for j, old in zip(self.joints, self._cmd):
            v = float(command.get(j, old))
            if not (math.isfinite(v) and lo <= v <= hi):
                raise ValueError(f"{self._NAME}: command {j}={v!r} um outside [{lo}, {hi}] um")
            new.append(v)
        steps = tuple(n - c for n, c in zip(new, self._cmd))
        self._dir = tuple(d if s == 0 else (1 if s > 0 else -1) for d, s in zip(self._dir, steps))
        self._cmd = tuple(new)
        rho = self.options["repeatability_correlation"]
        e = self._rng_moves.standard_normal(len(self.sensors)) * self._rep_sig
        self._rep = rho * self._rep + math.sqrt(1.0 - rho * rho) * e
        self._settle = (self._t, steps)
        self._t += self.options["rise_time_s"]

    def wait(self, seconds: float) -> None:
        """Dwell ``seconds`` of virtual time."""
        self._check_open()
        seconds = float(seconds)
        if not seconds >= 0:
            raise ValueError(f"{self._NAME}: cannot wait {seconds!r} s")
        self._t += seconds

    def read(self) -> dict[str, float]:
        """``time`` (s since start), each sensor (um), each thermometer (degC), now."""
        self._check_open()
        t = self._t
        pos, temps = self._state(t, self._cmd, self._dir, self._settle, self._rep)
        n = len(pos)
        noise = self._rng_reads.standard_normal(n + temps.size)
        xs = np.round((np.array(pos) + self._sig_um * noise[:n]) / self._q_um) * self._q_um
        ts = np.round((temps + self._sig_c * noise[n:]) / self._q_c) * self._q_c
        return {"time": t, **dict(zip(self.sensors, xs.tolist())),
                **dict(zip(self.thermometers, ts.tolist()))}

    def close(self) -> None:
        self._closed = True

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # ------------------------------------------------------------------ extras
    @property
    def time(self) -> float:
        """Current virtual time (s since the rig's start)."""
        return self._t

    def stream(self, seconds: float, rate_hz: float | None = None,
               chunk: int = 4096) -> Iterator[dict[str, np.ndarray]]:
        """Dwell ``seconds`` sampling at ``rate_hz`` (default option ``stream_rate_hz``).

        Advances the virtual clock by ``seconds`` at once and returns an iterator of chunk
        dicts of numpy arrays (``time`` and every sensor and thermometer, at most ``chunk``
        samples each); sample i is taken at ``t0 + (i + 1) / rate_hz``. Each call draws its
        noise from its own child seed, so interleaving reads does not change it. Reduce
        with :func:`calflow.acquisition.streams.reduce_dwell` (last 5 s of each dwell, Sec. 5.3.2).
        """
        self._check_open()
        rate = float(self.options["stream_rate_hz"] if rate_hz is None else rate_hz)
        seconds = float(seconds)
        if not (rate > 0 and seconds >= 0 and int(chunk) > 0):
            raise ValueError(f"{self._NAME}: stream needs seconds >= 0, rate_hz > 0, chunk > 0")
        n = int(math.floor(seconds * rate + 1e-9))
        t0 = self._t
        self._t += seconds
        rng = np.random.default_rng(self._ss_streams.spawn(1)[0])
        state = (self._cmd, self._dir, self._settle, self._rep.copy())
        return self._stream_iter(t0, n, rate, int(chunk), state, rng)

    def _stream_iter(self, t0, n, rate, chunk, state, rng):
        for start in range(0, n, chunk):
            i = np.arange(start, min(n, start + chunk), dtype=float)
            t = t0 + (i + 1.0) / rate
            pos, temps = self._state(t, *state)
            out = {"time": t}
            for k, name in enumerate(self.sensors):
                v = pos[k] + self._sig_um * rng.standard_normal(t.size)
                out[name] = np.round(v / self._q_um) * self._q_um
            for j, name in enumerate(self.thermometers):
                v = temps[..., j] + self._sig_c * rng.standard_normal(t.size)
                out[name] = np.round(v / self._q_c) * self._q_c
            yield out

    def true_position(self, command, time: float | np.ndarray | None = None,
                      direction: int | Mapping[str, int] = 0) -> dict[str, float | np.ndarray]:
        """Noise-free sensor values (um) for ``command`` at rig ``time`` (s, default now).

        Includes geometry, coupling, thermal drift, the world's walk and creep and, if
        ``direction`` is +1/-1 (per joint or for all), the hysteresis of that approach;
        excludes noise, quantisation, per-move repeatability and settling. ``command``
        (a mapping joint -> um, or a number for a 1-DoF rig) and ``time`` may be arrays.
        """
        if not isinstance(command, Mapping):
            command = {self.joints[0]: command}
        cmds = tuple(np.asarray(command[j], dtype=float) for j in self.joints)
        dirs = tuple(int(direction.get(j, 0)) if isinstance(direction, Mapping) else int(direction)
                     for j in self.joints)
        t = self._t if time is None else np.asarray(time, dtype=float)
        pos = self._true(cmds, t, dirs)
        return {name: (p if np.ndim(p) else float(p)) for name, p in zip(self.sensors, pos)}

    def truth(self) -> dict:
        """JSON-serialisable true physics parameters (independent of the noise seed)."""
        o = self.options
        keep = {k: (list(v) if isinstance(v, tuple) else v) for k, v in o.items()
                if k not in ("seed", "start_offset_s", "profile", "profile_params", "world_seed")}
        return {"rig": self._NAME, "joints": list(self.joints), "sensors": list(self.sensors),
                "thermometers": list(self.thermometers), "room": self.room.describe(),
                "geometry": self._geometry_truth(), "options": keep}

    # ------------------------------------------------------------------ physics
    def _check_open(self):
        if self._closed:
            raise RigError(f"{self._NAME}: the rig is closed")

    def _lags(self, t_campaign):
        if np.ndim(t_campaign) == 0:
            return self._bank.at(float(t_campaign))
        return self._bank(t_campaign)

    def _true(self, cmds, t_rig, dirs, lags=None):
        """Noise-free sensor values: geometry + thermal drift + walk + creep (um)."""
        o = self.options
        tc = o["start_offset_s"] + t_rig
        if lags is None:
            lags = self._lags(tc)
        t_ref = o["base_temperature_c"] + o["reference_offset_c"]
        d_stage = lags[..., 0] - t_ref
        d_frame = lags[..., 1] - t_ref
        geo = self._geometry(cmds, dirs)
        spos = self._thermal_positions(cmds)
        walk = self._walk(tc)
        creep = o["creep_nm"] * 1e-3 * -np.expm1(-np.maximum(tc, 0.0) / (o["creep_tau_h"] * 3600.0))
        kappa = o["position_thermal_gain"]
        return [geo[k] + self._c_stage[k] * (1.0 + kappa * spos[k]) * d_stage
                + self._c_frame[k] * d_frame + walk[..., k] + creep * self._drift_f[k]
                for k in range(len(self.sensors))]

    def _state(self, t_rig, cmds, dirs, settle, rep):
        """Noise-free sensor values incl. repeatability and settling, and thermocouples."""
        lags = self._lags(self.options["start_offset_s"] + t_rig)
        pos = self._true(cmds, t_rig, dirs, lags)
        t_start, steps = settle
        decay = self.options["settle_fraction"] * np.exp(-(t_rig - t_start) / self.options["settle_tau_s"])
        tail = self._settle_map(steps)
        pos = [p + rep[k] + tail[k] * decay for k, p in enumerate(pos)]
        base = self.options["base_temperature_c"]
        temps = base + self._tc_gain * (lags[..., 2:] - base) + self._tc_off
        return pos, temps

    # subclass hooks -----------------------------------------------------------
    def _geometry(self, cmds, dirs):  # pragma: no cover - abstract
        raise NotImplementedError

    def _thermal_positions(self, cmds):  # pragma: no cover - abstract
        raise NotImplementedError

    def _settle_map(self, steps):  # pragma: no cover - abstract
        raise NotImplementedError

    def _geometry_truth(self) -> dict:  # pragma: no cover - abstract
        raise NotImplementedError


class Nano1DRig(_NanoRig):
    """P-625.1CD-like single-axis stage, 0-500 um, two interferometer beams (Sec. 5.3.1).

    ``meas_x`` = x + g(x): the cubic of Table 5.1 inverted (two critical points inside the
    stroke, ~380 nm peak to valley, Fig. 5.1 a) plus a small non-polynomial ripple, and a
    ~10 nm forward/backward difference. ``meas_y`` is the coupling seen by the second beam,
    ~75 nm over the stroke (Fig. 5.1 b), with its own (frame) thermal drift.
    """

    joints = ("x",)
    _NAME = "nano1d"
    _EXTRA = {"stroke_um": 500.0, "coupling_y_nm": 75.0,
              "stage_coeff_um_per_c": (-1.25, 0.0), "frame_coeff_um_per_c": (0.25, -0.1)}
    _REP_FACTOR = (1.0, 0.25)
    _DRIFT_FACTOR = (1.0, 0.3)
    _POLY = (0.0, -2.825, 6.122, -3.466)  # um, s = x/500 um: -(Table 5.1 cubic - x) x 1.13
    _RIPPLE = (0.012, 3.0)  # um amplitude, half periods over the stroke
    _COUPLING = (1.3, -0.3, 0.004)  # shape s(1.3 - 0.3 s), + 4 nm sin(2 pi s)

    def _geometry(self, cmds, dirs):
        x = cmds[0]
        s = x / self.options["stroke_um"]
        p0, p1, p2, p3 = self._POLY
        amp, half = self._RIPPLE
        g = self.options["geometric_scale"] * (p0 + s * (p1 + s * (p2 + s * p3))
                                                + amp * np.sin(np.pi * half * s))
        hyst = dirs[0] * 0.5e-3 * self.options["hysteresis_nm"] * (0.5 + 0.5 * np.sin(np.pi * s))
        c1, c2, wig = self._COUPLING
        y = 1e-3 * self.options["coupling_y_nm"] * s * (c1 + c2 * s) + wig * np.sin(2 * np.pi * s)
        return [x + g + hyst, y]

    def _thermal_positions(self, cmds):
        s = cmds[0] / self.options["stroke_um"]
        return [s, s]

    def _settle_map(self, steps):
        return [steps[0], 0.0]

    def _geometry_truth(self):
        return {"meas_x": "x + geometric_scale*(sum_i poly[i] s^i + ripple[0] sin(pi ripple[1] s))"
                          " + direction*hysteresis/2*(0.5 + 0.5 sin(pi s)), s = x/stroke",
                "meas_y": "coupling_y*s*(c[0] + c[1] s) + c[2] sin(2 pi s)",
                "poly_um": list(self._POLY), "ripple": list(self._RIPPLE),
                "coupling": list(self._COUPLING)}


class Nano2DRig(_NanoRig):
    """80 x 80 um two-axis nanocube (Sec. 5.4): per-axis cubic errors, cross-axis coupling.

    Each axis has a scale error, a cubic with a non-polynomial ripple, and couples into the
    other through a linear term (axis non-orthogonality), a quadratic and a bilinear
    ``x*y`` term that Eq. 5.10 cannot represent; uncalibrated accuracy is ~1.2-1.4 um.
    """

    joints = ("x", "y")
    _NAME = "nano2d"
    _EXTRA = {"stroke_um": 80.0, "coupling_scale": 1.0,
              "stage_coeff_um_per_c": (-1.0, -0.8), "frame_coeff_um_per_c": (0.2, 0.15)}
    _REP_FACTOR = (1.0, 1.0)
    _DRIFT_FACTOR = (1.0, 1.0)
    # own axis (um): scale*s + cubic*T3(2s-1) + quad*(2s-1)^2 + ripple*sin(3 pi s)
    _OWN = {"meas_x": (0.30, 0.10, 0.03, 0.015), "meas_y": (-0.20, 0.08, -0.03, 0.015)}
    # other axis (um): lin*o + bilinear*s*o + quad*o^2, o = other axis / stroke
    _CROSS = {"meas_x": (0.75, 0.10, -0.06), "meas_y": (-0.55, 0.08, 0.05)}

    def _geometry(self, cmds, dirs):
        L = self.options["stroke_um"]
        G, C = self.options["geometric_scale"], self.options["coupling_scale"]
        h = 0.5e-3 * self.options["hysteresis_nm"]
        out = []
        for k, name in enumerate(self.sensors):
            s, o = cmds[k] / L, cmds[1 - k] / L
            u = 2 * s - 1
            a, b, c, d = self._OWN[name]
            lin, bil, quad = self._CROSS[name]
            own = a * s + b * (4 * u ** 3 - 3 * u) + c * u * u + d * np.sin(3 * np.pi * s)
            cross = lin * o + bil * s * o + quad * o * o
            hyst = dirs[k] * h * (0.5 + 0.5 * np.sin(np.pi * s))
            out.append(cmds[k] + G * own + C * cross + hyst)
        return out

    def _thermal_positions(self, cmds):
        L = self.options["stroke_um"]
        return [cmds[0] / L, cmds[1] / L]

    def _settle_map(self, steps):
        return [steps[0], steps[1]]

    def _geometry_truth(self):
        return {"own_axis": "a s + b T3(2s-1) + c (2s-1)^2 + d sin(3 pi s), s = own/stroke",
                "cross_axis": "lin o + bilinear s o + quad o^2, o = other/stroke",
                "own_um": {k: list(v) for k, v in self._OWN.items()},
                "cross_um": {k: list(v) for k, v in self._CROSS.items()}}


def nano1d(**options) -> Nano1DRig:
    """Factory of the simulated 1-DoF stage; options and defaults in ``_COMMON``/``_EXTRA``."""
    return Nano1DRig(**options)


def nano2d(**options) -> Nano2DRig:
    """Factory of the simulated 2-DoF stage; options and defaults in ``_COMMON``/``_EXTRA``."""
    return Nano2DRig(**options)


# The config check calls these (calflow.rigs.plugin.check_rig): options checked, no rig built.
nano1d.check_options = lambda **o: check_options("nano1d", {**_COMMON, **Nano1DRig._EXTRA}, 2, o)
nano2d.check_options = lambda **o: check_options("nano2d", {**_COMMON, **Nano2DRig._EXTRA}, 2, o)
