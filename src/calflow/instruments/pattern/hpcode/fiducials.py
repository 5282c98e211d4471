"""HP-code markers in a frame: their three QR-like fiducials found and grouped.

1. The frame is split at Otsu's threshold (the level that maximises the variance between the
   two classes of pixels) into bright and dark regions, for bright and for dark fiducials.
2. A fiducial is a connected region whose holes, filled, make a square about 7 half periods
   wide (its bounding box nearly square), of which the ring itself covers 24/49 (0.3–0.7
   accepted) and the square of the other class left inside it, around the same centre, holds
   a region of the ring's class covering 9/49 (0.08–0.3). Its centre is the filled square's
   centroid; its half period in pixels, u = √(area/49).
3. Three fiducials of one class and one size are one marker when two of them lie at the same
   distance, (2·size − 8)·u (±25 %), from the third at a right angle (±0.1 in cosine), the
   three seen clockwise on the screen as top, right, bottom (the image's y down), their sizes
   within 25 % of one another.
   Each fiducial belongs to one marker at most: the best-fitting triples are taken first.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

RING_SHARE = (0.3, 0.7)  # the ring's share of its filled square (24/49 drawn)
CORE_SHARE = (0.08, 0.3)  # the centre square's share (9/49 drawn)
MIN_WIDTH = 7  # pixels across a fiducial, at least
LEG_TOLERANCE = 0.25  # relative: fiducial spacing against the one the fiducials' size predicts
SQUARE_TOLERANCE = 0.1  # relative difference of the two legs, and |cos| of the angle between them


@dataclass(frozen=True)
class Fiducial:
    x: float  # pixel column of its centre
    y: float  # pixel row
    half_px: float  # its half period (pixels), from its area
    bright: bool


@dataclass(frozen=True)
class Triple:
    """One marker's fiducials: the corner one (top), then right and bottom (pixels, (x, y))."""

    top: np.ndarray
    right: np.ndarray
    bottom: np.ndarray
    bright: bool

    @property
    def centre(self) -> np.ndarray:
        return 0.5 * (self.right + self.bottom)


def otsu(frame: np.ndarray, bins: int = 256) -> float:
    """Otsu's threshold of a frame (the level splitting it into two classes of most variance)."""
    hist, edges = np.histogram(frame, bins)
    mid = 0.5 * (edges[:-1] + edges[1:])
    w0 = np.cumsum(hist, dtype=np.float64)
    w1 = w0[-1] - w0
    s = np.cumsum(hist * mid)
    m0 = s / np.maximum(w0, 1)
    m1 = (s[-1] - s) / np.maximum(w1, 1)
    return float(mid[np.argmax(w0 * w1 * (m0 - m1) ** 2)])


def find_fiducials(frame: np.ndarray) -> list[Fiducial]:
    """Every fiducial of either class in the frame (steps 1–2)."""
    from scipy import ndimage

    level = otsu(frame)
    found = []
    for bright in (True, False):
        binary = frame > level if bright else frame <= level
        labels, n = ndimage.label(binary)
        if n == 0:
            continue
        boxes = ndimage.find_objects(labels)
        area = np.bincount(labels.ravel(), minlength=n + 1)[1:]
        for i, box in enumerate(boxes):
            hh, ww = box[0].stop - box[0].start, box[1].stop - box[1].start
            if min(hh, ww) < MIN_WIDTH or max(hh, ww) > 1.3 * min(hh, ww):  # a square's box, any Θ
                continue
            if area[i] < RING_SHARE[0] * hh * ww / 2:  # thinner than any ring in such a box
                continue
            region = labels[box] == i + 1
            filled = ndimage.binary_fill_holes(region)
            f_area = int(filled.sum())
            if not RING_SHARE[0] < area[i] / f_area < RING_SHARE[1]:
                continue
            core = binary[box] & filled & ~region
            c_area = int(core.sum())
            if not CORE_SHARE[0] < c_area / f_area < CORE_SHARE[1]:
                continue
            cy, cx = ndimage.center_of_mass(filled)
            ky, kx = ndimage.center_of_mass(core)
            half = math.sqrt(f_area / 49.0)
            if math.hypot(cy - ky, cx - kx) > 0.7 * half:
                continue
            found.append(Fiducial(box[1].start + cx, box[0].start + cy, half, bright))
    return found


def group(fiducials: list[Fiducial], size: int) -> list[Triple]:
    """The markers of ``size`` dots a side the fiducials make (step 3)."""
    legs = 2 * size - 8  # half periods between the corner fiducial and each other one
    pts = np.array([[f.x, f.y] for f in fiducials]) if fiducials else np.zeros((0, 2))
    candidates = []
    n = len(fiducials)
    for t in range(n):
        for r in range(n):
            for b in range(n):
                if (
                    len({t, r, b}) < 3
                    or not fiducials[t].bright == fiducials[r].bright == fiducials[b].bright
                ):
                    continue
                vr, vb = pts[r] - pts[t], pts[b] - pts[t]
                if vr[0] * vb[1] - vr[1] * vb[0] <= 0:  # right, then bottom, clockwise on screen
                    continue
                lr, lb = math.hypot(*vr), math.hypot(*vb)
                sizes = [fiducials[i].half_px for i in (t, r, b)]
                half = float(np.mean(sizes))
                if max(sizes) > (1 + LEG_TOLERANCE) * min(sizes):
                    continue
                cos = abs(float(vr @ vb)) / (lr * lb)
                shape = abs(lr / lb - 1)
                scale = abs(0.5 * (lr + lb) / (legs * half) - 1)
                if shape > SQUARE_TOLERANCE or cos > SQUARE_TOLERANCE or scale > LEG_TOLERANCE:
                    continue
                candidates.append((shape + cos, (t, r, b)))
    used: set[int] = set()
    out = []
    for _, (t, r, b) in sorted(candidates):
        if used & {t, r, b}:
            continue
        used |= {t, r, b}
        out.append(Triple(pts[t].copy(), pts[r].copy(), pts[b].copy(), fiducials[t].bright))
    return out
