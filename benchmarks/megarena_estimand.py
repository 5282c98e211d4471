"""What a Megarena decoder's pose means on a distorted frame, and the dots' own estimate of it.

On a frame the optics distort, the lattice's phase is not a plane: each lobe's unwrapped phase
is a smooth field Φ_j(p) = 2π·L_j(p), L_j the lattice coordinate (in periods) of pixel p, an
integer at every dot (bright dots; half an integer for dark ones). Both decoders fit a plane to
it; the Vernier library by ordinary least squares over every pixel of the frame's central half
(its ``RegressionPlane``, crop factor 0.5: rows and columns from ⌊n/4⌋ on, ``n − 2⌊n/4⌋`` of
them, centred on the pixel (w/2, h/2)). The quantity both estimate is taken to be that plane of
the lattice's own phase:

    [L̂_j(p₀), ∂L̂_j/∂x, ∂L̂_j/∂y] = argmin Σ_{p ∈ R} (L_j(p) − a − b·(x − x₀) − c·(y − y₀))²     (1)

over the pixels p of the central half R, p₀ = (w/2, h/2); in the library's convention the pose is

    x = −P·L̂_1(p₀),  y = −P·L̂_2(p₀),  α = atan2(∂L̂_1/∂y, ∂L̂_1/∂x),  pixel = P·|∇L̂_1|         (2)

(P the period, lobe 1 the pattern's x axis: docs/instruments.md). On an undistorted frame (1) is
the lattice itself; on a distorted one it is the frame's mean lattice over R, equal weight per
pixel. A decoder's band-pass smooths Φ and calflow weights the samples by the lobe's power:
each is its own estimator of (1), and where the distortion is strong their estimates part.

The dots' estimate of (1): every dot's centroid c_k (megarena_dots.centroids) with its
lattice indices (s_k, t_k), a polynomial map of total degree d from pixels to lattice
coordinates fitted by least squares, L_j(p) ≈ Σ_m β_jm·ξ^a·η^b (ξ, η the pixel coordinates
centred on the frame and scaled by half its larger side), then (1) of that polynomial — linear in
β, so exact for each basis function. d is chosen by five-fold cross-validation of the dots'
prediction error; the uncertainty is the bootstrap over dots (resampled with replacement) and,
beside it, the change from d to d + 1 (how much the estimate rests on the map's form).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

CROP = 0.5  # the library's RegressionPlane crop factor: the central half of each side


def library_region(h: int, w: int, crop: float = CROP):
    """The library's plane-fit region: (row slice, column slice, p₀ = (x₀, y₀)), pixel centres at
    integer coordinates. ⌊n·crop/2⌋ rows (columns) are left out on each side; its mesh is zero at
    the region's start plus half its length (for even lengths, as every frame here)."""
    ro, co = int(h * crop / 2), int(w * crop / 2)
    nr, nc = h - 2 * ro, w - 2 * co
    return slice(ro, ro + nr), slice(co, co + nc), (co + nc // 2, ro + nr // 2)


def _exponents(degree: int) -> list[tuple[int, int]]:
    return [(a, n - a) for n in range(degree + 1) for a in range(n, -1, -1)]


@dataclass
class LatticeMap:
    """A polynomial map from pixels (x, y) to lattice coordinates (s, t), total degree ``degree``."""

    degree: int
    coef: np.ndarray  # (m, 2): per basis function, s and t
    centre: tuple[float, float]
    scale: float

    def basis(self, x, y) -> np.ndarray:
        xi, eta = (
            (np.asarray(x, float) - self.centre[0]) / self.scale,
            (np.asarray(y, float) - self.centre[1]) / self.scale,
        )
        return np.stack([xi**a * eta**b for a, b in _exponents(self.degree)], axis=-1)

    def __call__(self, x, y) -> np.ndarray:
        return self.basis(x, y) @ self.coef


def fit_map(xy: np.ndarray, st: np.ndarray, degree: int, shape: tuple[int, int]) -> LatticeMap:
    """Least-squares polynomial map of ``degree`` from the dots' pixel positions ``xy`` (n, 2) to
    their lattice indices ``st`` (n, 2), on a frame of ``shape`` (h, w)."""
    h, w = shape
    m = LatticeMap(degree, np.zeros((0, 2)), ((w - 1) / 2, (h - 1) / 2), max(h, w) / 2)
    B = m.basis(xy[:, 0], xy[:, 1])
    m.coef = np.linalg.lstsq(B, st, rcond=None)[0]
    return m


def plane_operator(m: LatticeMap, shape: tuple[int, int], crop: float = CROP) -> np.ndarray:
    """(3, n_basis): Eq. (1) of each basis function over the library's region — the plane's value
    at p₀ and its slopes along x and y (per pixel) — so that Eq. (1) of the map is this @ coef."""
    rows, cols, (x0, y0) = library_region(*shape, crop)
    y, x = np.mgrid[rows, cols]
    A = np.stack([np.ones(x.size), (x - x0).ravel(), (y - y0).ravel()], 1)
    B = m.basis(x.ravel(), y.ravel())
    return np.linalg.solve(A.T @ A, A.T @ B)


def cv_degree(xy, st, shape, degrees=range(1, 8), folds: int = 5, seed: int = 0) -> tuple[int, dict]:
    """The degree of least five-fold cross-validated rms prediction error (pixels of lattice
    coordinate × the mean period are not needed: the error is in periods), and every degree's."""
    rng = np.random.default_rng(seed)
    part = rng.permutation(len(xy)) % folds
    errs = {}
    for d in degrees:
        if len(xy) < 3 * len(_exponents(d)):
            break
        sq = 0.0
        for f in range(folds):
            m = fit_map(xy[part != f], st[part != f], d, shape)
            sq += float(((m(xy[part == f, 0], xy[part == f, 1]) - st[part == f]) ** 2).sum())
        errs[d] = math.sqrt(sq / (2 * len(xy)))
    return min(errs, key=errs.get), errs


def estimand(xy, st, shape, degree: int, boot: int = 200, seed: int = 1, crop: float = CROP) -> dict:
    """Eq. (1) for both lattice coordinates from the dots, with its bootstrap spread.

    Returns ``plane`` (2, 3): per coordinate (s, t) its value at p₀ (periods) and slopes
    (periods per pixel); ``boot`` (boot, 2, 3) the bootstrap replicates; ``rms`` the map's
    residual rms (periods); ``map`` the LatticeMap."""
    m = fit_map(xy, st, degree, shape)
    P = plane_operator(m, shape, crop)
    rng = np.random.default_rng(seed)
    B = m.basis(xy[:, 0], xy[:, 1])
    reps = np.empty((boot, 2, 3))
    for b in range(boot):
        k = rng.integers(0, len(xy), len(xy))
        reps[b] = (P @ np.linalg.lstsq(B[k], st[k], rcond=None)[0]).T
    res = B @ m.coef - st
    return {"plane": (P @ m.coef).T, "boot": reps, "rms": float(np.sqrt((res**2).mean())), "map": m}


def smoothed_plane(m: LatticeMap, shape, sigma_xy: tuple[float, float], crop: float = CROP) -> np.ndarray:
    """Eq. (1) of the map after a Gaussian smoothing of σ = (σ_x, σ_y) pixels — to first order what
    a Gaussian band-pass of the lobe does to a smooth phase. (2, 3) as ``estimand``'s plane."""
    from scipy.ndimage import gaussian_filter

    h, w = shape
    y, x = np.mgrid[0:h, 0:w]
    field = m(x, y)  # (h, w, 2)
    rows, cols, (x0, y0) = library_region(h, w, crop)
    ys, xs = np.mgrid[rows, cols]
    A = np.stack([np.ones(xs.size), (xs - x0).ravel(), (ys - y0).ravel()], 1)
    out = np.empty((2, 3))
    for j in range(2):
        f = gaussian_filter(field[..., j], (sigma_xy[1], sigma_xy[0]), mode="nearest")
        out[j] = np.linalg.lstsq(A, f[rows, cols].ravel(), rcond=None)[0]
    return out


def library_pose(
    plane: np.ndarray, period: float, axes: tuple[tuple[int, int], tuple[int, int]], offset: float
):
    """Eq. (2): the pose in the library's convention from ``plane`` (2, 3), with ``axes`` naming
    which lattice coordinate (index, sign) is the pattern's x and which its y, and ``offset`` the
    lattice coordinate of a dot (0 bright, 0.5 dark). x, y are modulo the period."""
    (jx, sx), (jy, sy) = axes
    Lx = sx * plane[jx] + np.array([offset, 0, 0])
    Ly = sy * plane[jy] + np.array([offset, 0, 0])
    return {
        "x": -period * Lx[0],
        "y": -period * Ly[0],
        "alpha": math.atan2(Lx[2], Lx[1]),
        "pixelSize": period * math.hypot(Lx[1], Lx[2]),
    }


def match_axes(plane: np.ndarray, alpha: float):
    """The lattice coordinates (index, sign) whose gradients point nearest ``alpha`` (the pattern's
    x axis) and ``alpha + π/2`` (its y axis, as the library's second plane): calflow or the library
    only name the axes; the directions and positions are the dots'."""

    def nearest(direction):
        return min(
            ((j, s) for j in (0, 1) for s in (1, -1)),
            key=lambda js: abs(
                _wrap(math.atan2(js[1] * plane[js[0], 2], js[1] * plane[js[0], 1]) - direction)
            ),
        )

    ax = nearest(alpha)
    ay = nearest(alpha + math.pi / 2)
    return ax, ay


def _wrap(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi


def near(value: float, reference: float, period: float) -> float:
    """``value`` moved by whole periods to lie nearest ``reference`` (positions are modulo P)."""
    return value + period * round((reference - value) / period)


def weighted_plane(
    m: LatticeMap, pts: np.ndarray, power: np.ndarray, shape, crop: float = CROP
) -> np.ndarray:
    """Eq. (1) with calflow's weights instead of the library's: over calflow's coarse samples
    ``pts`` (n, 2) of the central ``crop`` (its own region: |p − p_c| ≤ crop·size/2 about the
    frame centre p_c), each lobe's plane weighted by its power ``power`` (2, n); the value still
    at the library's p₀, so that the two compare. (2, 3) as ``estimand``'s plane."""
    h, w = shape
    _, _, (x0, y0) = library_region(h, w, crop)
    keep = (np.abs(pts[:, 0] - (w - 1) / 2) <= crop * w / 2) & (
        np.abs(pts[:, 1] - (h - 1) / 2) <= crop * h / 2
    )
    x, y = pts[keep, 0], pts[keep, 1]
    A = np.stack([np.ones(x.size), x - x0, y - y0], 1)
    field = m(x, y)
    out = np.empty((2, 3))
    for j in range(2):
        wgt = power[j, keep]
        out[j] = np.linalg.solve(A.T @ (A * wgt[:, None]), A.T @ (wgt * field[:, j]))
    return out


def _cell_phasors(img: np.ndarray, m: LatticeMap, xy: np.ndarray, st: np.ndarray, period_px: float):
    """Per dot wholly inside the frame, Σ_{p ∈ cell k} (I(p) − Ī_k)·exp(2πi·(L_j(p) − st_kj))
    for j = s, t ((n, 2) complex), and those dots' centroids (n, 2): the cell is the pixels
    whose mapped lattice coordinates lie within half a period of the dot's indices."""
    h, w = img.shape
    r = int(math.ceil(0.8 * period_px))
    dy, dx = np.mgrid[-r : r + 1, -r : r + 1]
    ix, iy = np.rint(xy[:, 0]).astype(int), np.rint(xy[:, 1]).astype(int)
    X, Y = ix[:, None, None] + dx, iy[:, None, None] + dy
    full = ((X >= 0) & (X < w) & (Y >= 0) & (Y < h)).all(axis=(1, 2))
    X, Y, st = X[full], Y[full], st[full]
    L = m(X, Y) - st[:, None, None, :]  # (n, box, box, 2)
    cell = np.all(np.abs(L) < 0.5, axis=-1)
    I = img[Y, X].astype(float)
    mean = (I * cell).sum(axis=(1, 2)) / np.maximum(cell.sum(axis=(1, 2)), 1)
    dev = (I - mean[:, None, None]) * cell
    z = np.stack([(dev * np.exp(2j * np.pi * L[..., j])).sum(axis=(1, 2)) for j in (0, 1)], 1)
    return z, xy[full]


def dot_phase_offset(
    img: np.ndarray, m: LatticeMap, xy: np.ndarray, st: np.ndarray, period_px: float
) -> np.ndarray:
    """Where the lobes' phase puts the dots, against where their centroids do (periods, per
    lattice coordinate s, t): over every dot's cell — the pixels whose mapped lattice coordinates
    lie within half a period of its indices — the frame demodulated by the lattice,

        δ_j = arg Σ_k Σ_{p ∈ cell k} (I(p) − Ī_k)·exp(2πi·(L_j(p) − st_kj)) / 2π,

    I the frame with the dots bright, Ī_k its cell's mean. A dot symmetric about its centroid
    gives δ = 0; an asymmetric one (its shape, the illumination's angle, coma) moves the lobes'
    phase, and so both decoders' positions, by P·δ along the lattice from the centroids'."""
    z, _ = _cell_phasors(img, m, xy, st, period_px)
    return np.angle(z.sum(axis=0)) / (2 * np.pi)


def dot_phase_plane(
    img: np.ndarray,
    m: LatticeMap,
    xy: np.ndarray,
    st: np.ndarray,
    period_px: float,
    shape,
    crop: float = CROP,
) -> np.ndarray:
    """``dot_phase_offset`` dot by dot, δ_kj = arg Σ_{p ∈ cell k} (I(p) − Ī_k)·exp(2πi·(L_j(p) −
    st_kj)) / 2π, and its uniform plane over the library's region (least squares over the dots
    whose centroids lie in it, value at p₀, slopes per pixel): (2, 3) as ``estimand``'s plane.
    Where the dots' asymmetry varies across the field (off-axis light, coma), the lobes' phase
    lattice is the centroids' less this plane, not less one mean offset."""
    z, xy = _cell_phasors(img, m, xy, st, period_px)
    delta = np.angle(z) / (2 * np.pi)
    rows, cols, (x0, y0) = library_region(*shape, crop)
    inside = (
        (xy[:, 0] >= cols.start) & (xy[:, 0] < cols.stop) & (xy[:, 1] >= rows.start) & (xy[:, 1] < rows.stop)
    )
    A = np.stack([np.ones(int(inside.sum())), xy[inside, 0] - x0, xy[inside, 1] - y0], 1)
    return np.linalg.lstsq(A, delta[inside], rcond=None)[0].T


def radial_map(shape, centre: tuple[float, float], k: float):
    """A decentred radial distortion q = c + (p − c)·(1 + k·|p − c|²/R²), R the frame's half
    diagonal: the function p ↦ q (pixel arrays), the frame seen through it sampling the
    undistorted one at q."""
    h, w = shape
    R2 = ((w - 1) ** 2 + (h - 1) ** 2) / 4.0

    def q(x, y):
        dx, dy = np.asarray(x, float) - centre[0], np.asarray(y, float) - centre[1]
        f = 1.0 + k * (dx * dx + dy * dy) / R2
        return centre[0] + dx * f, centre[1] + dy * f

    return q


def distort(frame: np.ndarray, qmap) -> np.ndarray:
    """``frame`` resampled through ``qmap`` (cubic spline): the frame a distorting lens shows."""
    from scipy.ndimage import map_coordinates

    h, w = frame.shape
    y, x = np.mgrid[0:h, 0:w]
    qx, qy = qmap(x, y)
    return map_coordinates(frame.astype(float), [qy, qx], order=3, mode="reflect").astype(np.float32)


def true_plane(affine: np.ndarray, qmap, shape, crop: float = CROP) -> np.ndarray:
    """Eq. (1) of a distorted frame whose undistorted lattice is ``affine`` (2, 3): per lattice
    coordinate (u, v) its value at pixel (0, 0) and slopes, L(q) = a + b·q_x + c·q_y, seen
    through ``qmap``: the uniform plane of L(qmap(p)) over the library's region. (2, 3)."""
    rows, cols, (x0, y0) = library_region(*shape, crop)
    y, x = np.mgrid[rows, cols]
    qx, qy = qmap(x.ravel(), y.ravel())
    A = np.stack([np.ones(x.size), (x - x0).ravel(), (y - y0).ravel()], 1)
    L = affine[:, :1] + affine[:, 1:2] * qx + affine[:, 2:3] * qy  # (2, n)
    return np.linalg.lstsq(A, L.T, rcond=None)[0].T


def band_pass_plane(frame, freq, sigma, centre: str = "integer", near=None) -> np.ndarray:
    """The library's estimator: per lobe (``freq`` (2, 2) cycles/px, x then y) a Gaussian
    band-pass of the unwindowed frame's spectrum about the lobe's peak bin (``centre="integer"``:
    the largest bin within one of the frequency) or its frequency itself (``"fitted"``), σ
    ``sigma`` = (bins along x, bins along y); the phase's plane over every pixel of the central
    half, at (w/2, h/2). (2, 3) as megarena_estimand's planes, each intercept's branch nearest
    ``near`` (2, 3)."""
    h, w = frame.shape
    F = np.fft.fft2(frame - frame.mean())
    rows, cols, (x0, y0) = library_region(h, w)
    yy, xx = np.mgrid[rows, cols]
    A = np.stack([np.ones(xx.size), (xx - x0).ravel(), (yy - y0).ravel()], 1)
    ii, jj = np.fft.fftfreq(h) * h, np.fft.fftfreq(w) * w
    plane = np.empty((2, 3))
    for lobe in (0, 1):
        gx, gy = freq[lobe]
        ci, cj = gy * h, gx * w
        if centre == "integer":
            cand = [(round(ci) + a, round(cj) + b) for a in (-1, 0, 1) for b in (-1, 0, 1)]
            ci, cj = max(cand, key=lambda q: abs(F[q[0] % h, q[1] % w]))
        di = (ii[:, None] - ci + h / 2) % h - h / 2
        dj = (jj[None, :] - cj + w / 2) % w - w / 2
        z = np.fft.ifft2(F * np.exp(-((dj / sigma[0]) ** 2 + (di / sigma[1]) ** 2) / 2))[rows, cols]
        carrier = 2 * np.pi * (gx * xx + gy * yy)
        psi = np.unwrap(np.angle(z * np.exp(-1j * carrier)), axis=1)  # along the rows, then
        psi += (np.unwrap(psi[:, 0]) - psi[:, 0])[:, None]  # each row onto the first column's branch
        phi = (psi + carrier) / (2 * np.pi)
        coef = np.linalg.lstsq(A, phi.ravel(), rcond=None)[0]
        if near is not None:
            coef[0] += np.round(near[lobe, 0] - coef[0])
        plane[lobe] = coef
    return plane


def differences(pose: dict, ref: dict) -> dict:
    """pose − ref (library convention, µm and radians) in nm, µrad and %."""
    return {
        "x_nm": 1000 * (pose["x"] - ref["x"]),
        "y_nm": 1000 * (pose["y"] - ref["y"]),
        "alpha_urad": 1e6 * _wrap(pose["alpha"] - ref["alpha"]),
        "pixel_percent": 100 * (pose["pixelSize"] / ref["pixelSize"] - 1),
    }


def summary(rows: list[dict], keys=("x_nm", "y_nm", "alpha_urad", "pixel_percent")) -> dict:
    """Over frames of known truth, each ``*_minus_truth`` difference of the rows' ``estimand``
    (the witness's, calflow's in each convention, the library's): mean, sample sd and count."""
    out: dict = {}
    for row in rows:
        for who, d in row.get("estimand", {}).items():
            if who.endswith("minus_truth"):
                for k in keys:
                    out.setdefault(who, {}).setdefault(k, []).append(d[k])
    return {
        who: {
            k: {"mean": float(np.mean(v)), "sd": float(np.std(v, ddof=1)) if len(v) > 1 else 0.0, "n": len(v)}
            for k, v in d.items()
        }
        for who, d in out.items()
    }
