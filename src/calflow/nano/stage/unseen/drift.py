"""The drift the thermocouples do not see, as terms of a simulated nano rig (um per sensor).

:class:`UnseenDrift` is built by the rig (:mod:`calflow.nano.stage.rig`) from its checked
options, thermal network, room and weather; it gives each effect of
:data:`~calflow.nano.stage.unseen.options.UNSEEN_EFFECTS` as one term per sensor
(:meth:`terms`), and what the thermocouples read beside their hosts (:meth:`thermocouples`).
Time in s (campaign time unless named ``t_rig``), lengths in um, temperatures in K/degC.

Two effects remember the moves (a *memory*: one decaying state per mode, updated at each
move, :meth:`after_move` on the rig, :meth:`replay` for a recorded run):

* ``piezo_heating``: each move's dissipated heat (:func:`~calflow.nano.stage.unseen.heat.piezo_energy_j`)
  enters the stage node and decays through the three structural modes of the network; it
  drifts the stage as the room's heat does (stage coefficient, optics on the base, expansion).
  Its share at the thermocouples' hosts is below a microkelvin and left out.
* ``move_settling``: the mechanics outside the control loop (flexure hinges, bonded parts)
  follow a move of size d by a log-time relaxation, the piezo's own creep law (PI, *Piezo
  Mechanics Design Tutorial*: x(t) = x0 [1 + g lg(t / 0.1 s)]) at ``move_settling_ppm_per_decade``
  of d per decade (an assumption: no datasheet gives the part outside the loop), written as
  the sum of five exponential modes of time constants 1 s .. 10^4 s (one per decade: their
  sum falls by ~1 per decade) and superposed over the moves (Boltzmann).

``mount_settling``: the same log-time law since the stage was bolted down and the mirror
clamped, ``mounted_h_before`` before the zeroing: a [lg(1 + (t + T)/60 s) - lg(1 + T/60 s)]
along a direction per sensor from ``world_seed`` (an assumption of size, log-time law of
stress relaxation in bolted joints).
"""

from __future__ import annotations

import numpy as np

from calflow.nano.stage.thermal_network import network_matrices
from calflow.nano.stage.unseen import heat, humidity, instruments
from calflow.nano.stage.unseen.options import HEAT_SOURCES, TC_ERRORS, UNSEEN_EFFECTS
from calflow.rigs.thermal import LinearBank

__all__ = ["UnseenDrift"]

_DECADES = 10.0 ** np.arange(5)  # move settling's time constants (s)
_T0_MOUNT = 60.0


