"""Heat sources off the thermocouples' paths, through the lumped thermal network.

Powers in W, temperatures in K (rises above what the room alone gives), time in s of
campaign time (0 = the zeroing, midnight of the room profile's first day). Each source
heats one node of :mod:`calflow.nano.stage.thermal_network`; the network is linear, so its
response adds to the room's (superposition) and the thermocouples see only what reaches
their hosts (the air, the base plate):

* ``lighting``: visible light through the (transparent) shield, absorbed by the stage, while
  the lights are on. 500 lx on a laboratory's work plane (EN 12464-1:2011) at a luminous
  efficacy of radiation of ~300 lm/W for white light is ~1.7 W/m2 of visible irradiance;
  ~0.01 m2 of stage top at absorptance ~0.5 under a shield passing ~0.9 gives ~8 mW.
* ``people``: a person at the bench. Sensible heat ~70 W of which ~60 % radiant (ASHRAE
  Handbook Fundamentals, Ch. 18, heat gain from occupants); the shield (opaque to thermal
  infrared) intercepts ~0.2 % at ~2 m and passes about half to the air under it: ~0.04 W.
* ``electronics_heating``: the controller/amplifier on the table; its heat reaching the base
  plate rises from switch-on with the housing's time constant, P (1 - exp(-t/tau)).
* ``piezo_heating``: the stack's own dielectric loss. In sinusoidal drive it dissipates
  P = pi/4 tan(delta) f C U_pp^2 (Noliac tutorial "Heat dissipation": C and tan(delta) at
  large signal, their product 7-10x the datasheet's small-signal one; PI's P-88x manual adds
  70 % to the small-signal capacitance for large signals); a move of
  dU is half a cycle, E = pi/8 tan(delta) C dU^2 (J), dU = step / stroke x drive span.
  Quasi-static stepping dissipates microwatts: the term is tiny, and says so.
"""

from __future__ import annotations

import math

import numpy as np

from calflow.nano.stage.thermal_network import network_matrices
from calflow.rigs.thermal import LinearBank

__all__ = ["daily_window", "HeatBanks", "piezo_energy_j", "structural_modes"]

_HOUR = 3600.0


def daily_window(t_s, start_h: float, stop_h: float):
    """1 while the hour of the day of campaign time ``t_s`` (s) is in [start_h, stop_h), else 0."""
    hod = np.mod(np.asarray(t_s, dtype=float) / _HOUR, 24.0)
    return ((hod >= start_h) & (hod < stop_h)).astype(float)


def piezo_energy_j(step_um, stroke_um: float, o: dict):
    """Heat (J) the stack dissipates in a move of ``step_um`` (module docstring)."""
    du = np.asarray(step_um, dtype=float) / stroke_um * o["piezo_drive_span_v"]
    return math.pi / 8.0 * o["piezo_loss_factor"] * o["piezo_capacitance_uf"] * 1e-6 * du**2


def _sources(o: dict) -> dict:
    """``{effect: (node index, power(t) in W)}`` of the scheduled heat sources that are on."""
    on_s = -o["mounted_h_before"] * _HOUR
    tau = o["electronics_warmup_h"] * _HOUR
    visits = [(h, h + o["people_visit_h"]) for h in o["people_visits_h"]]
    out = {
        "lighting": (0, lambda t: o["lighting_w"] * daily_window(t, o["lights_on_h"], o["lights_off_h"])),
        "people": (2, lambda t: o["people_w"] * sum(daily_window(t, a, b) for a, b in visits)),
        "electronics_heating": (
            1,
            lambda t: (
                o["electronics_w"] * (1.0 - np.exp(-np.clip(np.asarray(t, float) - on_s, 0.0, None) / tau))
            ),
        ),
    }
    keys = {"lighting": "lighting_w", "people": "people_w", "electronics_heating": "electronics_w"}
    return {k: v for k, v in out.items() if o[keys[k]] > 0}


class HeatBanks:
    """Node rises (K) of the rig's network from each scheduled source, exact on a 30 s grid.

    ``A`` is the rig's network matrix (states stage, base, air, thermocouples, ...; it may be
    extended with more linear states, e.g. glued junctions); ``capacities`` (J/K) of the three
    structural nodes turn W into K/s.
    """

    def __init__(self, A: np.ndarray, capacities, o: dict, earliest_s: float = 0.0):
        self.banks = {}
        self.n = A.shape[0]
        slowest = 1.0 / np.min(np.abs(np.linalg.eigvals(A).real))
        for name, (node, power) in _sources(o).items():
            b = np.zeros(A.shape[0])
            b[node] = 1.0 / capacities[node]
            bank = LinearBank(
                power,
                A,
                b,
                earliest_s=min(earliest_s, -o["mounted_h_before"] * _HOUR),
                warmup_s=10.0 * slowest,
            )
            self.banks[name] = (bank, bank.at(0.0))

    def at(self, t_campaign) -> tuple[dict, np.ndarray]:
        """``({effect: rise now minus at the zeroing}, sum of the absolute rises)`` (K, states
        (..., n)): each source's drift, and what the thermocouples read of them all."""
        scalar = np.ndim(t_campaign) == 0
        now = {k: (b.at(float(t_campaign)) if scalar else b(t_campaign)) for k, (b, _) in self.banks.items()}
        total = np.zeros(np.shape(t_campaign) + (self.n,))
        for v in now.values():
            total = total + v
        return {k: v - self.banks[k][1] for k, v in now.items()}, total


def structural_modes(net) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Decay rates (1/s), the stage-heat input per mode (K/J) and the (stage, base) outputs of the
    network's three structural nodes: a symmetric conductance matrix scaled by the capacities,
    so its eigenvalues are real and negative and its eigenbasis well-conditioned."""
    A, _ = network_matrices(net)
    lam, V = np.linalg.eig(A[:3, :3])
    lam, V = lam.real, V.real
    w = np.linalg.solve(V, np.array([1.0 / net.stage_capacity_j_per_k, 0.0, 0.0]))
    return -lam, w, V[:2]
