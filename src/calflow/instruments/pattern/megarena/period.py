"""The grid's period in the frame: where its fundamental lies, and the pixel size it gives."""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

MIN_PERIOD_PX = 3.0  # the shortest period (pixels) looked for


def fundamental(spec: np.ndarray, h: int, w: int, depth: int) -> float | None:
    """The grid's fundamental (cycles per pixel) from the strongest peak of a frame's half-plane
    spectrum between periods of :data:`MIN_PERIOD_PX` and the one that still shows
    3·(depth + 1) periods across the frame."""
    rows, cols, rad = _band(h, w, 3.0 * (depth + 1) / min(h, w))
    if len(rad) == 0:
        return None
    vals = spec[rows, cols]
    power = vals.real**2 + vals.imag**2
    k = int(np.argmax(power))
    return float(rad[k]) if power[k] > 0 else None


@lru_cache(maxsize=8)
def _band(h: int, w: int, lo: float):
    """Bins (rows, columns) of a half-plane spectrum between ``lo`` and 1/MIN_PERIOD_PX cycles
    per pixel, and their radial frequency."""
    fi = np.abs(np.fft.fftfreq(h))[:, None]
    fj = np.fft.rfftfreq(w)[None, :]
    rad = np.hypot(fi, fj)
    rows, cols = np.nonzero((rad >= lo) & (rad <= 1.0 / MIN_PERIOD_PX))
    return rows, cols, rad[rows, cols]


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