class UnseenDrift:
    """Terms of the unseen effects of one rig (module docstring). ``axes``: the joint each sensor
    measures along (None: across); ``phases``: the weather's (:func:`humidity.weather_at`)."""

    EFFECTS = tuple(UNSEEN_EFFECTS)
    POSITION = tuple(e for e in UNSEEN_EFFECTS if e not in TC_ERRORS)

    def __init__(self, o: dict, net, room, axes: tuple, phases, earliest_s: float = 0.0):
        self.o, self.axes, self.phases = o, axes, phases
        self.n_tc = len(o["thermocouple_offset_c"])
        self.active = any(o[k] for keys in UNSEEN_EFFECTS.values() for k in keys)
        n_joints = 1 + max(a for a in axes if a is not None)
        A, b = network_matrices(net)
        self._n_net = A.shape[0]
        self._A, self._b = self._extend(A, b)
        caps = (net.stage_capacity_j_per_k, net.base_capacity_j_per_k, net.air_capacity_j_per_k)
        self.heat = heat.HeatBanks(self._A, caps, o, earliest_s)
        self._room_bank = None
        if self.active:
            slowest = 1.0 / np.min(np.abs(np.linalg.eigvals(self._A).real))
            self._room_bank = LinearBank(room, self._A, self._b, earliest_s=earliest_s, warmup_s=10 * slowest)
        seed = int(o["world_seed"])
        self._rates_tc = instruments.calibration_rates_c_per_s(
            seed, self.n_tc, o["thermocouple_drift_mk_per_day"]
        )
        n_s = len(axes)
        self._laser = instruments.Wander([seed, 29, 2], n_s, 3600.0 * np.geomspace(0.5, 12.0, 5), bound=True)
        self._turb = instruments.Wander([seed, 29, 3], n_s, 1.0 / np.geomspace(0.02, 2.0, 24), bound=False)
        rng = np.random.default_rng(np.random.SeedSequence([seed, 29, 4]))
        self._periodic_phase = rng.uniform(0, 2 * np.pi, n_s)
        self._mount_dir = rng.uniform(-1.0, 1.0, n_s)
        rates, self._w_heat, self._out_heat = heat.structural_modes(net)
        self.rates = np.concatenate([rates, np.tile(1.0 / _DECADES, n_joints)])
        self._n_heat = rates.size
        self._cache = (None, None)  # the last scalar time's heat and states: a read asks twice
        self._eps0 = self._eps(0.0) if self.active else 1.0
        self._rh_lag0 = humidity.lagged_humidity(o, phases, 0.0, o["bond_moisture_tau_h"] * 3600.0)
        self._laser0 = [self._laser(0.0, k) for k in range(n_s)]

    # ------------------------------------------------------------------ network with the sensors' states
    def _extend(self, A, b):
        """The network plus glued-junction states (n_tc) and the reference junction's terminal and
        sensor (2), each when switched on; the rig's network's states come first."""
        o, n0, n_tc = self.o, A.shape[0], self.n_tc
        glue, cjc = o["junction_glue_tau_s"] > 0, o["cjc_lag_s"] > 0
        n = n0 + (n_tc if glue else 0) + (2 if cjc else 0)
        Ae, be = np.zeros((n, n)), np.zeros(n)
        Ae[:n0, :n0], be[:n0] = A, b
        self._glue = slice(n0, n0 + n_tc) if glue else None
        for j in range(n_tc if glue else 0):
            Ae[n0 + j, 3 + j] = 1.0 / o["junction_glue_tau_s"]
            Ae[n0 + j, n0 + j] = -1.0 / o["junction_glue_tau_s"]
        self._cjc = (n - 2, n - 1) if cjc else None
        if cjc:
            term, sens = self._cjc
            Ae[term, term], be[term] = -1.0 / o["cjc_terminal_tau_s"], 1.0 / o["cjc_terminal_tau_s"]
            Ae[sens, term], Ae[sens, sens] = 1.0 / o["cjc_lag_s"], -1.0 / o["cjc_lag_s"]
        return Ae, be

    # ------------------------------------------------------------------ the moves' memory
    def rest(self):
        """Memory of a rig that has not moved: (time of the last move, modal states)."""
        return -np.inf, np.zeros(self.rates.size)

    def _inputs(self, steps) -> np.ndarray:
        """Modal inputs of moves ``steps`` (..., n_joints) um."""
        steps = np.asarray(steps, dtype=float)
        e = np.sum(heat.piezo_energy_j(steps, self.o["stroke_um"], self.o), axis=-1)
        return np.concatenate(
            [e[..., None] * self._w_heat, np.repeat(steps, _DECADES.size, axis=-1)], axis=-1
        )

    def after_move(self, memory, t_rig: float, steps) -> tuple:
        """Memory after a move of ``steps`` (um per joint) starting at ``t_rig``."""
        t_last, s = memory
        return t_rig, (
            s * np.exp(-self.rates * (t_rig - t_last)) if np.isfinite(t_last) else s
        ) + self._inputs(steps)

    def replay(self, t_moves, steps) -> tuple:
        """Memory after each of a run's moves (times (n,) s, steps (n, n_joints) um), from rest at 0."""
        t_moves = np.asarray(t_moves, dtype=float)
        u = self._inputs(steps)
        out = np.empty_like(u)
        t_last, s = self.rest()
        for i, t in enumerate(t_moves):
            s = (s * np.exp(-self.rates * (t - t_last)) if np.isfinite(t_last) else s) + u[i]
            t_last = t
            out[i] = s
        return t_moves, out

    # ------------------------------------------------------------------ terms
    def terms(self, cmds, tc, t_rig, memory, true_pos, zero) -> dict:
        """``{effect: [term per sensor]}`` (um) at commands ``cmds`` (per joint), campaign time
        ``tc`` and rig time ``t_rig``; ``memory`` of the moves (None: their effects are 0);
        ``true_pos`` the sensors' values from the other effects (the optical path's length)."""
        out = {name: [] for name in self.POSITION}
        if not self.active:
            return {name: [zero for _ in self.axes] for name in out}
        o = self.o
        rises = dict(self._now(tc)[0])
        if memory is not None:
            t_last, s = memory
            modes = s * np.exp(-self.rates * np.asarray(np.asarray(t_rig, dtype=float) - t_last)[..., None])
            rises["piezo_heating"] = modes[..., : self._n_heat] @ self._out_heat.T  # (stage, base), K
        eps = self._eps(tc) / self._eps0 - 1.0
        tau_b = o["bond_moisture_tau_h"] * 3600.0
        lag = humidity.lagged_humidity
        swell = o["bond_swelling_nm_per_pct"] * 1e-3 * (lag(o, self.phases, tc, tau_b) - self._rh_lag0)
        age = o["mounted_h_before"] * 3600.0
        mount = (
            o["mount_settling_nm_per_decade"]
            * 1e-3
            * (np.log10(1 + (np.asarray(tc) + age) / _T0_MOUNT) - np.log10(1 + age / _T0_MOUNT))
        )
        dead = o["deadpath_m"] * 1e6
        n_dec = _DECADES.size
        for k, axis in enumerate(self.axes):
            x = cmds[axis] if axis is not None else zero
            for name in HEAT_SOURCES:
                r = rises.get(name)
                out[name].append(zero if r is None else self._thermal_um(k, x, r) + zero)
            out["mount_settling"].append(self._mount_dir[k] * mount + zero)
            settle = zero
            if memory is not None and axis is not None:
                m = modes[..., self._n_heat + axis * n_dec : self._n_heat + (axis + 1) * n_dec]
                settle = -o["move_settling_ppm_per_decade"] * 1e-6 * np.sum(m, axis=-1) + zero
            out["move_settling"].append(settle)
            out["humidity_swelling"].append(swell + zero)
            gap = o["sensor_gap_um"]
            out["sensor_air"].append(eps * (gap + x) + zero if axis is not None and gap > 0 else zero)
            path = dead + true_pos[k]
            out["laser_wander"].append(
                -o["laser_wander_ppm"] * 1e-6 * (self._laser(tc, k) - self._laser0[k]) * path + zero
            )
            out["periodic_nonlinearity"].append(
                instruments.periodic_um(
                    path, dead, o["periodic_error_nm"], o["periodic_period_nm"], self._periodic_phase[k]
                )
                + zero
            )
            out["turbulence"].append(
                instruments.turbulence_um(self._turb, k, tc, path, o["turbulence_mk"]) + zero
            )
        return out

    def _thermal_um(self, k: int, x, rise):
        """Drift (um) of sensor k from node rises (K): the stage and optics coefficients and the
        expansion of the stroke, as for the room's heat (calflow.nano.stage.rig)."""
        o = self.o
        return (
            o["stage_coeff_um_per_c"][k] * rise[..., 0]
            + o["optics_drift_um_per_c"] * rise[..., 1]
            + o["expansion_ppm_per_c"] * 1e-6 * x * rise[..., 0]
        )

    def _now(self, tc):
        """(each source's rise since the zeroing, their absolute sum, every state of the extended
        network: room-driven plus heat), K and degC; the last scalar time's kept."""
        scalar = np.ndim(tc) == 0
        if scalar and self._cache[0] == float(tc):
            return self._cache[1]
        rises, total = self.heat.at(tc)
        room = self._room_bank.at(float(tc)) if scalar else self._room_bank(tc)
        out = (rises, total, room + total)
        if scalar:
            self._cache = (float(tc), out)
        return out

    def _states(self, tc):
        """Every state (degC) of the extended network: room-driven plus the heat sources."""
        return self._now(tc)[2]

    def _eps(self, tc):
        """Permittivity of the capacitive sensor's air (at the stage node's temperature)."""
        p, rh = humidity.weather_at(self.o, self.phases, tc)
        return humidity.permittivity(self._states(tc)[..., 0], p, rh)

    # ------------------------------------------------------------------ thermocouples
    def thermocouples(self, tc) -> dict:
        """``{"heat": rise, effect: error}`` (K, (..., n_tc)) of what the thermocouples read beside
        their hosts' room-driven temperatures: the heat sources' share, then each error."""
        n = self.n_tc
        zeros = np.zeros(np.shape(tc) + (n,))
        if not self.active:
            return {"heat": zeros, **{e: zeros for e in TC_ERRORS}}
        states = self._states(tc)
        out = {"heat": self._now(tc)[1][..., 3 : 3 + n]}
        out["thermocouple_calibration"] = np.asarray(tc, dtype=float)[..., None] * self._rates_tc
        out["junction_lag"] = states[..., self._glue] - states[..., 3 : 3 + n] if self._glue else zeros
        out["reference_junction"] = zeros
        if self._cjc:
            term, sens = self._cjc
            out["reference_junction"] = (states[..., sens] - states[..., term])[..., None] + zeros
        return out

    def reading_c(self, tc):
        """Sum (K, (..., n_tc)) the thermocouples read beyond their hosts' room-driven temperature."""
        return sum(self.thermocouples(tc).values())
