"""Frames of several HP-code markers, rendered by calflow for tests and benchmarks.

Each marker is placed by its pose as a pattern is by :class:`~calflow.instruments.pattern.Camera`:
the marker point seen at the camera-plane point ``c`` (µm from the frame centre, y along the
rows) is ``(x, y) + R(−Θ) c``, so (x, y) are the frame centre's coordinates in the marker's
frame and the marker's x axis appears turned by Θ in the frame. The frame is the area each
pixel sees of the bright cells (``supersample``² points a pixel), blurred by the camera's
optics (a Gaussian of its diffraction and defocus; no illumination fall-off) and exposed with the camera's photometry and
noise (:meth:`Camera.expose`); the pixel size is the camera's.
"""

from __future__ import annotations

import math

import numpy as np

from calflow.instruments.pattern.hpcode.pattern import HPCodePattern
from calflow.instruments.pattern.render import Camera


def expectation(camera: Camera, pattern: HPCodePattern, markers, supersample: int = 4) -> np.ndarray:
    """The noise-free frame (DN, float32) of ``markers``: (number, x µm, y µm, Θ degree) each."""
    h, w, px = camera.height, camera.width, camera.pixel_um
    offsets = (np.arange(supersample) + 0.5) / supersample - 0.5
    cover = np.zeros((h, w), np.float32)
    ys = (np.arange(h) - (h - 1) / 2.0) * px
    xs = (np.arange(w) - (w - 1) / 2.0) * px
    for number, x, y, theta in markers:
        t = math.radians(theta)
        ct, st = math.cos(t), math.sin(t)
        reach = (pattern.half_periods + 2) * pattern.period_um / 2 * math.sqrt(2) / 2
        cx, cy = -(ct * x - st * y), -(st * x + ct * y)  # the marker's centre, camera plane
        rows = np.nonzero(np.abs(ys - cy) <= reach + px)[0]
        cols = np.nonzero(np.abs(xs - cx) <= reach + px)[0]
        if not len(rows) or not len(cols):
            continue
        Y, X = np.meshgrid(ys[rows], xs[cols], indexing="ij")
        part = np.zeros(X.shape, np.float32)
        for dy in offsets:
            for dx in offsets:
                Xs, Ys = X + dx * px, Y + dy * px
                u = x + ct * Xs + st * Ys
                v = y - st * Xs + ct * Ys
                part += pattern.cells(u, v, number)
        sub = cover[rows[0] : rows[-1] + 1, cols[0] : cols[-1] + 1]
        np.maximum(sub, part / supersample**2, out=sub)
    from scipy.ndimage import gaussian_filter

    # the camera's blur less the pixel's area, which the supersampling already integrates
    sigma_px = math.sqrt(max(camera.blur_sigma_um**2 - px * px / 12.0, 0.0)) / px
    cover = gaussian_filter(cover, sigma_px, mode="constant")
    level = np.float32(camera.background) + np.float32(camera.dot_level - camera.background) * cover
    return level * np.float32(camera.exposure * camera.max_level)


def render(camera: Camera, pattern: HPCodePattern, markers, rng=None, supersample: int = 4) -> np.ndarray:
    """One frame of ``markers`` with the camera's noise (``rng``: a seed or a Generator)."""
    rng = np.random.default_rng(rng)
    return camera.expose(expectation(camera, pattern, markers, supersample), rng)
