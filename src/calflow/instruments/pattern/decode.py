"""Frames of the pattern → (x, y, Θ) in the pattern frame, with uncertainties and a status.

The ten steps of the thesis's Sec. 3.5.1, as done here:

1. frames come in (an array (h, w) or (n, h, w); files through :mod:`.frames`);
2–6. :mod:`.phase`: Fourier transform, band-pass of the two lobes, inverse transforms of the
   cropped spectra, unwrapping and the weighted least-squares phase planes — the fine position
   of the grid in the frame (the planes' intercepts) and its orientation (their slopes);
7. the dots are binarised: the frame is sampled at every grid node the planes predict and
   between them; a node's contrast against its four neighbouring gaps, over the local contrast
   of the always-present frame dots, tells a present dot (≈ 1) from a missing one (≈ 0);
8. the bits: the x code is constant along a column of cells, so each bit is a majority vote
   over every row in view (and likewise for y), which outvotes missing or extra dots and dust;
9. each of the eight readings a square grid allows (four quarter turns × the two cells the
   frame dots leave) is matched against the two codes at every place; the reading that fits
   with at most one wrong bit per axis, and clearly better than every other reading and
   place, gives the coarse absolute position (the cell of the frame centre) and the quarter
   turn of Θ. Anything else — too few bits, too many wrong, two places too close — is not a
   position: the frame gets NaN, a status and a reason, never a neighbouring period;
10. the fine phase is added to the coarse cell: x, y (µm) and Θ (degree, (−180, 180]).

Uncertainties (``u_*``) are standard uncertainties from the phase-plane fits (their residuals),
the noise part only; a systematic error of the optics (distortion, pixel-size error) is not in
them. The derivation of the Cramér–Rao bound they are compared with is in :mod:`.phase`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from calflow.instruments.pattern.bits import bilinear, match, normalised, votes
from calflow.instruments.pattern.pattern import Pattern
from calflow.instruments.pattern.phase import CROP, GAUSS, PhaseFitter

STATUSES = ("ok", "bad_frame", "no_lobes", "low_contrast", "fov_too_small", "code_mismatch", "ambiguous")
MIN_PEAK_RATIO = 100.0  # lobe power over the ring's median: noise alone reaches ~15
MAX_WRONG_BITS = 1  # per axis; the code keeps windows ≥ 5 bits apart
MIN_MARGIN = 3  # bits between the best reading and the next one
MIN_KEPT = 0.5  # fraction of the field's samples a refit around unseen dots must keep
MAX_FRAME_MISSING = 0.25  # fraction of frame dots unseen before the frame is not trusted
NEAR_NODES = 3  # grid nodes around the seen frame dots over which unseen ones count
CHUNK = 8  # frames transformed together
# how far (grid nodes) an unseen frame dot bends the band-passed field: three standard
# deviations of the Gaussian band-pass's impulse response, GAUSS / (2π·CROP) periods
EDGE_NODES = math.ceil(3 * GAUSS / (2 * math.pi * CROP))


@dataclass(frozen=True)
class Decoded:
    """Decoded poses, one entry per frame; NaN where ``status`` is not "ok" (``reason`` says why)."""

    x_um: np.ndarray
    y_um: np.ndarray
    theta_deg: np.ndarray
    u_x_um: np.ndarray
    u_y_um: np.ndarray
    u_theta_deg: np.ndarray
    status: np.ndarray
    reason: np.ndarray
    details: list | None = field(default=None, repr=False)

    def __len__(self) -> int:
        return len(self.status)

    @property
    def ok(self) -> np.ndarray:
        return self.status == "ok"


def decode(
    frames,
    pattern: Pattern,
    camera=None,
    pixel_um: float | None = None,
    workers: int | None = None,
    details: bool = False,
) -> Decoded:
    """Decode one frame (h, w) or a stack (n, h, w) of the pattern.

    ``camera`` (a :class:`~calflow.instruments.pattern.render.Camera`) or ``pixel_um`` (the
    pixel size in the object plane, µm) tells where the grid's lobes are; the position itself
    comes from the phases and the code, not from the pixel size. ``details`` keeps, per frame,
    the lobes, the grid nodes and the bits read (for figures).
    """
    stack = _frames(frames)
    n, h, w = stack.shape
    if camera is not None and (h, w) != (camera.height, camera.width):
        raise ValueError(
            f"frames: expected {camera.width} × {camera.height} pixels (the camera's), got {w} × {h}"
        )
    if pixel_um is None:
        if camera is None:
            from calflow.instruments.pattern.render import Camera

            camera = Camera()
        pixel_um = camera.pixel_um
    if not (isinstance(pixel_um, (int, float)) and pixel_um > 0 and math.isfinite(pixel_um)):
        raise ValueError(f"pixel_um: expected a positive number (µm), got {pixel_um!r}")
    problem = field_of_view_problem(h, w, pixel_um, pattern)
    if problem:
        raise ValueError(problem)
    fitter = PhaseFitter((h, w), pixel_um / pattern.period_um, workers)
    out = {k: np.full(n, np.nan) for k in ("x_um", "y_um", "theta_deg", "u_x_um", "u_y_um", "u_theta_deg")}
    status = np.empty(n, dtype=object)
    reason = np.empty(n, dtype=object)
    info = [None] * n if details else None
    for start in range(0, n, CHUNK):
        block = stack[start : start + CHUNK]
        finite = np.isfinite(block).all(axis=(1, 2)) if block.dtype.kind == "f" else np.ones(len(block), bool)
        span = np.zeros(len(block))
        with np.errstate(over="ignore"):  # a span beyond the float range is inf
            span[finite] = np.ptp(block[finite].reshape(int(finite.sum()), -1), axis=1)
        good = finite & (span > 0)
        if block.dtype.kind == "f" and not ((span[good] > 1e-20) & (span[good] < 1e20)).all():
            block = _unit_range(block, good)  # the spectrum's squares would overflow or vanish
        if good.all():
            planes = fitter.fit(fitter.spectrum(block))
        elif good.any():
            planes = fitter.fit(fitter.spectrum(np.where(good[:, None, None], block, 0)))
        else:
            planes = None
        for k in range(len(block)):
            f = start + k
            if not good[k]:
                status[f], reason[f] = "bad_frame", "the frame is uniform or holds non-finite values"
                continue
            result = _read(block[k], planes, k, pattern, details, fitter)
            status[f], reason[f] = result["status"], result["reason"]
            if result["status"] == "ok":
                for key in out:
                    out[key][f] = result[key]
            if details:
                info[f] = result.get("details")
    return Decoded(**out, status=status.astype(str), reason=reason.astype(str), details=info)


def _unit_range(block: np.ndarray, good: np.ndarray) -> np.ndarray:
    """Float frames brought to values from 0 to 1; ``good`` frames whose values do not differ
    once scaled become uniform (bad frames)."""
    out = np.zeros(block.shape)
    for k in np.flatnonzero(good):
        b = block[k] / np.abs(block[k]).max()
        lo, hi = b.min(), b.max()
        good[k] = hi > lo
        out[k] = (b - lo) / (hi - lo) if good[k] else 0.0
    return out


def field_of_view_problem(h: int, w: int, pixel_um: float, pattern) -> str | None:
    """Why frames of ``h`` × ``w`` pixels of ``pixel_um`` µm cannot be decoded on ``pattern``
    (their field of view is smaller than its ``min_fov_um``), or None. Checked before any frame
    is read (a campaign's options at load) and by :func:`decode`."""
    need = max(pattern.min_fov_um)
    seen = (min(h, w) - 2) * pixel_um
    if seen < need:
        return (
            f"frames of {w} × {h} pixels of {pixel_um:g} µm see {seen:.1f} µm across; the pattern "
            f"needs a field of view of {need:g} µm (min_fov_um) to be decoded"
        )
    return None


def _frames(frames) -> np.ndarray:
    a = np.asarray(frames)
    if a.dtype.kind not in "uif":
        raise ValueError(f"frames: expected integer or float pixel values, got dtype {a.dtype}")
    if a.ndim == 2:
        a = a[None]
    if a.ndim != 3:
        raise ValueError(f"frames: expected an array (h, w) or (n, h, w), got shape {a.shape}")
    if a.shape[1] < 16 or a.shape[2] < 16:
        raise ValueError(f"frames: expected at least 16 × 16 pixels, got {a.shape[2]} × {a.shape[1]}")
    return a


_Q = (((1, 0), (0, 1)), ((0, 1), (-1, 0)), ((-1, 0), (0, -1)), ((0, -1), (1, 0)))  # (u, v) = Q_m (s, t)


def _read(frame, planes, k, pattern: Pattern, details: bool, fitter: PhaseFitter) -> dict:
    """Steps 7–10 for one frame whose phase planes are ``planes[k]``."""
    ratio = planes.peak_ratio[k]
    if not (ratio.min() >= MIN_PEAK_RATIO):
        return _fail(
            "no_lobes",
            f"no grid of period {pattern.period_um:g} µm in the frame at {fitter.f0 * pattern.period_um:g} µm per pixel "
            f"(lobe/ring {ratio.min():.0f}; is the pixel size right?)",
        )
    if not (np.isfinite(planes.phase[k]).all() and np.isfinite(planes.cov[k]).all()):
        return _fail("no_lobes", "the grid's phase planes could not be fitted (no signal in the lobes)")
    kvec = planes.freq[k].copy()  # (lobe, (x, y)) cycles per pixel
    phase = planes.phase[k].copy()
    cov = planes.cov[k]
    # the s lobe is the one nearer the image x axis (the half-plane spectrum has kx ≥ 0, so its
    # angle is within ±45°); the t lobe is turned so that t is s turned by +90° (image x → y)
    si = int(np.argmax(np.abs(kvec[:, 0]) / np.hypot(kvec[:, 0], kvec[:, 1])))
    ti = 1 - si
    sgn_s = 1.0 if kvec[si, 0] >= 0 else -1.0
    ks, ps = sgn_s * kvec[si], sgn_s * phase[si]
    cross = ks[0] * kvec[ti, 1] - ks[1] * kvec[ti, 0]
    sgn_t = 1.0 if cross > 0 else -1.0
    kt, pt = sgn_t * kvec[ti], sgn_t * phase[ti]
    K = np.array([ks, kt])
    if abs(np.linalg.det(K)) < 1e-12:
        return _fail("no_lobes", "the two lobes found are parallel: no square grid in the frame")
    sc = (ps / (2 * np.pi)) % 1.0
    tc = (pt / (2 * np.pi)) % 1.0
    h, w = frame.shape
    rc = np.array([(w - 1) / 2.0, (h - 1) / 2.0])
    Kinv = np.linalg.inv(K)
    img = frame.astype(np.float32)
    # step 7: polarity (dots brighter or darker than the substrate), then each node's contrast
    corners = np.array([[0, 0], [w - 1, 0], [0, h - 1], [w - 1, h - 1]], float) - rc
    st = corners @ K.T + [sc, tc]
    S = np.arange(math.floor(st[:, 0].min()) - 1, math.ceil(st[:, 0].max()) + 2)
    T = np.arange(math.floor(st[:, 1].min()) - 1, math.ceil(st[:, 1].max()) + 2)

    def sample(ds, dt):
        SS, TT = np.meshgrid(S + ds - sc, T + dt - tc)
        xy = np.stack([SS, TT], -1) @ Kinv.T + rc
        inside = (xy[..., 0] >= 1) & (xy[..., 0] <= w - 2) & (xy[..., 1] >= 1) & (xy[..., 1] <= h - 2)
        return bilinear(img, xy[..., 0], xy[..., 1]), inside, xy

    v0, in0, xy0 = sample(0.0, 0.0)
    v1, in1, _ = sample(0.5, 0.5)
    spread0 = np.subtract(*np.percentile(v0[in0], [90, 10])) if in0.any() else 0.0
    spread1 = np.subtract(*np.percentile(v1[in1], [90, 10])) if in1.any() else 0.0
    if spread1 > spread0:  # dark dots: the nodes are where the phase is π
        sc, tc = (sc + 0.5) % 1.0, (tc + 0.5) % 1.0
        v0, in0, xy0 = sample(0.0, 0.0)
    # the four gaps around node (S, T) are at (S ± ½, T ± ½): one grid of gaps, one row and
    # column larger, holds them all
    S_, T_ = S, T
    S, T = np.append(S_, S_[-1] + 1), np.append(T_, T_[-1] + 1)
    gaps = sample(-0.5, -0.5)[0]  # gap (S−½, T−½) at [T, S]
    S, T = S_, T_
    around = 0.25 * (gaps[:-1, :-1] + gaps[:-1, 1:] + gaps[1:, :-1] + gaps[1:, 1:])
    contrast = v0 - around
    valid = in0
    if valid.sum() < 16:
        return _fail("fov_too_small", "fewer than 16 grid nodes in the frame")
    par = (S[None, :] + T[:, None]) % 2
    med = [np.median(contrast[valid & (par == q)]) if (valid & (par == q)).any() else 0.0 for q in (0, 1)]
    qf = int(np.argmax(np.abs(med)))
    sign = 1.0 if med[qf] > 0 else -1.0
    contrast = contrast * sign
    fmask = valid & (par == qf)
    # local contrast from the always-present dots, twice: the second time only from those seen,
    # so that dust or the pattern's edge does not dilute it
    z = normalised(contrast, fmask)
    seen = fmask & (z > 0.5)
    z = normalised(contrast, seen)
    # unseen among the frame dots within NEAR_NODES of a seen one: a part of the view beyond
    # the pattern's edge is not poor contrast (the code's bits say whether enough is seen)
    from scipy import ndimage  # here, not at import: the camera model's users need no scipy

    near = fmask & ndimage.binary_dilation(seen, iterations=NEAR_NODES)
    zf = z[near]
    frame_missing = float(np.mean(~(zf > 0.5))) if len(zf) else 1.0
    if frame_missing > MAX_FRAME_MISSING:
        return _fail(
            "low_contrast",
            f"{100 * frame_missing:.0f} % of the grid's always-present dots are not seen "
            "(contrast, focus, dust or off the pattern)",
        )
    present = z > 0.5
    # steps 8–9: the eight readings, each matched against both codes at every place
    # a code dot is read only where the four frame dots around it are seen (not under dust,
    # not off the pattern's edge)
    seen = fmask & (z > 0.5)
    pad = np.pad(seen, 1)
    around_seen = pad[:-2, 1:-1] & pad[2:, 1:-1] & pad[1:-1, :-2] & pad[1:-1, 2:]
    cmask = valid & (par != qf) & np.isfinite(z) & around_seen
    SS, TT = np.meshgrid(S, T)
    readings = []
    for m, Q in enumerate(_Q):
        U = Q[0][0] * SS + Q[0][1] * TT
        V = Q[1][0] * SS + Q[1][1] * TT
        for pu in (0, 1):
            pv = (qf - pu) % 2
            u, v = U + pu, V + pv
            xm, ym = cmask & (v % 2 == 0), cmask & (v % 2 == 1)
            # the x code is flipped on odd rows of cells; where the rows start is not known yet,
            # so the reading is matched as it is (y place even) and complemented (odd)
            xr = votes(u[xm] // 2, present[xm] ^ ((v[xm] // 2) % 2 == 1))
            both = (match(xr, pattern.x_bits), match((xr[0], 1 - xr[1], xr[2]), pattern.x_bits))
            q = int(both[1][0] < both[0][0])
            mx, other = both[q], both[1 - q]
            # the y code is flipped on odd pairs of columns of cells: undo it from the x place
            flip = (((u[ym] // 2 + mx[1]) // 2) % 2) == 1
            my = match(votes(v[ym] // 2, present[ym] ^ flip), pattern.y_bits)
            enough = mx[3] >= pattern.window_bits[0] and my[3] >= pattern.window_bits[1]
            consistent = my[1] % 2 == q  # the x flip guessed is the y place's parity
            score = mx[0] + my[0] if enough and consistent else 10**6
            readings.append((score, m, pu, pv, mx, my, other[0]))
    readings.sort(key=lambda r: (r[0], -(r[4][3] + r[5][3])))
    best = readings[0]
    _, m, pu, pv, mx, my, x_alt = best
    nbits = (mx[3], my[3])
    if nbits[0] < pattern.window_bits[0] or nbits[1] < pattern.window_bits[1]:
        return _fail(
            "fov_too_small",
            f"{nbits[0]} x and {nbits[1]} y bits read with confidence; the code needs "
            f"{pattern.window_bits[0]} and {pattern.window_bits[1]}",
        )
    if mx[0] > MAX_WRONG_BITS or my[0] > MAX_WRONG_BITS:
        if best[0] >= 10**6:
            return _fail(
                "code_mismatch", "no reading of the code is consistent (x flips against the y place)"
            )
        return _fail(
            "code_mismatch",
            f"the best reading has {mx[0]} x and {my[0]} y bits wrong (at most {MAX_WRONG_BITS} allowed)",
        )
    runner = min([readings[1][0]] + [mx[0] + my[2], mx[2] + my[0], x_alt + my[0]])
    if runner - best[0] < MIN_MARGIN:
        return _fail(
            "ambiguous",
            f"two readings of the code differ by {runner - best[0]} bits only (at least {MIN_MARGIN} needed)",
        )
    # where dust or the pattern's edge hides frame dots, the planes are fitted again without
    # the samples there (a sharp change of the field's amplitude bends its phase around it)
    unseen = fmask & ~(z > 0.5)
    if unseen.any():
        bad = ndimage.maximum_filter(unseen, size=2 * EDGE_NODES + 1)
        pts = fitter.coarse_points()
        st_pts = (pts - rc) @ K.T + [sc, tc]
        ti_ = np.clip(np.rint(st_pts[:, 1]).astype(int) - T[0], 0, len(T) - 1)
        si_ = np.clip(np.rint(st_pts[:, 0]).astype(int) - S[0], 0, len(S) - 1)
        keep = ~bad[ti_, si_]
        # only where the unseen dots leave most of the field: scattered ones (noise) would
        # leave a few samples at the frame's edge, whose phase can be off by up to half a period
        if keep.sum() > 16 and keep.mean() >= MIN_KEPT:
            new_phase, new_freq, cov = fitter.refit(planes, k, keep)
            ks, kt = sgn_s * new_freq[si], sgn_t * new_freq[ti]
            # move the fine phases by the change only: the nodes' numbering stays as read
            sc += ((sgn_s * (new_phase[si] - phase[si]) / (2 * np.pi)) + 0.5) % 1.0 - 0.5
            tc += ((sgn_t * (new_phase[ti] - phase[ti]) / (2 * np.pi)) + 0.5) % 1.0 - 0.5
    # step 10: coarse cell + fine phase
    Q = _Q[m]
    uc = Q[0][0] * sc + Q[0][1] * tc + pu + 2 * mx[1]
    vc = Q[1][0] * sc + Q[1][1] * tc + pv + 2 * my[1]
    p = pattern.period_um
    x_um = uc * p - pattern.origin_um[0]
    y_um = vc * p - pattern.origin_um[1]
    # uncertainties: u follows the s plane (m even) or the t plane (m odd)
    lobe_u, lobe_v = (si, ti) if m % 2 == 0 else (ti, si)
    u_x = p * math.sqrt(cov[lobe_u, 0, 0]) / (2 * np.pi)
    u_y = p * math.sqrt(cov[lobe_v, 0, 0]) / (2 * np.pi)
    th_s, var_s = _angle(ks, cov[si], sgn_s)
    th_t, var_t = _angle(kt, cov[ti], sgn_t)
    th_t -= 90.0
    dt = (th_t - th_s + 180.0) % 360.0 - 180.0
    wsum = 1 / var_s + 1 / var_t
    theta = th_s + dt * (1 / var_t) / wsum + 90.0 * m
    theta = (theta + 180.0) % 360.0 - 180.0
    if theta == -180.0:
        theta = 180.0
    result = {
        "status": "ok",
        "reason": "decoded",
        "x_um": x_um,
        "y_um": y_um,
        "theta_deg": theta,
        "u_x_um": u_x,
        "u_y_um": u_y,
        "u_theta_deg": math.sqrt(1 / wsum),
    }
    if details:
        result["details"] = {
            "lobes_cycles_per_px": K.tolist(),
            "quarter_turns": m,
            "nodes_xy": xy0[valid],
            "node_present": present[valid],
            "frame_node": (par == qf)[valid],
            "wrong_bits": (int(mx[0]), int(my[0])),
            "bits_read": nbits,
            "margin_bits": int(runner - best[0]),
        }
    return result


def _angle(k, cov, sgn):
    """Direction (degree) of a lobe's frequency and its variance from the slope covariance."""
    g = 2 * np.pi * k  # rad per pixel; the covariance is of the fitted slopes (sign-free)
    th = math.degrees(math.atan2(g[1], g[0]))
    jac = np.array([-g[1], g[0]]) / (g @ g)
    var = float(jac @ cov[1:, 1:] @ jac) * (180 / np.pi) ** 2
    return th, max(var, 1e-30)


def _fail(status: str, reason: str) -> dict:
    return {"status": status, "reason": reason}
