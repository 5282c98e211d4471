"""A real Megarena frame's own lattice distortion, carried onto calflow's camera.

The dots' polynomial lattice map of a frame (megarena_dots.dots, its degree by
megarena_estimand.cv_degree) M(p) = (s, t), p the pixel, is split into its best affine fit over
the dots, a + J·p, and its non-affine remainder N(p) = M(p) − a − J·p (periods). Outside the
dots' bounding box a polynomial of degree 4–7 runs away, so N is **clamped**: evaluated at p
clipped to that box (the affine part alone continues beyond it).

calflow's camera renders a square lattice: at a pose, the render's lattice coordinates are an
affine function of the pixel, A_r(q) = a_r + J_r·q (megarena's sites at integer (u, v)), a
similarity. The real frame's lattice is written in the render's labels, R·M(p) + k — R the
signed permutation of (s, t) nearest J_r, k the integer offset nearest the mean of
A_r(c) − R·st over the dots (the code in view is the one calflow's decoded pose puts there) —
and the render samples the camera's undistorted frame at

    q(p) = p + J_r⁻¹·(R·(a + J·p + N(clip(p))) + k − A_r(p))                         (1)

so that A_r(q(p)) = R·M(p) + k over the dots' box: the render's lattice is the real frame's as
its dots trace it, its shear included (the part of J that is not a similarity goes into q's
linear part, the camera being square), its curvature N, and its affine part's difference from
the decoded pose. The truth of such a render is Eq. (1)–(2) of megarena_estimand of A_r through
q, pixel by pixel — exact for the render, whatever the map's error on the real frame.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import megarena_dots
import megarena_estimand as me
import numpy as np


@dataclass
class RealLattice:
    """The dots' lattice of one frame: the map, its affine part and where the dots lie."""

    map: me.LatticeMap
    affine: np.ndarray  # (2, 3): per lattice coordinate (s, t), value at pixel (0, 0), ∂/∂x, ∂/∂y
    xy: np.ndarray  # (n, 2) the dots' centroids (pixels)
    st: np.ndarray  # (n, 2) their lattice indices
    box: tuple[float, float, float, float]  # x_min, x_max, y_min, y_max of the dots
    period_px: float
    bright: bool
    rms_affine_px: float  # the dots' rms distance from one lattice (pixels)
    rms_px: float  # from the map (pixels)
    outer: RealLattice | None = None  # a map of the whole frame's dots, for beyond the box

    def nonaffine(self, x, y) -> np.ndarray:
        """N(clip(p)) (periods, (..., 2)): the map less its affine part, clamped to the dots' box."""
        x0, x1, y0, y1 = self.box
        xc, yc = np.clip(x, x0, x1), np.clip(y, y0, y1)
        return self.map(xc, yc) - self._affine(xc, yc)

    def _affine(self, x, y) -> np.ndarray:
        a = self.affine
        return np.stack([a[j, 0] + a[j, 1] * x + a[j, 2] * y for j in (0, 1)], axis=-1)

    def __call__(self, x, y) -> np.ndarray:
        """The map within the dots' box; beyond it, without ``outer``, the affine part continued
        and the non-affine part clamped (``nonaffine``); with ``outer``, the map at the box's
        nearest point plus the outer map's change from that point, M(clip(p)) + M_o(p) −
        M_o(clip(p)) (continuous at the box's edge, the whole frame's curvature beyond it)."""
        x, y = np.asarray(x, float), np.asarray(y, float)
        if self.outer is None:
            return self._affine(x, y) + self.nonaffine(x, y)
        x0, x1, y0, y1 = self.box
        xc, yc = np.clip(x, x0, x1), np.clip(y, y0, y1)
        return self.map(xc, yc) + self.outer(x, y) - self.outer(xc, yc)


