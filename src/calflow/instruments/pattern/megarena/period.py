"""The grid's period in the frame: where its fundamental lies, and the pixel size it gives."""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

MIN_PERIOD_PX = 3.0  # the shortest period (pixels) looked for
SUBHARMONIC_SHARE = 0.02  # a peak below the strongest is the fundamental from this share of its power
SUBHARMONIC_ABOVE = 100.0  # and this many times the band's median power (noise alone: a few)
SUBHARMONIC_TOL = 0.02  # relative: how near f/√2 its radius must be


def fundamental(spec: np.ndarray, h: int, w: int, depth: int) -> float | None:
    """The grid's fundamental (cycles per pixel) from the strongest peak of a frame's half-plane
    spectrum between periods of :data:`MIN_PERIOD_PX` and the one that still shows
    3·(depth + 1) periods across the frame.

    The strongest peak may be a harmonic: the diagonal one (1, 1) at √2·f₀, 45° from the
    fundamental (and from (2, 0) at 2·f₀, the diagonal's own diagonal) — when the fundamental's
    peak falls between bins and the code's rows and columns spread its power. So while a peak
    of at least :data:`SUBHARMONIC_SHARE` of the found one's power, and
    :data:`SUBHARMONIC_ABOVE` times the band's median, lies at f/√2 and ±45°, within
    :data:`SUBHARMONIC_TOL` of the radius and 5° of the direction, that peak is taken instead.
    Below a true fundamental nothing is there: the code's rows and columns put their spectrum
    on lines through the lattice's peaks along its axes (f_x or f_y a multiple of f₀), and the
    holes on multiples of f₀/3 — none at (f₀/2, f₀/2). (Along an axis, at f₀/2, the code's
    spectrum is: a peak there says nothing.)"""
    if spec.shape != (h, w // 2 + 1):
        raise ValueError(f"spec: expected a half-plane spectrum of shape {(h, w // 2 + 1)}, got {spec.shape}")
    flat, rad, ang, order, rad_sorted = _band(h, w, 3.0 * (depth + 1) / min(h, w))
    if len(rad) == 0:
        return None
    vals = np.ravel(spec).take(flat)  # one gather by flat index: a third of spec[rows, cols]'s time
    power = vals.real**2 + vals.imag**2
    k = int(np.argmax(power))
    if not power[k] > 0:
        return None
    f, a, p = float(rad[k]), float(ang[k]), float(power[k])
    floor = None
    for _ in range(2):  # (2, 0) → (1, 1) → (1, 0) at most
        # the bins within the radius's tolerance, from the band's radii in order (a few hundred
        # of its bins, not all), kept in the band's own order so that ties resolve as before
        reach = SUBHARMONIC_TOL * f / math.sqrt(2.0) + 1.0 / min(h, w)
        lo, hi = np.searchsorted(rad_sorted, [f / math.sqrt(2.0) - reach, f / math.sqrt(2.0) + reach])
        cand = np.sort(order[lo:hi])
        cand = cand[np.abs(rad[cand] - f / math.sqrt(2.0)) < reach]
        cand = cand[np.abs((ang[cand] - a) % 90.0 - 45.0) < 5.0]
        if len(cand) == 0:
            break
        j = int(cand[np.argmax(power[cand])])
        if power[j] < SUBHARMONIC_SHARE * p:  # below the share: no need of the median (1.5 ms)
            break
        if floor is None:  # the band's median power, only for a candidate above the share
            floor = SUBHARMONIC_ABOVE * float(np.median(power))
        if power[j] < floor:
            break
        f, a, p = float(rad[j]), float(ang[j]), float(power[j])
    return f


@lru_cache(maxsize=8)
def _band(h: int, w: int, lo: float):
    """Bins of a half-plane spectrum (h, w//2 + 1) between ``lo`` and 1/MIN_PERIOD_PX cycles per
    pixel — their flat indices in row order, radial frequency, direction (degree, −90 to 90) —
    the order of their radii and the radii in that order."""
    fi_signed = np.fft.fftfreq(h)[:, None]
    fi = np.abs(fi_signed)
    fj = np.fft.rfftfreq(w)[None, :]
    rad = np.hypot(fi, fj)
    rows, cols = np.nonzero((rad >= lo) & (rad <= 1.0 / MIN_PERIOD_PX))
    ang = np.degrees(np.arctan2(fi_signed[rows, 0], fj[0, cols]))
    rad = rad[rows, cols]
    order = np.argsort(rad, kind="stable")
    return rows * fj.shape[1] + cols, rad, ang, order, rad[order]


def pixel_size(p: float, K: np.ndarray, cov: np.ndarray, lobes) -> tuple[float, float]:
    """Pixel size (µm) = p · |k| per lobe (k in cycles per pixel), averaged over the two lobes,
    and its standard uncertainty from the slopes' covariance (rad per pixel)."""
    vals, var = [], []
    for k, lobe in zip(K, lobes):
        norm = float(np.hypot(*k))
        g = k / norm  # d|k|/dk
        var_k = float(g @ cov[lobe, 1:, 1:] @ g) / (2 * np.pi) ** 2
        vals.append(p * norm)
        var.append(p * p * var_k)
    return 0.5 * (vals[0] + vals[1]), 0.5 * math.sqrt(var[0] + var[1])
