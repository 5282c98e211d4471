"""One HP-code marker's pose in a frame: its grid's phase planes around its fiducials, its
number read from its first row of dots.

From the three fiducials (:mod:`.fiducials`) come the marker's centre, the directions of its
x and y axes and its period in pixels — coarse, to a fraction of a period. The fine pose is
the shared phase part (:class:`~calflow.instruments.pattern.phase.PhaseFitter`, thesis
Sec. 3.5.1 steps 2–6) run on a square of the frame around the marker, faded out beyond a
period from its outer dots, its planes refitted on the samples inside the marker's grid only
(half a period in from its outer dots, the corners' fiducials left out), so that what lies
beside the marker does not pull them. Near the grid's edge the lobe's field falls, and its
phase bends there: the band-pass's Gaussian (phase.py: σ = GAUSS / (2π·CROP)) is about 1.1
periods wide in the frame, and the dots' transfer function is not even about the lobe, so
the falling envelope shifts the phase by c·∇ln|z| (phase.py, "The code's envelope"): a plain
plane fit on samples one period in read a rendered marker's pixel size 1.3–3·10⁻⁴ small and
Θ up to 77 µrad off. The planes are therefore fitted with the code's envelope regressors
(``ENVELOPE``), which model that bend — on calflow's noise-free renders the pixel size within
2·10⁻⁵, Θ within 4 µrad, x and y within 0.2 nm, at any edge distance from two periods in to
half a period out — and so the refit can come nearer the edge. How near is set by what lies
beside a marker: with another marker's dots one period beyond its own, samples on or beyond
the outer dots are pulled (150 µrad, 17 nm), half a period in they are not pulled more than a
plain fit one period in (34 against 87 µrad). Half a period in (``EDGE = 0.5``), on a lab's
real sequence (the Vernier library's Image140) a fixed marker's pixel size scatters
0.62·10⁻⁴ from frame to frame instead of 0.83·10⁻⁴ and its pose 0.130 µm instead of
0.135 µm in y (docs/benchmarks.md, "The code's envelope in a marker's refit").

With ``K`` the 2 × 2 matrix of the two lobes' spatial frequencies (cycles per pixel; rows
along the marker's x and y axes) and ``φ`` their phases (radian) at the crop centre ``r₀``,
the lattice coordinates of a pixel r are

    ℓ(r) = φ / 2π + K (r − r₀)                                          (cycles),

dots on integer ℓ (bright dots; dark dots on half-integers). The marker's centre dot is the
integer node nearest the fiducials' centre — unless they disagree by more than a quarter
period, when the marker is not trusted ("ambiguous") — and the marker coordinates of the
frame centre F are ``(x, y) = p · (ℓ(F) − node)`` µm, p the period. Θ is the direction of the
marker's x axis in the frame (its lobe and the y lobe turned back by 90°, weighted by their
variances), the pixel size ``p · |k|`` of the two lobes averaged; the standard uncertainties
are the planes' fit's, propagated to F (``aᵀ C a``, a = (1, F − r₀) in pixels), and to the
centre dot for the relative poses.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from calflow.instruments.pattern.bits import bilinear
from calflow.instruments.pattern.decode import _angle
from calflow.instruments.pattern.hpcode.fiducials import Triple
from calflow.instruments.pattern.hpcode.pattern import HPCodePattern
from calflow.instruments.pattern.megarena.period import pixel_size
from calflow.instruments.pattern.phase import PhaseFitter

MIN_PEAK_RATIO = 30.0  # a lobe's power over the ring's median around a marker
MAX_CENTRE_OFFSET = 0.25  # periods between the fiducials' centre and the nearest dot
MAX_PERIOD_MISMATCH = 0.05  # a given pixel size and the period the fiducials show
CORNER = 4.0  # periods: the corners' fiducials are left out of the fit, as far in
EDGE = 0.5  # periods: the refit's samples lie this far in from the outer dots (module docstring)
ENVELOPE = True  # the planes fitted with the envelope's regressors (module docstring)
BIT_UNSURE = (0.3, 0.7)  # a number dot's contrast over the full dots' that reads as neither


def marker_pose(frame: np.ndarray, triple: Triple, pattern: HPCodePattern, given_pixel: float | None) -> dict:
    """The pose of the marker ``triple`` marks in ``frame`` (float32): a dict with ``status``,
    ``reason`` and, when "ok", ``number``, x, y, Θ, their uncertainties, the pixel sizes and
    the centre dot's pixel position (module docstring)."""
    p, size = pattern.period_um, pattern.size
    h, w = frame.shape
    ex = triple.right - triple.top
    ey = triple.bottom - triple.top
    per_px = 0.5 * (math.hypot(*ex) + math.hypot(*ey)) / pattern.fiducial_spacing
    ex, ey = ex / math.hypot(*ex), ey / math.hypot(*ey)
    # the fiducials' own direction of the x axis (the mean of x and y turned back by 90°): a
    # coarse witness of Θ that owes nothing to the phase planes
    th_f = math.degrees(math.atan2(ex[1] - ey[0], ex[0] + ey[1]))
    if given_pixel is not None and abs(p / given_pixel / per_px - 1) > MAX_PERIOD_MISMATCH:
        return _fail(
            "no_lobes",
            f"the marker's fiducials are {per_px:.3g} pixels a period apart; at {given_pixel:g} µm "
            f"per pixel the pattern's {p:g} µm period is {p / given_pixel:.3g} (is the pixel size right?)",
        )
    c = triple.centre
    half = int(math.ceil(0.5 * math.sqrt(2) * (size + 1) * per_px))
    x0, y0 = max(0, int(round(c[0])) - half), max(0, int(round(c[1])) - half)
    x1, y1 = min(w, int(round(c[0])) + half), min(h, int(round(c[1])) + half)
    if min(x1 - x0, y1 - y0) < 8 * per_px:
        return _fail("fov_too_small", "the marker is cut by the frame's edge")
    # what lies beside the marker (another marker, a mechanism's edges) is faded out before the
    # transform: the crop is kept within a period of the marker's outer dots, tapered over one
    # more, and filled beyond with the marker's mean level
    yy, xx = np.mgrid[y0:y1, x0:x1]
    dx, dy = xx - c[0], yy - c[1]
    reach = np.maximum(np.abs(dx * ex[0] + dy * ex[1]), np.abs(dx * ey[0] + dy * ey[1])) / per_px
    fade = np.clip((size - 1) / 2 + 2.0 - reach, 0.0, 1.0).astype(np.float32)
    crop = frame[y0:y1, x0:x1]
    level = float(np.sum(crop * fade) / max(float(fade.sum()), 1.0))
    crop = level + (crop - level) * fade
    fitter = _fitter(y1 - y0, x1 - x0, round(math.log(1.0 / per_px) / math.log(1.02)), ENVELOPE)
    planes = fitter.fit(fitter.spectrum(crop[None]))
    ratio = planes.peak_ratio[0]
    if not ratio.min() >= MIN_PEAK_RATIO:
        return _fail("no_lobes", f"no dot grid between the marker's fiducials (lobe/ring {ratio.min():.0f})")
    r0 = np.array([x0 + fitter.xc, y0 + fitter.yc])
    pts = fitter.coarse_points() + [x0, y0] - c
    lim = (size - 1) / 2 - EDGE
    ax, ay = np.abs(pts @ ex) / per_px, np.abs(pts @ ey) / per_px
    keep = (ax <= lim) & (ay <= lim) & ~((ax > lim - CORNER) & (ay > lim - CORNER))
    if keep.sum() < 16:
        return _fail("fov_too_small", "fewer than 16 phase samples inside the marker")
    phase, freq, cov = fitter.refit(planes, 0, keep)
    if not (np.isfinite(phase).all() and np.isfinite(cov).all()):
        return _fail("no_lobes", "the marker's phase planes could not be fitted")
    ix = int(np.argmax(np.abs(freq @ ex)))
    iy = 1 - ix
    sx, sy = np.sign(freq[ix] @ ex), np.sign(freq[iy] @ ey)
    if sx == 0 or sy == 0 or abs(freq[iy] @ ex) > abs(freq[iy] @ ey):
        return _fail("no_lobes", "the grid's lobes do not follow the marker's fiducials")
    K = np.array([sx * freq[ix], sy * freq[iy]])
    frac = np.array([sx * phase[ix], sy * phase[iy]]) / (2 * np.pi)
    if not triple.bright:  # dark dots: the fundamental's phase is π on them
        frac = frac + 0.5
    at_centre = frac + K @ (c - r0)
    node = np.round(at_centre)
    offset = at_centre - node
    if np.abs(offset).max() > MAX_CENTRE_OFFSET:
        return _fail(
            "ambiguous",
            f"the fiducials put the marker's centre {np.abs(offset).max():.2f} period from the nearest dot",
        )
    node_px = r0 + np.linalg.solve(K, node - frac)
    number, why = _number(frame, node_px, K, pattern, triple.bright)
    if number is None:
        return _fail("code_mismatch", why)
    F = np.array([(w - 1) / 2.0, (h - 1) / 2.0])
    xy = p * (K @ (F - node_px))
    a = np.array([1.0, *(F - r0)])
    u_xy = [p * math.sqrt(max(float(a @ cov[i] @ a), 0.0)) / (2 * np.pi) for i in (ix, iy)]
    a = np.array([1.0, *(node_px - r0)])
    u_c = [p * math.sqrt(max(float(a @ cov[i] @ a), 0.0)) / (2 * np.pi) for i in (ix, iy)]
    th_x, var_x = _angle(K[0], cov[ix], 1.0)
    th_y, var_y = _angle(K[1], cov[iy], 1.0)
    d = ((th_y - 90.0) - th_x + 180.0) % 360.0 - 180.0
    wsum = 1 / var_x + 1 / var_y
    theta = (th_x + d * (1 / var_y) / wsum + 180.0) % 360.0 - 180.0
    pix, u_pix = pixel_size(p, K, cov, (ix, iy))
    return {
        "status": "ok",
        "reason": "decoded",
        "number": number,
        "x_um": float(xy[0]),
        "y_um": float(xy[1]),
        "theta_deg": float(theta),
        "u_x_um": u_xy[0],
        "u_y_um": u_xy[1],
        "u_theta_deg": math.sqrt(1 / wsum),
        "pixel_um": pix,
        "u_pixel_um": u_pix,
        "theta_x_deg": th_x,
        "pixel_x_um": p * float(np.hypot(*K[0])),
        "theta_y_deg": th_y,
        "pixel_y_um": p * float(np.hypot(*K[1])),
        "centre_x_px": float(node_px[0]),
        "centre_y_px": float(node_px[1]),
        "u_centre_x_um": u_c[0],
        "u_centre_y_um": u_c[1],
        "theta_fiducials_deg": th_f,
        "centre_fiducials_x_px": float(c[0]),
        "centre_fiducials_y_px": float(c[1]),
    }


