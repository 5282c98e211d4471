"""The machinery the simulated nano rigs share (:mod:`calflow.nano.stage.rig`): their options,
virtual clock, move, dwell and read, noise, and each deterministic effect's term at the
commanded positions and times (:meth:`NanoRig.effect_terms`); a rig adds only its stage's
geometry and coupling. Lengths in um, temperatures in degC, time in s.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from calflow.errors import RigError
from calflow.nano.stage import interferometer as ifm
from calflow.nano.stage.options import _COMMON, EFFECTS, NOISE, _Walk, check_options
from calflow.nano.stage.piezo import (
    PlayHysteresis,
    closed_loop_step,
    gain_offset_um,
    residual_creep_um,
    sensor_nonlinearity_um,
)
from calflow.nano.stage.records import HighRateRecords
from calflow.nano.stage.thermal_network import ThermalNetwork, network_bank
from calflow.nano.stage.truth import RigTruth
from calflow.nano.stage.unseen.drift import UnseenDrift
from calflow.nano.stage.unseen.humidity import weather_at
from calflow.rigs.thermal import room_profile

_DETERMINISTIC = tuple(e for e in EFFECTS if e not in NOISE and e not in UnseenDrift.EFFECTS)  # built in here
_STAGE, _BASE, _AIR = 0, 1, 2  # structural nodes of the network; thermocouples, compensation sensor follow


class NanoRig(HighRateRecords, RigTruth):
    """Common machinery of the nano rigs: options, virtual clock, noise, physics."""

    joints: tuple[str, ...] = ()
    replayable = True  # deterministic given its seeds: acquisition may replay it to resume
    sensors: tuple[str, ...] = ("meas_x", "meas_y")
    _NAME = ""
    _EXTRA: dict = {}
    _REP_FACTOR: tuple[float, ...] = ()  # repeatability per sensor, relative
    _AXIS: tuple = ()  # joint index each sensor measures along (None: across)

    @classmethod
    def check(cls, **options) -> dict:
        """The stage's options checked with its defaults, no rig built (the family's option check)."""
        return check_options(cls._NAME, {**_COMMON, **cls._EXTRA}, len(cls.sensors), options)

    def __init__(self, **options):
        o = self.check(**options)
        n_tc = len(o["thermocouple_tau_s"])
        self.options = o
        self.thermometers = tuple(f"T{j + 1}" for j in range(n_tc))
        self.room = room_profile(
            o["profile"], base_c=o["base_temperature_c"], seed=o["world_seed"], **o["profile_params"]
        )
        self._comp_lag = o["compensation_sensor_tau_s"] > 0  # else the compensation reads the beam's air
        net = ThermalNetwork.from_options(
            {
                **o,
                "thermocouple_tau_s": (*o["thermocouple_tau_s"], o["compensation_sensor_tau_s"] or 1.0),
                "thermocouple_air_weight": (*o["thermocouple_air_weight"], 1.0),
            }
        )
        self._bank = network_bank(net, self.room, earliest_s=o["start_offset_s"])
        self._n_tc = n_tc
        self._walk = _Walk(
            o["world_seed"], o["drift_walk_nm_per_sqrt_day"] * 1e-3 * np.ones(len(self.sensors))
        )
        self._weather = np.random.default_rng(np.random.SeedSequence([int(o["world_seed"]), 3_4])).uniform(
            0, 2 * np.pi, 3
        )
        self._nodes0 = self._bank.at(0.0)  # the zeroing (campaign time 0)
        self._unseen = UnseenDrift(o, net, self.room, self._AXIS, self._weather, o["start_offset_s"])
        self._mem = self._unseen.rest()  # the moves' memory (piezo heat, settling)
        self._n0 = self._indices(0.0, self._nodes0)
        self._c_stage = np.array(o["stage_coeff_um_per_c"])
        self._tc_off = np.array(o["thermocouple_offset_c"])
        self._q_um = o["interferometer_resolution_nm"] * 1e-3
        self._q_c = o["thermocouple_resolution_mk"] * 1e-3
        self._sig_um = o["interferometer_noise_nm"] * 1e-3
        self._sig_c = o["thermocouple_noise_mk"] * 1e-3
        self._rep_sig = o["repeatability_nm"] * 1e-3 * np.array(self._REP_FACTOR)
        self.play = PlayHysteresis(o["stroke_um"], o["hysteresis_nm"])
        self._loop = o["loop_residual_pct"] * 1e-2
        ss = np.random.SeedSequence(o["seed"])
        s_moves, s_reads, self._ss_streams = ss.spawn(3)
        self._rng_moves = np.random.default_rng(s_moves)
        self._rng_reads = np.random.default_rng(s_reads)
        self._t = 0.0
        self._cmd = tuple(0.0 for _ in self.joints)
        self._z = tuple(self.play.initial() for _ in self.joints)
        self._rep = np.zeros(len(self.sensors))
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
        self._cmd = tuple(new)
        self._z = tuple(self.play.step(z, v) for z, v in zip(self._z, new))
        rho = self.options["repeatability_correlation"]
        e = self._rng_moves.standard_normal(len(self.sensors)) * self._rep_sig
        self._rep = rho * self._rep + math.sqrt(1.0 - rho * rho) * e
        self._settle = (self._t, steps)
        self._mem = self._unseen.after_move(self._mem, self._t, steps)
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
        pos, temps = self._state(t, self._snapshot())
        n = len(pos)
        noise = self._rng_reads.standard_normal(n + temps.size)
        xs = np.round((np.array(pos) + self._noise_sd(pos) * noise[:n]) / self._q_um) * self._q_um
        ts = np.round((temps + self._sig_c * noise[n:]) / self._q_c) * self._q_c
        return {
            "time": t,
            **dict(zip(self.sensors, xs.tolist())),
            **dict(zip(self.thermometers, ts.tolist())),
        }

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

    # ------------------------------------------------------------------ physics
    def effect_terms(
        self, cmds, t_rig, z, steps=None, since_s=None, nodes=None, memory=None
    ) -> dict[str, list]:
        """Each deterministic effect's term (um) per sensor, at commands ``cmds`` (one array per
        joint) and rig times ``t_rig``: play states ``z`` (one (..., n) array per joint), last
        ``steps`` (um per joint), the time ``since_s`` the move started (creep; None: no creep)
        and the moves' ``memory`` (:class:`UnseenDrift`; None: piezo heat and settling are 0).
        The summary step's error budget evaluates these at a run's samples."""
        o = self.options
        tc = o["start_offset_s"] + np.asarray(t_rig, dtype=float)
        shape = np.broadcast(tc, *cmds).shape
        if not shape:  # one reading: plain floats are several times faster than 0-d arrays
            tc, cmds = float(tc), tuple(float(c) for c in cmds)
        nodes = self._nodes(tc) if nodes is None else nodes
        d = nodes - self._nodes0
        zero = np.zeros(shape) if shape else 0.0  # broadcasts every term to the query's shape
        L = o["stroke_um"]
        geo = self._geometry(cmds)
        n_air, n_comp = self._indices(tc, nodes)
        out = {name: [] for name in _DETERMINISTIC}
        walk = self._walk(tc) if o["drift_walk_nm_per_sqrt_day"] else None
        for k, axis in enumerate(self._AXIS):
            x = cmds[axis] if axis is not None else zero
            s = x / L
            on_axis = axis is not None
            aged = gain_offset_um(x, o["gain_pct"], o["offset_nm"][k])  # +0.0 unaged
            out["geometry"].append(geo["geometry"][k] + aged + zero)
            out["coupling"].append(geo["coupling"][k] + zero)
            out["sensor_nonlinearity"].append(
                sensor_nonlinearity_um(s, L, o["sensor_linearity_pct"]) + zero if on_axis else zero
            )
            out["hysteresis"].append(self.play.error(z[axis], x) + zero if on_axis else zero)
            out["creep"].append(
                residual_creep_um(steps[axis], since_s, o["creep_pct_per_decade"], self._loop) + zero
                if on_axis and steps is not None and since_s is not None
                else zero
            )
            out["stage_drift"].append(self._c_stage[k] * d[..., _STAGE])
            out["expansion"].append(o["expansion_ppm_per_c"] * 1e-6 * x * d[..., _STAGE])
            out["optics_drift"].append(o["optics_drift_um_per_c"] * d[..., _BASE])
            dead, path = ifm.reading_error_um(
                x, n_air, n_comp, *self._n0, o["deadpath_m"] * 1e6, o["deadpath_corrected"]
            )
            out["deadpath"].append(dead + zero)
            out["compensation"].append(path + zero)
            out["cosine"].append(ifm.cosine_error_um(x, o["cosine_deg"]) + zero if on_axis else zero)
            out["abbe"].append(
                ifm.abbe_error_um(s, o["abbe_offset_mm"], o["abbe_pitch_urad"]) + zero if on_axis else zero
            )
            out["walk"].append(walk[..., k] + zero if walk is not None else zero)
        out.update(self._unseen.terms(cmds, tc, t_rig, memory, self._sum(cmds, out), zero))
        return out

    def _nodes(self, t_campaign):
        if np.ndim(t_campaign) == 0:
            return self._bank.at(float(t_campaign))
        return self._bank(t_campaign)

    def _weather_at(self, t_campaign):
        """Air pressure (Pa) and relative humidity (%) at campaign time (s): a 3.3-day weather
        swing and a daily humidity swing, phases from ``world_seed``."""
        return weather_at(self.options, self._weather, t_campaign)

    def _indices(self, t_campaign, nodes):
        """Refractive index of the beam's air and the one the compensation unit computes."""
        o = self.options
        p, rh = self._weather_at(t_campaign)
        n_air = ifm.refractive_index(nodes[..., _AIR], p, rh)
        t_comp = nodes[..., -1] if self._comp_lag else nodes[..., _AIR]
        n_comp = ifm.refractive_index(
            t_comp + o["compensation_bias_k"], p + o["compensation_bias_pa"], rh + o["compensation_bias_pct"]
        )
        return n_air, n_comp

    def _noise_sd(self, pos):
        """Per-sensor noise sd (um): white noise (U3) and the laser's wavelength instability (U1,
        a uniform relative error of the measured distance)."""
        u1 = self.options["wavelength_stability_ppm"] * 1e-6 / math.sqrt(3.0)
        return [np.hypot(self._sig_um, u1 * np.abs(p)) for p in pos]

    def _snapshot(self):
        return self._cmd, self._z, self._settle, self._rep.copy(), self._mem

    def _check_open(self):
        if self._closed:
            raise RigError(f"{self._NAME}: the rig is closed")

    def _state(self, t_rig, state):
        """Noise-free sensor values incl. repeatability, step response, settling and creep, and thermocouples."""
        cmds, z, (t_start, steps), rep, memory = state
        o = self.options
        nodes = self._nodes(o["start_offset_s"] + t_rig)
        cmds = tuple(np.asarray(c, dtype=float) for c in cmds)
        since = t_rig - t_start if math.isfinite(t_start) else None
        terms = self.effect_terms(cmds, t_rig, z, steps, since, nodes, memory)
        pos = self._sum(cmds, terms)
        decay = o["settle_fraction"] * np.exp(-(t_rig - t_start) / o["settle_tau_s"])
        if since is not None:  # the closed loop's step response: the stage lags the new command
            decay = decay + (
                closed_loop_step(since, o["step_natural_hz"], o["step_damping"]) - 1.0
            )  # 0 once settled
        pos = [
            p + rep[k] + (steps[a] * decay if a is not None else 0.0)
            for k, (p, a) in enumerate(zip(pos, self._AXIS))
        ]
        temps = (
            nodes[..., 3 : 3 + self._n_tc]
            + self._tc_off
            + self._unseen.reading_c(o["start_offset_s"] + t_rig)
        )
        return pos, temps

    # subclass hooks -----------------------------------------------------------
    def _geometry(self, cmds) -> dict:  # pragma: no cover - abstract
        raise NotImplementedError

    def _geometry_truth(self) -> dict:  # pragma: no cover - abstract
        raise NotImplementedError
