"""ISO 9283 position stabilisation time and position overshoot (ISO 9283:1998, 7.5 and 7.6).

Both are read from a sampled record of the approach to one attained position (a high-rate
sensor stream, e.g. an interferometer at 1 kHz), with r(t) = |x(t) - P_a| the distance
of the record to the attained position P_a and B the half-width of the limit band around
it (the standard: the pose repeatability RP, or a band the manufacturer states):

* position stabilisation time (7.5): from the instant the record first enters the band
  (r <= B) to the instant from which it stays inside until the end of the record;
* position overshoot (7.6): OV = max r(t) after that first entry if it exceeds B, else 0
  (the record never leaves the band again).

The standard averages both over three cycles; do so over the results of each cycle.
Times in seconds (the unit of ``time``), lengths in the unit of the inputs; both are
resolved to the sampling period of the record.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .iso9283 import _finite

__all__ = ["StabilisationResult", "iso9283_stabilisation"]


@dataclass(frozen=True, eq=False)
class StabilisationResult:
    """Stabilisation time (s) and overshoot (input length unit) of one approach.

    Attributes
    ----------
    stabilisation_time_s : float
        Time from the first entry into the band to the start of the final stay inside
        (clause 7.5); NaN when the record never enters the band or ends outside it.
    overshoot : float
        Clause 7.6: largest distance to P_a after the first entry when it exceeds the band,
        else 0; NaN when the record never enters the band.
    max_excursion : float
        Largest distance to P_a after the first entry (whether or not beyond the band).
    entered_s, settled_s : float
        Time of the first entry and of the start of the final stay (NaN when undefined).
    stabilised : bool
        The record enters the band and ends inside it.
    """

    stabilisation_time_s: float
    overshoot: float
    max_excursion: float
    entered_s: float
    settled_s: float
    stabilised: bool


def iso9283_stabilisation(time, trajectory, attained, band) -> StabilisationResult:
    """Position stabilisation time (ISO 9283, 7.5) and overshoot (7.6) of one approach.

    Parameters
    ----------
    time : array_like (N,)
        Sample times in s, strictly increasing, N >= 2.
    trajectory : array_like (N, d), or (N,) for d = 1
        Measured positions along the approach and after it, any length unit, d in 1..3.
    attained : array_like (d,), or a scalar for d = 1
        The attained position P_a (e.g. the reading of the dwell), same unit.
    band : float
        Half-width B > 0 of the limit band around P_a, same unit.

    Returns
    -------
    StabilisationResult
        ``stabilisation_time_s`` in s and ``overshoot`` in the unit of the inputs.
    """
    t = _finite(np.asarray(time, dtype=float), "time")
    x = np.asarray(trajectory, dtype=float)
    if x.ndim == 1:
        x = x[:, None]
    if t.ndim != 1 or t.size < 2:
        raise ValueError(f"time must be a 1-D array of N >= 2 sample times; got shape {t.shape}")
    if np.any(np.diff(t) <= 0):
        raise ValueError("time must be strictly increasing")
    if x.ndim != 2 or x.shape[0] != t.size or x.shape[1] not in (1, 2, 3):
        raise ValueError(
            f"trajectory must have shape ({t.size}, d) with d in 1..3; got shape {np.shape(trajectory)}"
        )
    p = np.atleast_1d(np.asarray(attained, dtype=float))
    if p.shape != (x.shape[1],):
        raise ValueError(f"attained must have shape ({x.shape[1]},) to match trajectory; got shape {p.shape}")
    band = float(band)
    if not (np.isfinite(band) and band > 0):
        raise ValueError(f"band must be a finite half-width > 0; got {band!r}")
    _finite(x, "trajectory")
    _finite(p, "attained")

    r = np.sqrt(((x - p) ** 2).sum(axis=1))
    inside = r <= band
    nan = float("nan")
    if not inside.any():
        return StabilisationResult(nan, nan, nan, nan, nan, False)
    i_in = int(np.argmax(inside))
    excursion = float(r[i_in:].max())
    overshoot = excursion if excursion > band else 0.0
    if not inside[-1]:
        return StabilisationResult(nan, overshoot, excursion, float(t[i_in]), nan, False)
    outside = np.flatnonzero(~inside[i_in:])
    i_settle = i_in + (int(outside[-1]) + 1 if outside.size else 0)
    return StabilisationResult(
        stabilisation_time_s=float(t[i_settle] - t[i_in]),
        overshoot=overshoot,
        max_excursion=excursion,
        entered_s=float(t[i_in]),
        settled_s=float(t[i_settle]),
        stabilised=True,
    )
