"""Frames of a Megarena target → x, y (µm), Θ (degree) and the pixel size, with uncertainties.

The phase part is the one every layout shares (:class:`~calflow.instruments.pattern.phase.PhaseFitter`,
steps 2–6 of the thesis's Sec. 3.5.1); what is Megarena's own is how the absolute place is read
(André et al., IEEE TIM 70, 2020):

1. the pixel period: when the pixel size is not given, the strongest peak of the frame's
   spectrum between periods of 3 pixels and a twelfth of the frame is the grid's fundamental;
   the phase planes' slopes then refine it, so the pixel size is *measured*,
   ``pixel = p · |k|`` (p the period in µm, k the lobe's frequency in cycles per pixel), with
   the standard uncertainty of the slopes' fit;
2. every grid node the planes predict is sampled and its contrast against the four gaps around
   it, over the local contrast of the dots seen, says present (≈ 1) or missing (≈ 0);
3. the three rows (and columns) of a code period: of the 36 ways to place the holes' class
   (3 × 3) and the direction of each axis (2 × 2), the one whose sure sites (the holes, which
   must be empty, and the sites of the two always-full classes, which must carry dots) are
   contradicted least, and clearly less than every other way;
4. each code column's bit is the majority over the rows whose sites it decides; the bits read,
   in the pattern's order, are placed in the code (at most :data:`MAX_WRONG_BITS` wrong, the
   next place at least :data:`MIN_MARGIN` bits worse);
5. the handedness of the two axes' directions in the frame tells which lattice direction is x
   (the pattern is not seen mirrored) and Θ is the direction of the pattern's x axis.

Anything else — no grid, too few code bits, a reading that fits no place or two — is not a
position: NaN, a status and one reason.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from calflow.instruments.pattern.bits import bilinear, dilate3, erode3, match, normalised, percentile, votes
from calflow.instruments.pattern.decode import Decoded, _angle, _fail
from calflow.instruments.pattern.megarena.pattern import MegarenaPattern
from calflow.instruments.pattern.megarena.period import fundamental, pixel_size
from calflow.instruments.pattern.megarena.reading import classes, strong_reading
from calflow.instruments.pattern.megarena.uniform import PLANE_WEIGHTS, uniform_planes
from calflow.instruments.pattern.phase import PhaseFitter
from calflow.instruments.pattern.spectrum import scratch

MIN_PEAK_RATIO = 100.0  # lobe power over the ring's median (noise alone reaches ~15)
MAX_WRONG_BITS = 1  # per axis
MIN_MARGIN = 3  # bits between the place found and the next one
MIN_CLASS_MARGIN = 0.02  # fraction of the sure sites between the best arrangement and the next
MAX_PERIOD_MISMATCH = 0.05  # relative: a given pixel size and the period seen must agree this well


@dataclass(frozen=True)
class MegarenaDecoded(Decoded):
    """:class:`Decoded` plus the pixel size measured from each frame (µm in the object plane)."""

    pixel_um: np.ndarray | None = None
    u_pixel_um: np.ndarray | None = None
    theta_x_deg: np.ndarray | None = None  # the direction of the pattern's x axis alone
    pixel_x_um: np.ndarray | None = None  # the pixel size along the x axis alone
    theta_y_deg: np.ndarray | None = None  # the direction of the pattern's y axis alone
    pixel_y_um: np.ndarray | None = None  # the pixel size along the y axis alone
    shape: tuple[int, int] | None = None  # the frames' (height, width), pixels
    origin_um: tuple[float, float] = (0.0, 0.0)  # the pattern's: the library has none

    def library_pose(self) -> dict[str, np.ndarray]:
        """The poses as the Vernier library prints them (``x, y, alpha, pixelSize``).

        The library gives the translation of the pattern in the camera frame at the pixel
        (w/2, h/2) — pixel centres at integer coordinates — where calflow gives the pattern
        coordinates of the frame centre ((w − 1)/2, (h − 1)/2), half a pixel up and left; its
        angle is the x axis's direction alone, its pixel size the period along x alone
        (docs/instruments.md)::

            x_lib = −(x + o_x + s_x·(cos α_x + sin α_x)/2),  y_lib = −(y + o_y + s_y·(cos α_y + sin α_y)/2)

        with α_x, α_y the directions of the pattern's x and y axes in the frame (α_y = α_x + 90°
        when the pixels are square and the optics do not shear) and s_x, s_y the pixel sizes
        along them, (o_x, o_y) the pattern's ``origin_um``; alpha = α_x, pixelSize = s_x.
        """
        ax, ay = np.radians(self.theta_x_deg), np.radians(self.theta_y_deg)
        return {
            "x": -(self.x_um + self.origin_um[0] + 0.5 * self.pixel_x_um * (np.cos(ax) + np.sin(ax))),
            "y": -(self.y_um + self.origin_um[1] + 0.5 * self.pixel_y_um * (np.cos(ay) + np.sin(ay))),
            "alpha": ax,
            "pixelSize": self.pixel_x_um,
        }


def decode(
    frames,
    pattern: MegarenaPattern,
    pixel_um: float | None = None,
    workers: int | None = None,
    details: bool = False,
    fit_region: float = 1.0,
    plane_weights: str = "power",
):
    """Decode one frame (h, w) or a stack (n, h, w) of a Megarena target.

    ``pixel_um`` (µm per pixel in the object plane), when given, tells where the grid's lobes
    are and a frame of another period is refused; when not, it is measured from each frame
    (``pixel_um`` and ``u_pixel_um`` of the result either way). ``fit_region``: the central
    fraction of the frame's width and height the phase planes are fitted on (1: the whole frame
    but the window's tapered margin, a tenth of each side; 0.5: the central half, as the Vernier
    library fits them — where the optics distort the frame, the two differ). ``plane_weights``:
    ``"power"`` (calflow's, the least noise) or ``"uniform"`` (the library's mean lattice over
    the region; :meth:`PhaseFitter.refit <calflow.instruments.pattern.phase.PhaseFitter.refit>`).
    ``fit_region=0.5, plane_weights="uniform"`` is the library's estimand (docs/instruments.md).
    """
    if not (isinstance(fit_region, (int, float)) and 0.1 <= fit_region <= 1.0):
        raise ValueError(f"fit_region: expected a fraction from 0.1 to 1, got {fit_region!r}")
    if plane_weights not in PLANE_WEIGHTS:
        raise ValueError(f"plane_weights: expected one of {', '.join(PLANE_WEIGHTS)}, got {plane_weights!r}")
    stack = _frames(frames)
    n, h, w = stack.shape
    if pixel_um is not None and not (
        isinstance(pixel_um, (int, float)) and pixel_um > 0 and math.isfinite(pixel_um)
    ):
        raise ValueError(f"pixel_um: expected a positive number (µm), got {pixel_um!r}")
    keys = ("x_um", "y_um", "theta_deg", "u_x_um", "u_y_um", "u_theta_deg", "pixel_um", "u_pixel_um")
    keys += ("theta_x_deg", "pixel_x_um", "theta_y_deg", "pixel_y_um")
    out = {k: np.full(n, np.nan) for k in keys}
    status = np.empty(n, dtype=object)
    reason = np.empty(n, dtype=object)
    info = [None] * n if details else None
    window = None
    for f in range(n):
        frame = scratch((h, w), "frame")  # not a new array per frame (module spectrum)
        np.copyto(frame, stack[f])
        problem = _bad_frame(stack[f])
        if problem:
            status[f], reason[f] = "bad_frame", problem
            continue
        if window is None:
            window = _fitter(h, w, -116, workers)  # its spectrum only, which no frequency changes
        spec = window.spectrum(frame[None])
        if pixel_um is None:
            f0 = fundamental(spec[0], window.h, window.w, pattern.depth)  # the transform's size
            if f0 is None:
                status[f], reason[f] = "no_lobes", "no periodic grid in the frame (no peak in the spectrum)"
                continue
        else:
            f0 = pixel_um / pattern.period_um
        # one plan per 2 % of frequency: the lobes are searched within ±20 % and their
        # frequency fitted, so frames of nearly one pixel size share it (and any batch of frames
        # gives each the same result)
        fitter = _fitter(h, w, round(math.log(f0) / math.log(1.02)), workers)
        planes = fitter.fit(spec)
        result = _read(frame, planes, pattern, fitter, pixel_um, (fit_region, plane_weights))
        status[f], reason[f] = result["status"], result["reason"]
        if result["status"] == "ok":
            for k in keys:
                out[k][f] = result[k]
        if details:
            info[f] = result.get("details")
    return MegarenaDecoded(
        **{k: out[k] for k in keys[:6]},
        status=status.astype(str),
        reason=reason.astype(str),
        details=info,
        pixel_um=out["pixel_um"],
        u_pixel_um=out["u_pixel_um"],
        theta_x_deg=out["theta_x_deg"],
        pixel_x_um=out["pixel_x_um"],
        theta_y_deg=out["theta_y_deg"],
        pixel_y_um=out["pixel_y_um"],
        shape=(h, w),
        origin_um=tuple(pattern.origin_um),
    )


@lru_cache(maxsize=8)
def _fitter(h: int, w: int, key: int, workers: int | None) -> PhaseFitter:
    """The phase planes' plan for frames of h × w pixels and a fundamental of 1.02^key cycles
    per pixel, kept between calls (a recording is decoded in chunks). The code's rows and
    columns left out bias a plain plane fit: the planes are fitted with the envelope's
    regressors (:mod:`calflow.instruments.pattern.phase`); a side of a slow FFT length is
    zero-padded to a fast one."""
    return PhaseFitter((h, w), 1.02**key, workers, envelope=True, pad=True)


def _frames(frames) -> np.ndarray:
    a = np.asarray(frames)
    if a.dtype.kind not in "uif":
        raise ValueError(f"frames: expected integer or float pixel values, got dtype {a.dtype}")
    if a.ndim == 2:
        a = a[None]
    if a.ndim != 3 or a.shape[1] < 32 or a.shape[2] < 32:
        raise ValueError(
            f"frames: expected an array (h, w) or (n, h, w) of at least 32 × 32 pixels, got {a.shape}"
        )
    return a


def _bad_frame(frame: np.ndarray) -> str | None:
    """Why a frame holds no image to decode (non-finite, uniform, mostly clipped), or None."""
    if frame.dtype.kind == "f" and not np.isfinite(frame).all():
        return "the frame holds non-finite values"
    lo, hi = frame.min(), frame.max()
    if not hi > lo:
        return "the frame is uniform (blank or saturated)"
    if frame.dtype.kind == "u":
        top = np.iinfo(frame.dtype).max
        clipped = float(np.mean(frame == top)) if hi == top else 0.0
        if clipped > 0.5:
            return f"{100 * clipped:.0f} % of the pixels are saturated"
    return None


def _read(
    frame, planes, pattern: MegarenaPattern, fitter: PhaseFitter, given_pixel, plane=(1.0, "power")
) -> dict:
    p = pattern.period_um
    ratio = planes.peak_ratio[0]
    if not ratio.min() >= MIN_PEAK_RATIO:
        where = "" if given_pixel is None else f" at {given_pixel:g} µm per pixel"
        return _fail(
            "no_lobes", f"no square grid of period {p:g} µm in the frame{where} (lobe/ring {ratio.min():.0f})"
        )
    if not (np.isfinite(planes.phase[0]).all() and np.isfinite(planes.cov[0]).all()):
        return _fail("no_lobes", "the grid's phase planes could not be fitted (no signal in the lobes)")
    kvec, phase, cov = planes.freq[0], planes.phase[0], planes.cov[0]
    si = int(np.argmax(np.abs(kvec[:, 0]) / np.hypot(kvec[:, 0], kvec[:, 1])))
    ti = 1 - si
    sgn_s = 1.0 if kvec[si, 0] >= 0 else -1.0
    ks, ps = sgn_s * kvec[si], sgn_s * phase[si]
    sgn_t = 1.0 if ks[0] * kvec[ti, 1] - ks[1] * kvec[ti, 0] > 0 else -1.0
    kt, pt = sgn_t * kvec[ti], sgn_t * phase[ti]
    K = np.array([ks, kt])
    if abs(np.linalg.det(K)) < 1e-12:
        return _fail("no_lobes", "the two lobes found are parallel: no square grid in the frame")
    ratio_k = np.hypot(*ks) / np.hypot(*kt)
    if abs(ratio_k - 1) > 0.05:
        return _fail(
            "no_lobes", f"the two lattice directions have periods {ratio_k:.3f} apart: not a square grid"
        )
    if given_pixel is not None:
        seen = given_pixel / float(np.mean(np.hypot(K[:, 0], K[:, 1])))  # µm per period in the frame
        if abs(seen / p - 1) > MAX_PERIOD_MISMATCH:
            return _fail(
                "no_lobes",
                f"the frame's grid has a period of {seen:.3g} µm at {given_pixel:g} µm per pixel; "
                f"the pattern's is {p:g} µm (is the pixel size right?)",
            )
    sc, tc = (ps / (2 * np.pi)) % 1.0, (pt / (2 * np.pi)) % 1.0
    h, w = frame.shape
    rc = np.array([(w - 1) / 2.0, (h - 1) / 2.0])
    Kinv = np.linalg.inv(K)
    corners = np.array([[0, 0], [w - 1, 0], [0, h - 1], [w - 1, h - 1]], float) - rc
    st = corners @ K.T + [sc, tc]
    S = np.arange(math.floor(st[:, 0].min()) - 1, math.ceil(st[:, 0].max()) + 2)
    T = np.arange(math.floor(st[:, 1].min()) - 1, math.ceil(st[:, 1].max()) + 2)

    def lattice(ds, dt, S=S, T=T):
        # the lattice points (S + ds, T + dt) in the frame, pixel = K⁻¹·(lattice − phase) + centre
        s, t = (S + ds - sc)[None, :], (T + dt - tc)[:, None]
        x = Kinv[0, 0] * s + Kinv[0, 1] * t + rc[0]
        y = Kinv[1, 0] * s + Kinv[1, 1] * t + rc[1]
        return x, y, (x >= 1) & (x <= w - 2) & (y >= 1) & (y <= h - 2)

    def sample():
        # the frame at the nodes in it, and at the gaps (S + ½, T + ½ and one more row and column
        # before) in it or at a corner of a node in it: nothing else is read (0 there)
        x, y, inside = lattice(0.0, 0.0)
        xg, yg, in_gaps = lattice(-0.5, -0.5, S1, T1)
        need = in_gaps.copy()
        for rows, cols in (
            (np.s_[:-1], np.s_[:-1]),
            (np.s_[:-1], np.s_[1:]),
            (np.s_[1:], np.s_[:-1]),
            (np.s_[1:], np.s_[1:]),
        ):
            need[rows, cols] |= inside
        v0, gaps = np.zeros(x.shape, np.float32), np.zeros(xg.shape, np.float32)
        v0[inside] = bilinear(frame, x[inside], y[inside])
        gaps[need] = bilinear(frame, xg[need], yg[need])
        return v0, inside, gaps, in_gaps

    S1, T1 = np.append(S, S[-1] + 1), np.append(T, T[-1] + 1)
    v0, inside, gaps, in_gaps = sample()
    v1, in1 = gaps[1:, 1:], in_gaps[1:, 1:]  # the points (S + ½, T + ½)
    if (
        in1.any()
        and inside.any()
        and np.ptp(percentile(v1[in1], [10, 90])) > np.ptp(percentile(v0[inside], [10, 90]))
    ):  # dark dots: the fundamental's phase is π on them
        sc, tc = (sc + 0.5) % 1.0, (tc + 0.5) % 1.0
        v0, inside, gaps, _ = sample()
    contrast = v0 - 0.25 * (gaps[:-1, :-1] + gaps[:-1, 1:] + gaps[1:, :-1] + gaps[1:, 1:])
    if inside.sum() < 16:
        return _fail("fov_too_small", "fewer than 16 grid nodes in the frame")
    c_in = contrast[inside]
    strong = np.abs(c_in) > 0.5 * percentile(np.abs(c_in), 95)
    if np.mean(c_in[strong]) < 0:
        contrast = -contrast
    dots = inside & (contrast > 0.5 * percentile(contrast[inside], 95))
    z = normalised(contrast, dots)
    present = z > 0.5
    # inside the target every site has a dot within one node (a code row or column left out
    # is one in three): nodes farther from any dot are beyond the target's edge, not code
    on_target = erode3(dilate3(present & inside))
    known = inside & np.isfinite(z) & on_target
    arrangement = classes(present, known, S, T)
    if arrangement is None:
        return _fail("code_mismatch", "the holes of a Megarena grid are not where three periods put them")
    (a0, ds, b0, dt), margin, contradicted = arrangement
    if margin < MIN_CLASS_MARGIN:
        return _fail(
            "ambiguous",
            "two arrangements of the code's rows and columns fit the sites seen nearly as well "
            f"({100 * margin:.1f} % of the sure sites apart)",
        )
    readings = []
    for axis, (c0, direction, other0, lines, cross) in enumerate(((a0, ds, b0, S, T), (b0, dt, a0, T, S))):
        code_class = (c0 + (1 if direction > 0 else 2)) % 3
        full_class = (other0 + (2 if (dt if axis == 0 else ds) > 0 else 1)) % 3
        decides = (cross % 3 == other0) | (cross % 3 == full_class)  # rows whose sites show the bit
        if axis == 0:
            mask = known & (lines[None, :] % 3 == code_class) & decides[:, None]
            idx = np.broadcast_to(lines[None, :], mask.shape)[mask]
        else:
            mask = known & (lines[:, None] % 3 == code_class) & decides[None, :]
            idx = np.broadcast_to(lines[:, None], mask.shape)[mask]
        cells = (idx - code_class) // 3
        vals = present[mask]
        if direction < 0:
            cells = -cells
        readings.append((votes(cells, vals), code_class, strong_reading(cells, vals)))
    found = [match(reading, pattern.bits) for reading, _, _ in readings]
    nbits = [m[3] for m in found]
    if min(nbits) < pattern.depth:
        return _fail(
            "fov_too_small",
            f"{nbits[0]} and {nbits[1]} code bits read with confidence along the two axes; "
            f"the {pattern.depth}-bit code needs {pattern.depth}",
        )
    wrong = [m[0] for m in found]
    if max(wrong) > MAX_WRONG_BITS:
        return _fail(
            "code_mismatch",
            f"the code bits read fit no place of the {pattern.depth}-bit code ({wrong[0]} and {wrong[1]} wrong)",
        )
    gap = min(m[2] - m[0] for m in found)
    if gap < MIN_MARGIN:
        # fewer bits in view than the margin asks: the place stands only if the bits decided by
        # overwhelming majorities alone fit it exactly and no other place as well
        strict = [match(strong, pattern.bits) for _, _, strong in readings]
        unique = all(m[0] == 0 and m[2] >= 1 and m[3] >= pattern.depth for m in strict)
        if not (unique and [m[1] for m in strict] == [m[1] for m in found]):
            return _fail("ambiguous", f"two places of the code fit the bits read within {gap} bits")
    fit_region, weights = plane
    if fit_region < 1.0 or weights != "power":  # the fine pose again; the numbering stays as read
        pts = fitter.coarse_points()
        keep = (np.abs(pts[:, 0] - rc[0]) <= fit_region * w / 2) & (
            np.abs(pts[:, 1] - rc[1]) <= fit_region * h / 2
        )
        if weights == "uniform":  # every pixel of the region alike: each sample its cell's share
            keep = fitter.region_share(fit_region)
        if np.count_nonzero(keep) < 16:
            return _fail(
                "fov_too_small", f"fewer than 16 phase samples in the central {fit_region:g} of the frame"
            )
        refit = uniform_planes if weights == "uniform" else PhaseFitter.refit
        new_phase, new_freq, cov = refit(fitter, planes, 0, keep)
        sc += ((sgn_s * (new_phase[si] - phase[si]) / (2 * np.pi)) + 0.5) % 1.0 - 0.5
        tc += ((sgn_t * (new_phase[ti] - phase[ti]) / (2 * np.pi)) + 0.5) % 1.0 - 0.5
        ks, kt = sgn_s * new_freq[si], sgn_t * new_freq[ti]
        K = np.array([ks, kt])
    # lattice coordinate of the frame centre → pattern site coordinate (column or row)
    centre = []
    for (_, code_class, _), m, c, direction in zip(readings, found, (sc, tc), (ds, dt)):
        # cell q (signed by the direction) is code bit q + offset, the site 3·bit + 1
        q = (c - code_class) / 3.0 * direction
        centre.append(3.0 * (q + m[1]) + 1.0)
    es, et = ds * ks, dt * kt  # the directions of increasing site index, in the frame
    s_is_x = es[0] * et[1] - es[1] * et[0] > 0
    ix, iy = (0, 1) if s_is_x else (1, 0)
    lobe = (si, ti)
    e_x, e_y = (es, et) if s_is_x else (et, es)
    x_um, y_um = centre[ix] * p - pattern.origin_um[0], centre[iy] * p - pattern.origin_um[1]
    u_x = p * math.sqrt(cov[lobe[ix], 0, 0]) / (2 * np.pi)
    u_y = p * math.sqrt(cov[lobe[iy], 0, 0]) / (2 * np.pi)
    th_x, var_x = _angle(e_x, cov[lobe[ix]], 1.0)
    th_y, var_y = _angle(e_y, cov[lobe[iy]], 1.0)
    d = ((th_y - 90.0) - th_x + 180.0) % 360.0 - 180.0
    wsum = 1 / var_x + 1 / var_y
    theta = th_x + d * (1 / var_y) / wsum
    theta = (theta + 180.0) % 360.0 - 180.0
    if theta == -180.0:
        theta = 180.0
    pix, u_pix = pixel_size(p, K, cov, (si, ti))
    pix_x, pix_y = p * float(np.hypot(*e_x)), p * float(np.hypot(*e_y))
    return {
        "status": "ok",
        "reason": "decoded",
        "x_um": x_um,
        "y_um": y_um,
        "theta_deg": theta,
        "u_x_um": u_x,
        "u_y_um": u_y,
        "u_theta_deg": math.sqrt(1 / wsum),
        "pixel_um": pix,
        "u_pixel_um": u_pix,
        "theta_x_deg": th_x,
        "pixel_x_um": pix_x,
        "theta_y_deg": th_y,
        "pixel_y_um": pix_y,
        "details": {
            "classes": (int(a0), int(ds), int(b0), int(dt)),
            "contradicted": contradicted,
            "bits_read": tuple(nbits),
            "wrong_bits": tuple(wrong),
            "margin_bits": int(gap),
        },
    }
