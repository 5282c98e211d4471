"""A camera on a microscope looking at the pattern: frames rendered at a pose.

Geometry. A pixel (row i, column j) of a ``width × height`` frame sits at the camera-plane
point ``c = pixel_um · (j − (w−1)/2, i − (h−1)/2)`` (µm in the object plane, y along the
rows); radial distortion maps it to ``c · (1 + k1 ρ²)`` with ρ the distance to the centre over
the half-diagonal. The pose (x, y, Θ) places the pattern: the pattern point seen at ``c`` is
``(x, y) + R(−Θ) c`` — (x, y) is the frame centre in pattern coordinates and the pattern's axes
appear turned by Θ (from the camera's x axis towards its y axis) in the frame.

Photometry. Each dot is a disc of the pattern's diameter, blurred by a Gaussian whose variance
sums the objective's diffraction (σ ≈ 0.21 λ/NA, the Gaussian fit of the Airy spot), the
defocus (geometric blur radius NA·Δz, as a Gaussian of the same second moment) and the pixel's
area (pixel²/12). Its exact radial profile is the probability that a 2-D Gaussian around the
point falls in the disc (a non-central χ² with 2 degrees of freedom), tabulated once per
camera. The frame is ``illumination · (background + (dot − background) · Σ dots) · dust``,
exposed to a fraction of the full well, with Poisson shot noise (its normal approximation;
above ~100 electrons the two are indistinguishable here), Gaussian read noise and rounding to
the bit depth. Dots the pattern lacks and dots it has in excess (manufacturing defects) are
drawn once per site from ``defect_seed``, so a defect stays where it is from frame to frame;
dust (on the optics, fixed in the frame) is drawn per frame from ``rng``.

Every default and its source: docs/instruments.md, "The camera model".
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from calflow.instruments.pattern.pattern import Pattern


@dataclass(frozen=True)
class Camera:
    """A camera, its optics and its noise (lengths in µm in the object plane unless stated)."""

    width: int = 1024  # thesis Sec. 4.3: 1024 × 768 mono
    height: int = 768
    sensor_pixel_um: float = 3.75  # AVT Stingray F-125 (Sony ICX445) datasheet
    magnification: float = 10.0  # thesis: 10× objective; zoom lens at 1× assumed
    numerical_aperture: float = 0.28  # assumed: a 10× long-working-distance plan objective
    wavelength_um: float = 0.55  # assumed: white light through a green-weighted mono sensor
    defocus_um: float = 0.0  # distance of the pattern from the focal plane
    background: float = 0.25  # assumed: reflectance of the substrate relative to the dots
    dot_level: float = 1.0  # dots bright (metal on glass, reflected light); < background: dark dots
    illumination_nonuniformity: float = 0.1  # assumed: peak-to-peak relative fall-off over the frame
    exposure: float = 0.6  # assumed: a dot's signal as a fraction of the full well
    full_well_e: float = 10000.0  # assumed, typical of a 3.75 µm interline CCD
    read_noise_e: float = 12.0  # assumed
    bit_depth: int = 8  # assumed: Mono8
    k1: float = 0.0  # radial distortion at the frame's corner (relative)
    dust_count: float = 0.0  # mean number of dust particles per frame
    dust_size_um: float = 10.0  # typical diameter of a dust shadow in the object plane
    missing_dot_rate: float = 0.0  # fraction of the pattern's dots missing (defects)
    extra_dot_rate: float = 0.0  # fraction of the pattern's empty sites carrying a dot
    defect_seed: int = 0

    def __post_init__(self):
        for name in ("width", "height", "bit_depth"):
            v = getattr(self, name)
            if not isinstance(v, int) or isinstance(v, bool) or v < 1:
                raise ValueError(f"Camera.{name}: expected a positive integer, got {v!r}")
        if not 1 <= self.bit_depth <= 16:
            raise ValueError(f"Camera.bit_depth: expected 1 to 16, got {self.bit_depth!r}")
        for name in (
            "sensor_pixel_um",
            "magnification",
            "numerical_aperture",
            "wavelength_um",
            "full_well_e",
        ):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and v > 0 and math.isfinite(v)):
                raise ValueError(f"Camera.{name}: expected a positive number, got {v!r}")
        for name in ("missing_dot_rate", "extra_dot_rate", "illumination_nonuniformity"):
            v = getattr(self, name)
            if not 0 <= v <= 1:
                raise ValueError(f"Camera.{name}: expected a fraction from 0 to 1, got {v!r}")
        if not self.numerical_aperture < 1:
            raise ValueError(
                f"Camera.numerical_aperture: expected below 1 (dry objective), got {self.numerical_aperture!r}"
            )

    @property
    def pixel_um(self) -> float:
        """Pixel size in the object plane (µm)."""
        return self.sensor_pixel_um / self.magnification

    @property
    def psf_sigma_um(self) -> float:
        """σ of the Gaussian approximating the in-focus Airy spot, 0.21 λ/NA (µm)."""
        return 0.21 * self.wavelength_um / self.numerical_aperture

    @property
    def blur_sigma_um(self) -> float:
        """σ of the whole blur: diffraction, defocus (disc of radius NA·|Δz|: σ = r/2) and pixel."""
        defocus = self.numerical_aperture * abs(self.defocus_um) / 2.0
        return math.sqrt(self.psf_sigma_um**2 + defocus**2 + self.pixel_um**2 / 12.0)

    @property
    def max_level(self) -> int:
        return (1 << self.bit_depth) - 1

    @property
    def noise_dn(self) -> float:
        """Typical noise of a mid-level pixel (DN): shot, read and quantisation."""
        gain = self.full_well_e / self.max_level  # electrons per DN
        mid = 0.5 * (self.background + self.dot_level) * self.exposure * self.full_well_e
        return math.sqrt((mid + self.read_noise_e**2) / gain**2 + 1 / 12)

    # -- rendering ---------------------------------------------------------------------------
    def render(self, pattern: Pattern, x_um: float, y_um: float, theta_deg: float, rng=None) -> np.ndarray:
        """One frame (uint8 up to 8 bits, uint16 beyond) of the pattern at a pose, shape (height, width).

        ``rng`` (a ``numpy.random.Generator`` or a seed) draws the noise and dust; ``rng=None``
        renders the noise-free expectation, unrounded, as float32.
        """
        expect = self.expectation(pattern, x_um, y_um, theta_deg)
        if rng is None:
            return expect
        return self.expose(expect, np.random.default_rng(rng))

    def render_batch(self, pattern: Pattern, poses, rng=None) -> np.ndarray:
        """Frames at ``poses`` (n, 3: x µm, y µm, Θ degree), shape (n, height, width)."""
        poses = np.asarray(poses, dtype=float)
        if poses.ndim != 2 or poses.shape[1] != 3:
            raise ValueError(f"poses: expected an array of shape (n, 3), got {poses.shape}")
        gen = None if rng is None else np.random.default_rng(rng)
        dtype = np.float32 if gen is None else (np.uint8 if self.bit_depth <= 8 else np.uint16)
        out = np.empty((len(poses), self.height, self.width), dtype=dtype)
        for k, (x, y, t) in enumerate(poses):
            e = self.expectation(pattern, x, y, t)
            out[k] = e if gen is None else self.expose(e, gen)
        return out

    def object_points(self, x_um: float, y_um: float, theta_deg: float):
        """Pattern coordinates (µm, float64) of every pixel centre: two arrays (height, width)."""
        X, Y = self._camera_points()
        t = math.radians(theta_deg)
        ct, st = math.cos(t), math.sin(t)
        if X.ndim == 1:  # no distortion: separable
            return (x_um + ct * X[None, :] + st * Y[:, None]), (y_um - st * X[None, :] + ct * Y[:, None])
        return x_um + ct * X + st * Y, y_um - st * X + ct * Y

    def _camera_points(self):
        """Camera-plane coordinates (µm) of the pixel centres, distorted: 1-D (x, y) when k1 is 0."""
        h, w, px = self.height, self.width, self.pixel_um
        cx = (np.arange(w) - (w - 1) / 2.0) * px
        cy = (np.arange(h) - (h - 1) / 2.0) * px
        if not self.k1:
            return cx, cy
        half_diag2 = ((w - 1) ** 2 + (h - 1) ** 2) / 4.0 * px * px
        scale = 1.0 + self.k1 * (cx[None, :] ** 2 + cy[:, None] ** 2) / half_diag2
        return cx[None, :] * scale, cy[:, None] * scale

    def expectation(self, pattern: Pattern, x_um: float, y_um: float, theta_deg: float) -> np.ndarray:
        """The noise-free frame in DN (float32), before dust."""
        p = pattern.period_um
        u, v = self.object_points(x_um + pattern.origin_um[0], y_um + pattern.origin_um[1], theta_deg)
        u /= p  # site coordinates, fractional: column u, row v
        v /= p
        c0 = np.floor(u)
        r0 = np.floor(v)
        fu = (u - c0).astype(np.float32)
        fv = (v - r0).astype(np.float32)
        sigma = self.blur_sigma_um
        radius = pattern.dot_diameter_um / 2.0
        reach = int(math.ceil((radius + 5.0 * sigma) / p))  # sites beyond it add < 3e-7 of a dot
        step, table = _profile_table(radius / p, sigma / p, float(2 * reach * reach))
        lo_c, lo_r = int(c0.min()) - reach, int(r0.min()) - reach
        hi_c, hi_r = int(c0.max()) + reach + 1, int(r0.max()) + reach + 1
        rows = np.arange(lo_r, hi_r + 1)[:, None]
        cols = np.arange(lo_c, hi_c + 1)[None, :]
        present = pattern.present(rows, cols)
        present = _defects(present, rows, cols, self.missing_dot_rate, self.extra_dot_rate, self.defect_seed)
        ncols = present.shape[1]
        flat = present.astype(np.float32).ravel()
        site = ((r0 - lo_r) * ncols + (c0 - lo_c)).astype(np.int32)
        dots = np.zeros(fu.shape, dtype=np.float32)
        last = len(table) - 2
        for dr in range(-reach + 1, reach + 1):
            dv2 = (fv - dr) ** 2
            for dc in range(-reach + 1, reach + 1):
                q = ((fu - dc) ** 2 + dv2) * np.float32(1.0 / step)  # squared distance in table steps
                i = np.minimum(q.astype(np.int32), last)
                f = np.minimum(q - i, np.float32(1.0))
                val = table[i] + f * (table[i + 1] - table[i])
                dots += flat[site + (dr * ncols + dc)] * val
        level = np.float32(self.background) + np.float32(self.dot_level - self.background) * dots
        level *= _illumination(self.illumination_nonuniformity, self.height, self.width)
        level *= np.float32(self.exposure * self.max_level)
        return level

    def expose(self, expectation: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """Dust, shot noise, read noise and rounding applied to an expected frame (DN)."""
        gain = self.full_well_e / self.max_level
        electrons = expectation * np.float32(gain)
        if self.dust_count > 0:
            electrons = electrons * self._dust(rng)
        np.clip(electrons, 0, None, out=electrons)
        noise = rng.standard_normal(electrons.shape, dtype=np.float32)
        electrons += np.sqrt(electrons + np.float32(self.read_noise_e**2)) * noise
        dn = np.clip(np.rint(electrons * np.float32(1 / gain)), 0, self.max_level)
        return dn.astype(np.uint8 if self.bit_depth <= 8 else np.uint16)

    def _dust(self, rng: np.random.Generator) -> np.ndarray:
        h, w = self.height, self.width
        out = np.ones((h, w), dtype=np.float32)
        n = rng.poisson(self.dust_count) if self.dust_count > 0 else 0
        for _ in range(n):  # a few particles per frame: a loop over particles, not dots
            d = self.dust_size_um * rng.uniform(0.5, 1.5) / self.pixel_um
            r = d / 2
            ci, cj = rng.uniform(0, h), rng.uniform(0, w)
            opacity = rng.uniform(0.3, 0.9)
            edge = max(self.blur_sigma_um / self.pixel_um, 1.0) * 3
            i0, i1 = max(0, int(ci - r - edge)), min(h, int(ci + r + edge) + 1)
            j0, j1 = max(0, int(cj - r - edge)), min(w, int(cj + r + edge) + 1)
            if i0 >= i1 or j0 >= j1:
                continue
            ii, jj = np.mgrid[i0:i1, j0:j1]
            dist = np.hypot(ii - ci, jj - cj)
            shade = opacity * np.clip((r + edge / 3 - dist) / (2 * edge / 3), 0, 1)
            out[i0:i1, j0:j1] *= 1 - shade
        return out


@lru_cache(maxsize=32)
def _profile_table(radius: float, sigma: float, max_d2: float):
    """Radial profile of a disc (radius, in periods) blurred by a Gaussian (σ, in periods),
    tabulated against the squared distance (periods²) up to ``max_d2``: (step, values float32)."""
    from scipy.stats import ncx2

    n = 16384
    step = max_d2 / (n - 2)
    d2 = np.arange(n) * step
    return step, ncx2.cdf((radius / sigma) ** 2, 2, d2 / sigma**2).astype(np.float32)


@lru_cache(maxsize=64)
def _illumination(a: float, h: int, w: int) -> np.ndarray:
    """Relative illumination: a quadratic fall-off and a tilt, peak-to-peak ``a``."""
    if not a:
        return np.ones((h, w), dtype=np.float32)
    X = np.linspace(-1, 1, w, dtype=np.float32)[None, :]
    Y = np.linspace(-1, 1, h, dtype=np.float32)[:, None]
    shape = 0.6 * (X**2 + Y**2) / 2 + 0.4 * (X + Y + 2) / 4  # 0 at the brightest corner … 1
    return (1.0 - a * shape).astype(np.float32)


def _defects(present, rows, cols, missing: float, extra: float, seed: int) -> np.ndarray:
    """Sites that lost their dot or gained one, drawn once per site (a hash of its indices)."""
    if not (missing or extra):
        return present
    h = (rows.astype(np.uint64) * np.uint64(0x9E3779B97F4A7C15)) ^ (
        cols.astype(np.uint64) * np.uint64(0xC2B2AE3D27D4EB4F)
    )
    h = h ^ np.uint64((seed * 0x165667B19E3779F9) & 0xFFFFFFFFFFFFFFFF)
    h ^= h >> np.uint64(31)
    h *= np.uint64(0xBF58476D1CE4E5B9)
    h ^= h >> np.uint64(29)
    uniform = (h >> np.uint64(11)).astype(np.float64) / float(1 << 53)
    return np.where(present, uniform >= missing, uniform < extra)
