"""Lumped thermal network of a nanopositioning cell under its air shield (thesis Sec. 5.2.2, 5.3.1).

Three structural nodes exchange heat with each other and with the room (the driver, a
profile of :mod:`calflow.rigs.thermal`):

    C_s dT_s/dt = G_sa (T_a - T_s) + G_sb (T_b - T_s)                       stage
    C_b dT_b/dt = G_sb (T_s - T_b) + G_ba (T_a - T_b) + G_br (T_room - T_b)  base plate
    C_a dT_a/dt = G_sa (T_s - T_a) + G_ba (T_b - T_a) + G_ar (T_room - T_a)  air under the shield

(heat capacities C in J/K, conductances G in W/K). Each thermocouple j is a node of its
own: its junction sits on a host that is a mix of the air and the base (``air_weight_j``
of the air, the rest of the base: a junction taped to the plate in still air sees both)
and follows it with its own sensor time constant tau_j:

    tau_j dT_j/dt = w_j T_a + (1 - w_j) T_b - T_j.

The whole network is one linear system ``dx/dt = A x + b T_room`` integrated exactly
(:class:`calflow.rigs.thermal.LinearBank`). Default values and where they come from:
docs/rigs.md ("Where the simulated nano rigs' defaults come from").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calflow.rigs.thermal import LinearBank

__all__ = ["NODES", "ThermalNetwork", "network_matrices", "network_bank"]

NODES = ("stage", "base", "air")  # structural nodes; the thermocouples follow


@dataclass(frozen=True)
class ThermalNetwork:
    """Physical parameters of the network (J/K, W/K, s; see the module docstring)."""

    stage_capacity_j_per_k: float
    base_capacity_j_per_k: float
    air_capacity_j_per_k: float
    stage_air_w_per_k: float
    stage_base_w_per_k: float
    base_air_w_per_k: float
    base_room_w_per_k: float
    air_room_w_per_k: float
    thermocouple_tau_s: tuple[float, ...]
    thermocouple_air_weight: tuple[float, ...]

    @classmethod
    def from_options(cls, o: dict) -> ThermalNetwork:
        """The network of a nano rig's checked options (same key names)."""
        return cls(**{k: o[k] for k in cls.__dataclass_fields__})


def network_matrices(net: ThermalNetwork) -> tuple[np.ndarray, np.ndarray]:
    """``(A, b)`` of ``dx/dt = A x + b T_room`` (1/s), states (stage, base, air, T1..Tn)."""
    n_tc = len(net.thermocouple_tau_s)
    n = 3 + n_tc
    G = np.zeros((3, 3))
    G[0, 1] = G[1, 0] = net.stage_base_w_per_k
    G[0, 2] = G[2, 0] = net.stage_air_w_per_k
    G[1, 2] = G[2, 1] = net.base_air_w_per_k
    to_room = np.array([0.0, net.base_room_w_per_k, net.air_room_w_per_k])
    C = np.array([net.stage_capacity_j_per_k, net.base_capacity_j_per_k, net.air_capacity_j_per_k])
    A = np.zeros((n, n))
    A[:3, :3] = (G - np.diag(G.sum(axis=1) + to_room)) / C[:, None]
    b = np.zeros(n)
    b[:3] = to_room / C
    for j, (tau, w) in enumerate(zip(net.thermocouple_tau_s, net.thermocouple_air_weight)):
        A[3 + j, 2] += w / tau
        A[3 + j, 1] += (1.0 - w) / tau
        A[3 + j, 3 + j] = -1.0 / tau
    return A, b


def network_bank(net: ThermalNetwork, room, *, earliest_s: float = 0.0) -> LinearBank:
    """The network's node temperatures (degC) driven by ``room``, on a 30 s exact grid; warmed
    up for ten of its slowest time constants so the start carries no transient."""
    A, b = network_matrices(net)
    slowest = 1.0 / np.min(np.abs(np.linalg.eigvals(A).real))
    return LinearBank(room, A, b, earliest_s=earliest_s, warmup_s=10.0 * slowest)
