"""The windowed frame's half-plane spectrum, its geometry: the Tukey window and where it
tapers, the bins' radii and directions (sorted once per frame size), a ring of bins around a
frequency, the corners beyond 0.4 cycle per pixel, FFT lengths, a peak's sub-bin position —
and the reused arrays a decoder of single frames windows them in. What depends on the frame's
size only, so that a plan for a new pixel size
(:class:`~calflow.instruments.pattern.phase.PhaseFitter`) costs a search rather than a pass
over the spectrum."""

from __future__ import annotations

import math
import threading
from functools import lru_cache

import numpy as np

RING = (0.8, 1.2)  # the lobe is searched between these fractions of the expected frequency
TUKEY = 0.2  # fraction of each side tapered by the window

_scratch = threading.local()  # :func:`scratch`'s arrays, one set per thread


def scratch(shape: tuple[int, ...], name: str) -> np.ndarray:
    """A float32 array of ``shape`` kept for reuse in this thread under ``name`` (its values
    are whatever its last user left). A frame's worth of new memory on every frame costs its
    pages' faults (a few tenths of a millisecond per 3 MB): a decoder of single frames reuses one array."""
    kept = _scratch.__dict__
    a = kept.get(name)
    if a is None or a.shape != tuple(shape):
        a = kept[name] = np.empty(shape, np.float32)
    return a


def tukey(n: int, alpha: float = TUKEY) -> np.ndarray:
    """The Tukey (tapered cosine) window of n samples, float32 (Harris, Proc. IEEE 66, 1978):
    w(x) = ½·(1 − cos(2π·d/α)) where d = min(x, 1 − x) < α/2, else 1, at x = k/(n − 1).

    The same window as ``scipy.signal.windows.tukey(n, alpha)`` (the tests check it), written
    here because importing scipy.signal costs every decoding process over a second of CPU."""
    if n == 1:
        return np.ones(1, np.float32)
    x = np.arange(n) / (n - 1)
    d = np.minimum(x, 1.0 - x)
    if alpha <= 0:
        return np.ones(n, np.float32)
    taper = d < alpha / 2
    w = np.ones(n)
    w[taper] = 0.5 * (1.0 - np.cos(2 * np.pi * d[taper] / min(alpha, 1.0)))
    return w.astype(np.float32)


@lru_cache(maxsize=4)
def window(h: int, w: int) -> np.ndarray:
    """The frame's Tukey window (h, w), one per frame size (plans of one size share it)."""
    return tukey(h, TUKEY)[:, None] * tukey(w, TUKEY)[None, :]


@lru_cache(maxsize=4)
def tapered(h: int, w: int) -> tuple[tuple[slice, slice], ...]:
    """The parts of an h × w frame where :func:`window` is not exactly 1, as (rows, columns)
    slices: the top and bottom bands, and the left and right ones between them (multiplying
    the rest by 1 changes nothing)."""
    flat_rows = np.flatnonzero(tukey(h, TUKEY) == 1)
    flat_cols = np.flatnonzero(tukey(w, TUKEY) == 1)
    if len(flat_rows) == 0 or len(flat_cols) == 0:
        return ((slice(None), slice(None)),)
    r0, r1 = int(flat_rows[0]), int(flat_rows[-1]) + 1
    c0, c1 = int(flat_cols[0]), int(flat_cols[-1]) + 1
    if len(flat_rows) != r1 - r0 or len(flat_cols) != c1 - c0:  # not one run: the whole frame
        return ((slice(None), slice(None)),)
    mid = slice(r0, r1)
    return (slice(0, r0), slice(None)), (slice(r1, h), slice(None)), (mid, slice(0, c0)), (mid, slice(c1, w))


def ring(h: int, w: int, f0: float):
    """The bins (rows, columns, in row order) of a half-plane spectrum of h × w pixels between
    RING[0]·f0 and RING[1]·f0 cycles per pixel, the half of the j = 0 column with negative row
    frequencies left out (it mirrors the other half), and each bin's direction (degree).

    The bins come from the spectrum's radii sorted once per frame size (:func:`radii`): a plan
    for a new frequency — a new pixel size — costs a search and the ring's own bins."""
    flat, rad, angle = radii(h, w)
    lo = np.searchsorted(rad, RING[0] * f0, side="right")  # strictly inside the ring
    hi = np.searchsorted(rad, RING[1] * f0, side="left")
    mask = np.zeros(h * (w // 2 + 1), bool)  # back to row order: a scatter, not a sort
    mask[flat[lo:hi]] = True
    bins = np.flatnonzero(mask)
    ri, rj = np.divmod(bins, w // 2 + 1)
    return ri, rj, angle[bins]


@lru_cache(maxsize=4)
def radii(h: int, w: int):
    """Every bin of a half-plane spectrum of h × w pixels but the mirrored half of the j = 0
    column (negative row frequencies): the flat indices (row order within equal radii) sorted
    by radius (cycles per pixel), and the radii; and every bin's direction (degree), by flat
    index."""
    fi = np.fft.fftfreq(h)[:, None]
    fj = np.fft.rfftfreq(w)[None, :]
    rad = np.hypot(fi, fj)
    keep = np.flatnonzero(~((fj == 0) & (fi < 0)))
    r = rad.ravel()[keep]
    order = np.argsort(r, kind="stable")
    angle = np.degrees(np.arctan2(fi, fj)).ravel()
    return keep[order], r[order], angle


def corners(h: int, w: int):
    """The spectrum's corners beyond 0.4 cycle per pixel along both axes, as (rows, columns)
    slices of a half-plane spectrum of h × w pixels — the rows are one run (the middle of the
    FFT's order), the columns the last — or None when the frame is too small to have them."""
    rows = np.flatnonzero(np.abs(np.fft.fftfreq(h)) > 0.4)
    cols = np.flatnonzero(np.fft.rfftfreq(w) > 0.4)
    if len(rows) == 0 or len(cols) == 0:
        return None
    return slice(int(rows[0]), int(rows[-1]) + 1), slice(int(cols[0]), None)


def fast_length(n: int) -> int:
    """The next length at or above n whose factors are 2, 3, 5, 7 and 11 (fast in pocketfft)."""
    import scipy.fft  # here, not at import: the camera model's users need no scipy

    return scipy.fft.next_fast_len(int(n), real=False)


def on_flat(x: np.ndarray, n: int, alpha: float = TUKEY) -> np.ndarray:
    """Whether pixel positions ``x`` (continuous) of a side of n pixels lie on the flat part
    of :func:`tukey`'s window, w = 1, rather than on its taper."""
    t = np.asarray(x, float) / max(n - 1, 1)
    return np.minimum(t, 1.0 - t) >= alpha / 2


def subbin(mag: np.ndarray, ci: int, cj: int) -> tuple[float, float]:
    """Gaussian (log-parabolic) interpolation of a spectral peak at (ci, cj) of ``mag``."""
    out = []
    for m1, m0, p1 in (
        (mag[ci - 1, cj], mag[ci, cj], mag[ci + 1, cj]),
        (mag[ci, cj - 1], mag[ci, cj], mag[ci, cj + 1]),
    ):
        a, b, c = (math.log(max(float(v), 1e-30)) for v in (m1, m0, p1))
        den = a - 2 * b + c
        out.append(0.0 if den >= 0 else max(-0.5, min(0.5, 0.5 * (a - c) / den)))
    return out[0], out[1]