def _number(frame, node_px, K, pattern: HPCodePattern, bright: bool):
    """The marker's number from its first row of dots, against the three rows below it (always
    full); (None, reason) when a dot is neither clearly there nor clearly missing."""
    m = (pattern.size - 1) // 2
    Kinv = np.linalg.inv(K)
    cols = pattern.number_columns() - m

    def contrast(lx, ly):
        lx, ly = np.asarray(lx, float), np.asarray(ly, float)
        at = lambda dx, dy: bilinear(frame, *(node_px[:, None] + Kinv @ np.stack([lx + dx, ly + dy])))  # noqa: E731
        gaps = 0.25 * (at(0.5, 0.5) + at(-0.5, 0.5) + at(0.5, -0.5) + at(-0.5, -0.5))
        return (at(0.0, 0.0) - gaps) * (1.0 if bright else -1.0)

    full = contrast(np.tile(cols, 3), np.repeat(np.arange(1, 4) - m, len(cols)))
    level = float(np.median(full))
    if not level > 0:
        return None, "the marker's dots show no contrast where its number is read"
    z = contrast(cols, np.full(len(cols), -m)) / level
    unsure = (z > BIT_UNSURE[0]) & (z < BIT_UNSURE[1])
    if unsure.any():
        return None, f"{int(unsure.sum())} dot(s) of the marker's number are neither there nor missing"
    bits = (z <= BIT_UNSURE[0]).astype(int)
    return int(np.sum(bits << np.arange(len(bits)))), ""


@lru_cache(maxsize=8)
def _fitter(h: int, w: int, key: int, envelope: bool) -> PhaseFitter:
    """The phase planes' plan for crops of h × w pixels and a fundamental of 1.02^key cycles per
    pixel, with or without the envelope's regressors, kept between markers and frames."""
    return PhaseFitter((h, w), 1.02**key, 1, envelope=envelope)


def _fail(status: str, reason: str) -> dict:
    return {"status": status, "reason": reason}
