"""Steps 7–9 of the decoding, the small pieces: sampling the frame at the grid's nodes, each
node's contrast over the local contrast of the frame dots, the majority vote of a code's bits
and the place of a reading in its code (module :mod:`.decode` puts them together)."""

from __future__ import annotations

import numpy as np


def bilinear(img: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Bilinear interpolation of ``img`` at pixel positions (x along columns), edges clamped."""
    h, w = img.shape
    x = np.clip(x, 0, w - 1.001)
    y = np.clip(y, 0, h - 1.001)
    j = x.astype(np.intp)
    i = y.astype(np.intp)
    fx = (x - j).astype(np.float32)
    fy = (y - i).astype(np.float32)
    flat = img.ravel()
    k = i * w + j
    top = flat[k] * (1 - fx) + flat[k + 1] * fx
    bottom = flat[k + w] * (1 - fx) + flat[k + w + 1] * fx
    return top * (1 - fy) + bottom * fy


def percentile(a: np.ndarray, q):
    """``np.percentile(a, q)`` of a 1-D array without NaN — its default (linear) method, value
    and type alike (the tests check it bit for bit) — from one partition at the two order
    statistics each percentile lies between: numpy's also places the smallest and largest
    element, which on a frame's nodes costs twice the time. ``a`` is reordered in place."""
    a = np.asarray(a)
    n = a.size
    if n == 0 or a.ndim != 1 or a.dtype.kind != "f" or np.isnan(a).any():
        return np.percentile(a, q)
    weak = type(q) in (int, float)
    v = (n - 1) * np.true_divide(q, 100, out=...)  # the rank, as numpy's "linear" method
    below = np.floor(v, out=...)
    below[v >= n - 1] = n - 1  # at or past the last: the largest (numpy: index −1)
    below[v < 0] = 0
    lo = below.astype(np.intp)
    hi = np.minimum(lo + 1, n - 1)
    a.partition(np.unique(np.concatenate((lo.ravel(), hi.ravel()))))
    gamma = np.asanyarray(v - np.where(v >= n - 1, -1, lo), dtype=v.dtype)
    if weak:
        gamma = float(gamma)
    left, right = a[lo], a[hi]
    diff = right - left  # numpy's interpolation (its _lerp), from whichever end is nearer
    out = np.add(left, diff * gamma, out=...)
    np.subtract(
        right, diff * (1 - gamma), out=out, where=gamma >= 0.5, casting="unsafe", dtype=type(out.dtype)
    )
    return out[()] if out.ndim == 0 else out


def dilate3(mask: np.ndarray) -> np.ndarray:
    """A 2-D boolean mask grown by one element in the eight directions (a 3 × 3 block, nothing
    beyond the edge): ``scipy.ndimage.binary_dilation(mask, np.ones((3, 3)))``, in a few slices."""
    return _block3(mask, False, np.logical_or)


def erode3(mask: np.ndarray) -> np.ndarray:
    """A 2-D boolean mask shrunk by one element in the eight directions (a 3 × 3 block, the
    outside counted as set): ``scipy.ndimage.binary_erosion(mask, np.ones((3, 3)), border_value=1)``."""
    return _block3(mask, True, np.logical_and)


def _block3(mask, outside: bool, op) -> np.ndarray:
    padded = np.pad(np.asarray(mask, bool), 1, constant_values=outside)
    h, w = padded.shape[0] - 2, padded.shape[1] - 2
    out = padded[1 : h + 1, 1 : w + 1].copy()
    for di in range(3):
        for dj in range(3):
            if di != 1 or dj != 1:
                op(out, padded[di : di + h, dj : dj + w], out=out)
    return out


def normalised(contrast: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Contrast over the local mean contrast of the nodes in ``mask`` (7 × 7 nodes around), the
    local mean kept above a third of the frame's median (so that where the dots fade out —
    heavy dust, beyond the pattern's edge — noise is not scaled up into dots)."""
    if not mask.any():
        return np.full(contrast.shape, np.nan)
    from scipy import ndimage  # here, not at import: the camera model's users need no scipy

    num = ndimage.uniform_filter(np.where(mask, contrast, 0.0), size=7, mode="constant")
    den = ndimage.uniform_filter(mask.astype(float), size=7, mode="constant")
    floor = np.median(contrast[mask]) / 3.0
    level = np.where(den > 0.02, num / np.maximum(den, 1e-12), floor)
    with np.errstate(invalid="ignore", divide="ignore"):
        return contrast / np.maximum(level, floor)


def votes(cells: np.ndarray, present: np.ndarray):
    """Majority vote per cell: (first cell, bits, sure mask) over the cells present in the frame."""
    if len(cells) == 0:
        return 0, np.zeros(0, np.int8), np.zeros(0, bool)
    c0 = int(cells.min())
    idx = cells - c0
    n = np.bincount(idx)
    ones = np.bincount(idx, weights=present.astype(float), minlength=len(n))
    frac = np.where(n > 0, ones / np.maximum(n, 1), 0.5)
    sure = (n >= 3) & (np.minimum(frac, 1 - frac) <= 0.2)  # three votes at least, four in five agree
    return c0, (frac > 0.5).astype(np.int8), sure


def match(reading, code: np.ndarray):
    """Best place of a reading in the code: (wrong bits, cell offset, next-best wrong bits, bits used)."""
    c0, bits, sure = reading
    nsure = int(sure.sum())
    if nsure:  # the cells before the first sure bit and after the last one are not read
        first, last = np.flatnonzero(sure)[[0, -1]]
        c0, bits, sure = c0 + int(first), bits[first : last + 1], sure[first : last + 1]
    L = len(code)
    if len(bits) == 0 or len(bits) > L or nsure == 0:
        return (10**6, 0, 10**6, nsure)
    o = np.where(sure, 2.0 * bits - 1.0, 0.0)
    a = 2.0 * code.astype(float) - 1.0
    corr = np.correlate(a, o, mode="valid")  # corr[j]: reading's first cell at code index j
    wrong = (nsure - corr) / 2.0
    j = int(np.argmin(wrong))
    best = int(round(wrong[j]))
    rest = np.delete(wrong, j)
    second = int(round(rest.min())) if len(rest) else 10**6
    return (best, j - c0, second, nsure)
