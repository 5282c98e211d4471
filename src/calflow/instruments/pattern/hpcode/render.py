"""Frames of several HP-code markers, rendered by calflow for tests and benchmarks.

Each marker is placed by its pose as a pattern is by :class:`~calflow.instruments.pattern.Camera`:
the marker point seen at the camera-plane point ``c`` (µm from the frame centre, y along the
rows) is ``(x, y) + R(−Θ) c``, so (x, y) are the frame centre's coordinates in the marker's
frame and the marker's x axis appears turned by Θ in the frame. The bright cells are blurred
by the camera's optics and pixel (:func:`expectation`; no illumination fall-off) and exposed
with the camera's photometry and noise (:meth:`Camera.expose`); the pixel size is the
camera's.
"""

from __future__ import annotations

import math

import numpy as np

from calflow.instruments.pattern.hpcode.pattern import HPCodePattern
from calflow.instruments.pattern.render import Camera


def expectation(camera: Camera, pattern: HPCodePattern, markers) -> np.ndarray:
    """The noise-free frame (DN, float32) of ``markers``: (number, x µm, y µm, Θ degree) each.

    Each bright cell (a square half a period wide, :meth:`HPCodePattern.cells`) seen through
    the camera's blur (a Gaussian of σ the camera's :attr:`~Camera.blur_sigma_um`: diffraction,
    defocus and the pixel's area) is, in the marker's own axes, the product of two differences
    of error functions, exact for any sub-pixel pose and any Θ::

        I(u, v) = Σ_cells ¼ [erf((u − a)/√2σ) − erf((u − b)/√2σ)] · [erf((v − c)/√2σ) − erf((v − d)/√2σ)]

    with [a, b] × [c, d] the cell; overlapping markers: the brighter wins."""
    from scipy.special import erf

    h, w, px = camera.height, camera.width, camera.pixel_um
    half = pattern.period_um / 2
    sigma = camera.blur_sigma_um
    k = 1.0 / (math.sqrt(2.0) * sigma)
    reach_cells = int(math.ceil(5.0 * sigma / half)) + 1
    n = pattern.half_periods
    centres = (np.arange(n) - (pattern.size - 1)) * half
    cover = np.zeros((h, w), np.float32)
    ys = (np.arange(h) - (h - 1) / 2.0) * px
    xs = (np.arange(w) - (w - 1) / 2.0) * px
    for number, x, y, theta in markers:
        bitmap = np.zeros((n + 2 * reach_cells, n + 2 * reach_cells), np.float32)
        bitmap[reach_cells:-reach_cells, reach_cells:-reach_cells] = pattern.cells(
            centres[None, :], centres[:, None], number
        )
        t = math.radians(theta)
        ct, st = math.cos(t), math.sin(t)
        extent = (n / 2 + reach_cells) * half * math.sqrt(2)
        cx, cy = -(ct * x - st * y), -(st * x + ct * y)  # the marker's centre, camera plane
        rows = np.nonzero(np.abs(ys - cy) <= extent + px)[0]
        cols = np.nonzero(np.abs(xs - cx) <= extent + px)[0]
        if not len(rows) or not len(cols):
            continue
        Y, X = np.meshgrid(ys[rows], xs[cols], indexing="ij")
        u = x + ct * X + st * Y
        v = y - st * X + ct * Y
        cu = (u + half / 2) / half + pattern.size - 1  # continuous cell coordinates
        cv = (v + half / 2) / half + pattern.size - 1
        c0, r0 = np.floor(cu).astype(np.int64), np.floor(cv).astype(np.int64)
        fu, fv = cu - c0, cv - r0  # position within the cell, in cells
        part = np.zeros(X.shape, np.float64)
        for dr in range(-reach_cells + 1, reach_cells):
            pv = 0.5 * (erf((fv - dr) * half * k) - erf((fv - dr - 1) * half * k))
            r = np.clip(r0 + dr + reach_cells, 0, bitmap.shape[0] - 1)
            for dc in range(-reach_cells + 1, reach_cells):
                pu = 0.5 * (erf((fu - dc) * half * k) - erf((fu - dc - 1) * half * k))
                c = np.clip(c0 + dc + reach_cells, 0, bitmap.shape[1] - 1)
                part += bitmap[r, c] * pu * pv
        sub = cover[rows[0] : rows[-1] + 1, cols[0] : cols[-1] + 1]
        np.maximum(sub, part.astype(np.float32), out=sub)
    level = np.float32(camera.background) + np.float32(camera.dot_level - camera.background) * cover
    return level * np.float32(camera.exposure * camera.max_level)


def render(camera: Camera, pattern: HPCodePattern, markers, rng=None) -> np.ndarray:
    """One frame of ``markers`` with the camera's noise (``rng``: a seed or a Generator)."""
    rng = np.random.default_rng(rng)
    return camera.expose(expectation(camera, pattern, markers), rng)
