"""ISO 9283 multi-directional pose accuracy variation vAP (ISO 9283:1998, clause 7.3).

The same command pose is approached from h = 1..H directions (the standard uses three,
n = 30 visits each); G_h is the barycentre of the positions attained from direction h:

    vAP = max_{h,k} sqrt(sum_c (x̄_hc - x̄_kc)^2),   c over the d coordinates,

the largest distance between the barycentres of two approach directions.  For a 1-DoF
stage the directions are the forward and backward approach, and vAP = |x̄↑ - x̄↓| (the
magnitude of the ISO 230-2 reversal value B_i at that target).  Lengths in the unit of
the inputs; the orientation part of the clause (vAP_a, vAP_b, vAP_c) has no counterpart
on a translation stage and is not computed.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .iso9283 import _finite, _readonly

__all__ = ["MultiDirectionalResult", "iso9283_vap"]


@dataclass(frozen=True, eq=False)
class MultiDirectionalResult:
    """vAP of one command pose (unit of the inputs).

    Attributes
    ----------
    vap : float
        Largest distance between the barycentres of two approach directions (clause 7.3).
    barycentres : ndarray (H, d)
        G_h, the mean attained position of each direction, in the order given.
    pair : tuple of int
        (h, k), the directions whose barycentres are farthest apart.
    n : tuple of int
        Number of attained positions per direction.
    """

    vap: float
    barycentres: np.ndarray
    pair: tuple[int, int]
    n: tuple[int, ...]


def _direction(a, h: int) -> np.ndarray:
    arr = np.asarray(a, dtype=float)
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2 or arr.shape[0] < 1 or arr.shape[1] not in (1, 2, 3):
        raise ValueError(
            f"direction {h}: attained must have shape (n, d) with n >= 1 and d in 1..3; "
            f"got shape {np.shape(a)}"
        )
    return _finite(arr, f"direction {h} attained")


def iso9283_vap(attained_by_direction: Sequence) -> MultiDirectionalResult:
    """Multi-directional pose accuracy variation vAP of one command pose (ISO 9283, 7.3).

    Parameters
    ----------
    attained_by_direction : sequence of H >= 2 arrays, each (n_h, d) or (n_h,) for d = 1
        Positions attained at the same command pose, one array per approach direction,
        n_h >= 1, all in one length unit and with the same d (1, 2 or 3).

    Returns
    -------
    MultiDirectionalResult
        ``vap`` = max over direction pairs of |G_h - G_k|, in the unit of the inputs.

    Raises
    ------
    ValueError
        Fewer than two directions, bad shapes, mixed d, or NaN/inf.
    """
    groups = [_direction(a, h) for h, a in enumerate(attained_by_direction)]
    if len(groups) < 2:
        raise ValueError(
            f"vAP needs attained positions from at least 2 approach directions; got {len(groups)}"
        )
    dims = {g.shape[1] for g in groups}
    if len(dims) != 1:
        raise ValueError(f"every direction must have the same number of coordinates d; got {sorted(dims)}")
    g = np.array([a.mean(axis=0) for a in groups])
    dist = np.sqrt(((g[:, None, :] - g[None, :, :]) ** 2).sum(axis=2))
    h, k = np.unravel_index(int(np.argmax(dist)), dist.shape)
    return MultiDirectionalResult(
        vap=float(dist[h, k]),
        barycentres=_readonly(g),
        pair=(int(min(h, k)), int(max(h, k))),
        n=tuple(int(a.shape[0]) for a in groups),
    )
