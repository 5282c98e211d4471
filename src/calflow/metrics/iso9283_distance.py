"""ISO 9283 distance accuracy AD and distance repeatability RD (ISO 9283:1998, clause 7.4).

Two command poses P_c1, P_c2 are visited in turn, n times (the standard: n = 10 cycles);
cycle j attains P_1j and P_2j.  With D_c = |P_c1 - P_c2| and D_j = |P_1j - P_2j|:

* distance accuracy (7.4.1): AD = D̄ - D_c, D̄ = (1/n) sum_j D_j — signed, positive when
  the attained distance is too long; per coordinate AD_c = D̄_c - D_cc with
  D_cj = x_1jc - x_2jc (signed differences, not their magnitudes);
* distance repeatability (7.4.2): RD = ±3 S_D, S_D = sqrt(sum_j (D_j - D̄)^2 / (n - 1));
  ``rd`` here is the half-width 3 S_D (>= 0).

Lengths in the unit of the inputs.  AD and RD depend only on distances, so they are
unchanged when both poses and every attained position undergo the same rigid motion.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .iso9283 import _pose_arrays, _readonly

__all__ = ["DistanceResult", "iso9283_distance"]


@dataclass(frozen=True, eq=False)
class DistanceResult:
    """AD and RD of one pair of command poses (unit of the inputs).

    Attributes
    ----------
    ad : float
        Distance accuracy AD = D̄ - D_c (signed), clause 7.4.1.
    rd : float
        Distance repeatability 3 S_D (the standard writes ±3 S_D), clause 7.4.2.
    ad_components : ndarray (d,)
        AD per coordinate, D̄_c - D_cc (signed differences P_1 - P_2).
    d_command : float
        Command distance D_c.
    d_attained : ndarray (n,)
        Attained distances D_j of each cycle.
    d_mean, s_d : float
        D̄ and S_D (n - 1 in the denominator).
    n : int
        Number of cycles.
    """

    ad: float
    rd: float
    ad_components: np.ndarray
    d_command: float
    d_attained: np.ndarray
    d_mean: float
    s_d: float
    n: int


def iso9283_distance(command_1, command_2, attained_1, attained_2) -> DistanceResult:
    """Distance accuracy AD and repeatability RD between two command poses (ISO 9283, 7.4).

    Parameters
    ----------
    command_1, command_2 : array_like (d,), or scalars for d = 1
        The two command poses P_c1 and P_c2, d = 1, 2 or 3, any length unit.
    attained_1, attained_2 : array_like (n, d), or (n,) for d = 1
        Positions attained at P_c1 and P_c2, row j of both from the same cycle j, n >= 2.
        Same unit as the commands.

    Returns
    -------
    DistanceResult
        ``ad`` = D̄ - D_c and ``rd`` = 3 S_D, in the unit of the inputs.

    Raises
    ------
    ValueError
        Bad shapes, unequal cycle counts or d, n < 2, or NaN/inf.
    """
    c1, a1 = _pose_arrays(command_1, attained_1)
    c2, a2 = _pose_arrays(command_2, attained_2)
    if a1.shape != a2.shape:
        raise ValueError(
            f"attained_1 {a1.shape} and attained_2 {a2.shape} must have the same shape: "
            "one row per cycle, both poses of a cycle in the same row"
        )
    d_cmd = float(np.linalg.norm(c1 - c2))
    d_j = np.linalg.norm(a1 - a2, axis=1)
    d_mean = float(d_j.mean())
    s_d = float(d_j.std(ddof=1))
    return DistanceResult(
        ad=d_mean - d_cmd,
        rd=3.0 * s_d,
        ad_components=_readonly((a1 - a2).mean(axis=0) - (c1 - c2)),
        d_command=d_cmd,
        d_attained=_readonly(d_j),
        d_mean=d_mean,
        s_d=s_d,
        n=int(d_j.size),
    )
