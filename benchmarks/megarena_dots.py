"""The dots of a Megarena frame, located without either decoder's phase fit: calflow's coarse
lattice only numbers them and seeds the search (``lattice``); each is then a Gaussian-weighted
centroid iterated onto itself (``centroids``), on the frame less its smooth ``background``.
The witness (bench_megarena_witness.py) and the real-frame map (megarena_realmap.py) read them.
"""

from __future__ import annotations

import math

import numpy as np

from calflow.instruments.pattern.megarena.decode import _fitter
from calflow.instruments.pattern.megarena.period import fundamental

REGION = 0.5  # the central fraction of the width and height (the library's fit region)
MARGIN = 0.1  # dots this fraction of the frame beyond the library's region anchor the map at its edge


def lattice(frame: np.ndarray, depth: int, fields: bool = False):
    """calflow's coarse lattice: every node's indices (s, t) and pixel position, and the period
    in pixels. The dots are at the nodes, or at the cells' centres when they are dark. With
    ``fields``, also calflow's coarse sample points (n, 2) and each lobe's power |z|² there
    (2, n): lobe 0 is the lattice coordinate s, lobe 1 t."""
    h, w = frame.shape
    plan = _fitter(h, w, -116, 1)
    spec = plan.spectrum(frame[None].astype(np.float32))
    f0 = fundamental(spec[0], plan.h, plan.w, depth)  # the transform's size (padded)
    planes = _fitter(h, w, round(math.log(f0) / math.log(1.02)), 1).fit(spec)
    K, c = planes.freq[0], (planes.phase[0] / (2 * np.pi)) % 1.0
    rc = np.array([(w - 1) / 2, (h - 1) / 2])
    corners = np.array([[0, 0], [w - 1, 0], [0, h - 1], [w - 1, h - 1]], float) - rc
    st = corners @ K.T + c
    S, T = np.meshgrid(
        np.arange(math.floor(st[:, 0].min()) - 1, math.ceil(st[:, 0].max()) + 2),
        np.arange(math.floor(st[:, 1].min()) - 1, math.ceil(st[:, 1].max()) + 2),
    )
    s, t = S.ravel().astype(float), T.ravel().astype(float)
    at = lambda off: np.stack([s + off - c[0], t + off - c[1]], 1) @ np.linalg.inv(K).T + rc  # noqa: E731
    out = s, t, at(0.0), at(0.5), float(1 / np.mean(np.hypot(K[:, 0], K[:, 1])))
    if fields:
        z = planes.fields[0].astype(complex)
        pts = _fitter(h, w, round(math.log(f0) / math.log(1.02)), 1).coarse_points()
        inside = (pts[:, 0] < w) & (pts[:, 1] < h)  # a padded transform samples beyond the frame
        return (*out, pts[inside], (np.abs(z) ** 2)[:, inside])
    return out


def centroids(
    img: np.ndarray, xy: np.ndarray, period: float, iterations: int = 50, sigma_periods: float = 0.2
) -> np.ndarray:
    """Each dot's Gaussian-weighted centroid (σ a fifth of the period unless told) over the
    background (the window's 20th percentile), re-centred on itself until it moves less than
    1e-5 pixel. A symmetric dot's centroid does not depend on σ; an asymmetric one's does."""
    h, w = img.shape
    r = int(math.ceil(max(0.6, 2.5 * sigma_periods) * period))
    dy, dx = np.mgrid[-r : r + 1, -r : r + 1]
    sigma = sigma_periods * period
    p = xy.copy()
    for _ in range(iterations):
        ix, iy = np.rint(p[:, 0]).astype(int), np.rint(p[:, 1]).astype(int)
        X, Y = ix[:, None, None] + dx, iy[:, None, None] + dy
        patch = img[Y.clip(0, h - 1), X.clip(0, w - 1)]
        background = np.percentile(patch.reshape(len(p), -1), 20, axis=1)[:, None, None]
        g = np.exp(-((X - p[:, 0, None, None]) ** 2 + (Y - p[:, 1, None, None]) ** 2) / (2 * sigma**2))
        wt = np.clip(patch - background, 0, None) * g
        total = wt.sum(axis=(1, 2))
        new = np.stack([(wt * X).sum(axis=(1, 2)) / total, (wt * Y).sum(axis=(1, 2)) / total], 1)
        moved, p = np.nanmax(np.abs(new - p)), new
        if moved < 1e-5:
            break
    return p


def background(img: np.ndarray, period: float) -> np.ndarray:
    """The smooth background under bright dots: the frame's grey opening by a square of one
    period (which no dot, half a period wide, fits around: the gaps are kept, the dots cut
    off), smoothed by a Gaussian of one period. A centroid's own background (its window's 20th
    percentile) is a constant: a background that slopes across the window — the illumination's
    fall-off, a glare — pulls it uphill, and the lobes' phase (band-passed) does not see it."""
    from scipy.ndimage import gaussian_filter, grey_opening

    n = int(math.ceil(period)) | 1
    return gaussian_filter(grey_opening(img, size=(n, n)), period)


def dots(
    frame: np.ndarray, depth: int, region: float = REGION, flatten: bool = True, sigma_periods: float = 0.2
):
    """The dots within the central ``region`` of the frame's width and height (measured at the
    nodes calflow's coarse lattice predicts): their lattice indices s, t, centroids (n, 2), the
    period in pixels, and whether the dots are bright. ``flatten``: the centroids are taken on
    the frame less its smooth :func:`background` (without, a sloping background moves them)."""
    frame = frame.astype(float)
    h, w = frame.shape
    s, t, nodes, mids, period = lattice(frame, depth)
    rc = np.array([(w - 1) / 2, (h - 1) / 2])

    def value(xy):
        return frame[
            np.clip(np.rint(xy[:, 1]).astype(int), 0, h - 1), np.clip(np.rint(xy[:, 0]).astype(int), 0, w - 1)
        ]

    inside = np.all((nodes > period) & (nodes < np.array([w, h]) - 1 - period), axis=1)
    spread = lambda xy: np.ptp(np.percentile(value(xy[inside]), [10, 90]))  # noqa: E731
    if spread(mids) > spread(nodes):  # dark dots: at the cells' centres
        nodes = mids
    bright = bool(np.median(value(nodes[inside])) > np.median(frame))
    img = frame if bright else frame.max() - frame
    v = value(nodes) if bright else frame.max() - value(nodes)
    central = np.all(np.abs(nodes - rc) <= region * np.array([w, h]) / 2, axis=1)
    kept = inside & central & (v > 0.5 * (np.percentile(v[inside], 5) + np.percentile(v[inside], 95)))
    if flatten:
        img = img - background(img, period)
    c = centroids(img, nodes[kept], period, sigma_periods=sigma_periods)
    ok = np.isfinite(c).all(axis=1) & (np.hypot(*(c - nodes[kept]).T) < 0.25 * period)
    return s[kept][ok], t[kept][ok], c[ok], period, bright