def real_lattice(
    frame: np.ndarray, depth: int, degree: int | None = None, region: float = 1.0
) -> RealLattice:
    """The dots of ``frame`` within the central ``region`` of its sides (1: the whole frame, less
    a period at the edges) and their polynomial map, of ``degree`` or the cross-validated one."""
    s, t, xy, period_px, bright = megarena_dots.dots(frame, depth, region=region)
    st = np.stack([s, t], 1)
    if degree is None:
        degree, _ = me.cv_degree(xy, st, frame.shape)
    m = me.fit_map(xy, st, degree, frame.shape)
    A = np.stack([np.ones(len(xy)), xy[:, 0], xy[:, 1]], 1)
    affine = np.linalg.lstsq(A, m(xy[:, 0], xy[:, 1]), rcond=None)[0].T
    one = np.linalg.lstsq(A, st, rcond=None)[0]
    rms = lambda r: float(np.sqrt((r**2).mean()) * period_px)  # noqa: E731
    return RealLattice(
        map=m,
        affine=affine,
        xy=xy,
        st=st,
        box=(xy[:, 0].min(), xy[:, 0].max(), xy[:, 1].min(), xy[:, 1].max()),
        period_px=period_px,
        bright=bright,
        rms_affine_px=rms(A @ one - st),
        rms_px=rms(m(xy[:, 0], xy[:, 1]) - st),
    )


def labels(real: RealLattice, render_affine: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """R (2, 2), the signed permutation of (s, t) whose gradients are nearest the render's, and
    k (2,), the integer offset putting the real dots on the render's sites (Eq. (1))."""
    J, Jr = real.affine[:, 1:], render_affine[:, 1:]
    candidates = []
    for perm in ((0, 1), (1, 0)):
        for signs in itertools.product((1, -1), repeat=2):
            R = np.zeros((2, 2))
            R[0, perm[0]], R[1, perm[1]] = signs
            candidates.append((float(np.linalg.norm(R @ J - Jr)), R))
    R = min(candidates, key=lambda c: c[0])[1]
    xy = real.xy
    at = render_affine[:, :1] + render_affine[:, 1:2] * xy[:, 0] + render_affine[:, 2:3] * xy[:, 1]
    k = np.rint(np.mean(at.T - real.st @ R.T, axis=0))
    return R, k


def real_warp(real: RealLattice, render_affine: np.ndarray):
    """Eq. (1): the map p ↦ q (pixel arrays) through which the camera's undistorted render of
    ``render_affine`` shows the real frame's lattice; also R and k."""
    R, k = labels(real, render_affine)
    ar, Jri = render_affine[:, 0], np.linalg.inv(render_affine[:, 1:])

    def q(x, y):
        x, y = np.asarray(x, float), np.asarray(y, float)
        target = real(x, y) @ R.T + k  # (..., 2) in the render's labels
        own = ar + np.stack([x, y], axis=-1) @ render_affine[:, 1:].T
        dq = (target - own) @ Jri.T
        return x + dq[..., 0], y + dq[..., 1]

    return q, R, k


def shear_deg(affine: np.ndarray) -> float:
    """How far a lattice's two axes in the frame are from square (degree): its shear."""
    g = np.linalg.inv(affine[:, 1:])  # columns: the pixel steps of one period along s and t
    c = g[:, 0] @ g[:, 1] / (np.linalg.norm(g[:, 0]) * np.linalg.norm(g[:, 1]))
    return 90.0 - math.degrees(math.acos(abs(c)))


def envelope(img: np.ndarray, period_px: float) -> tuple[np.ndarray, np.ndarray]:
    """A frame's background and dot-top fields (its level's units): the minimum (maximum) over
    a period, averaged over three periods — what illumination, halo and glare make of the
    frame's levels, slowly varying, without the dots."""
    from scipy.ndimage import maximum_filter, minimum_filter, uniform_filter

    n = max(int(round(period_px)), 1)
    img = np.asarray(img, float)
    return uniform_filter(minimum_filter(img, n), 3 * n), uniform_filter(maximum_filter(img, n), 3 * n)


def relight(expected: np.ndarray, real: np.ndarray, period_px: float, scale: float) -> np.ndarray:
    """The render's expected frame carried onto the real frame's background B and dot tops T
    (``envelope`` of each, the real one times ``scale`` to the render's levels):
    B + (T − B)·(E − b)/(t − b), b and t the render's own fields — the real frame's light, the
    render's dots."""
    b, t = envelope(expected, period_px)
    B, T = envelope(real, period_px)
    out = scale * (B + (T - B) * (expected - b) / np.maximum(t - b, 1e-6))
    return np.clip(out, 0, None).astype(np.float32)
