"""The linear part of the decoding (thesis Sec. 3.5.1, steps 2–6): the grid's two phase planes.

Each frame is windowed (Tukey, so that the frame's edges do not leak into the lobes), Fourier
transformed (step 2), and the two lobes of the grid's fundamental — one per lattice
direction — are found on the ring where the pattern's period puts them. A box of the spectrum
around each lobe is cut out (step 3, the band-pass) and inverse transformed on its own small
grid (step 4): the result is the lobe's complex field sampled every few pixels over the whole
frame. Its phase, demodulated by the lobe's frequency, is unwrapped (step 5) and a plane is
fitted to it by weighted least squares (step 6), the weights the field's squared amplitude.

The plane gives, per lobe, the lattice coordinate of the frame centre (its intercept over 2π)
and the lattice's spatial frequency (its slope), each with the covariance of the fit.

The code's envelope (``envelope=True``, for layouts whose code leaves dots out, or whose grid
ends inside the fitted region: an HP-code marker's edge bends the phase the same way). A frame of
dots a_n ∈ {0, 1} at the lattice nodes r_n is I = Σ a_n D(r − r_n); near the lobe k₀ its
spectrum is D̂(k₀ + δ)·Â(δ), Â the spectrum of the dots kept. Were D̂ even about k₀, the
band-passed field would be the carrier times a real envelope and its phase exact. It is not:
a dot's transfer function falls with |k| (for a disc of half the period's diameter by about a
quarter between k₀ ± k₀/3, where the code's rows and columns put their sidebands). With
D̂(k₀ + δ) ≈ D̂(k₀)·exp(γ·δ) the envelope is shifted by the imaginary vector −iγ/2π, and to
first order the field's phase is off by

    Δψ(r) = c · ∇ln|z(r)|,        c = −γ/2π (pixels),

the gradient of the field's log-amplitude (Re(∇z/z), computed exactly from the band-passed
box times 2πi·δ). Where rows or columns of dots are missing, that gradient is large and the
plane tilts: tens of µrad of angle over half a frame. The plane is fitted with these two
gradients as nuisance regressors, c one vector per lobe and frame, so the bias is removed
whatever the dots' shape, blur or focus, and the covariance of (phase, slopes) is their
marginal one. The samples of the window's taper are left out of that fit: there the field's
amplitude falls by the window (which multiplies the frame after the dots are drawn, so it
biases nothing) and the circular transform mixes the opposite edges.

Cramér–Rao bound of the intercept. Near a lobe the frame is I(r) = B(r) + A(r) cos Φ(r) + n(r),
Φ(r) = φ₀ + 2π k·(r − r_c), with white noise of variance σ²(r). With centred coordinates the
intercept decouples from the slopes, and the Fisher information of φ₀ is
J = Σ_r A(r)² sin² Φ(r) / σ²(r) ≈ Σ_r A(r)² / (2σ²(r)), so var(φ̂₀) ≥ 1/J and the position
along the lobe's direction has σ ≥ p/(2π)·J^(−1/2) (p the period). The benchmark computes J
from the noise-free frame's lobe (:func:`lobe_information`) and the camera's noise.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

from calflow.instruments.pattern.spectrum import (
    corners,
    fast_length,
    on_flat,
    ring,
    scratch,
    subbin,
    tapered,
    window,
)

CROP = 0.35  # half-width of the band-pass box, as a fraction of the lobe's frequency
GAUSS = 2.5  # the box half-width in standard deviations of the Gaussian band-pass


@dataclass
class Planes:
    """Per frame (arrays of length n): each lobe's phase at the frame centre and frequency."""

    phase: np.ndarray  # (n, 2) radians at the frame centre (unwrapped branch arbitrary)
    freq: np.ndarray  # (n, 2, 2) cycles per pixel, lobe × (along columns x, along rows y)
    cov: np.ndarray  # (n, 2, 3, 3) covariance of (phase, slope_x, slope_y) per lobe, rad & rad/px
    peak_ratio: np.ndarray  # (n, 2) lobe power over the ring's median power
    amplitude: np.ndarray  # (n, 2) mean |field| of the lobe (DN)
    fields: np.ndarray  # (n, 2, ni·nj) the band-passed lobes on the coarse grid (complex)
    bins: np.ndarray  # (n, 2, 2) each lobe's integer bin (row signed, column)
    gradients: np.ndarray | None = None  # (n, 2, 2, ni·nj) ∇ln|field| (1/px, x then y), envelope fits
    var_all: np.ndarray | None = None  # (n, 2) the intercept's variance of a plain fit over every sample


class PhaseFitter:
    """Steps 2–6 for frames of one shape and one expected lobe frequency (cycles per pixel).

    ``envelope``: fit the planes with the code's envelope regressors, on the window's flat
    part (module docstring); off, the planes are those of a plain weighted fit. ``pad``: zero-pad
    the windowed frame to the next length the FFT does fast (a side of 856 = 8 × 107 pixels
    costs twice one of 864); ``h`` and ``w`` are then the transform's size, ``frame_shape`` the
    frame's."""

    def __init__(
        self,
        shape: tuple[int, int],
        f0: float,
        workers: int | None = None,
        envelope: bool = False,
        pad: bool = False,
    ):
        fh, fw = shape
        h, w = (fast_length(fh), fast_length(fw)) if pad else (fh, fw)
        self.h, self.w, self.f0 = h, w, float(f0)
        self.frame_shape = (fh, fw)
        self.padding = (h * w) / (fh * fw)  # transform bins per frame pixel: 1 unpadded
        self.envelope = bool(envelope)
        self.workers = workers or os.cpu_count() or 1
        self.window = window(fh, fw)
        self.ring_i, self.ring_j, self.ring_angle = ring(h, w, self.f0)
        self.ring_flat = self.ring_i * (w // 2 + 1) + self.ring_j  # one gather per frame
        self.corner = corners(h, w)
        self.bi = max(2, int(math.ceil(CROP * f0 * h)))
        self.bj = max(2, int(math.ceil(CROP * f0 * w)))
        self.ni = fast_length(2 * self.bi + 1)
        self.nj = fast_length(2 * self.bj + 1)
        di = np.arange(-self.bi, self.bi + 1)
        dj = np.arange(-self.bj, self.bj + 1)
        self.di, self.dj = np.meshgrid(di, dj, indexing="ij")
        # sample points of the cropped field, pixels from the frame centre
        self.yc, self.xc = (fh - 1) / 2.0, (fw - 1) / 2.0
        self.ym1 = np.arange(self.ni) * (h / self.ni)
        self.xm1 = np.arange(self.nj) * (w / self.nj)
        self.ym, self.xm = np.meshgrid(self.ym1, self.xm1, indexing="ij")
        self.sample_row = np.repeat(np.arange(self.ni), self.nj)  # each coarse sample's row, column
        self.sample_col = np.tile(np.arange(self.nj), self.ni)
        # the plane's design matrix (1, x − x_c, y − y_c) over the coarse samples
        xr, yr = self.xm.ravel(), self.ym.ravel()
        self.A = np.stack([np.ones_like(xr), xr - self.xc, yr - self.yc], axis=1)
        # the coarse samples on the window's flat part, and the box's derivative factors (rad/px)
        self.flat = (on_flat(self.ym, fh) & on_flat(self.xm, fw)).ravel().astype(float)
        self.ddx = (2j * np.pi / w) * self.dj
        self.ddy = (2j * np.pi / h) * self.di

    def spectrum(self, frames: np.ndarray) -> np.ndarray:
        """Step 2: the windowed, mean-removed frames' half-plane spectrum (n, h, w//2+1)."""
        frames = np.asarray(frames, dtype=np.float32)  # no copy of float32 frames
        out = scratch(frames.shape, "windowed") if len(frames) == 1 else None
        f = np.subtract(frames, frames.mean(axis=(1, 2), keepdims=True), out=out)
        # times the window where it is not 1 (its tapered bands: a third of the frame)
        for rows, cols in tapered(*self.frame_shape):
            f[:, rows, cols] *= self.window[rows, cols]
        import scipy.fft

        if (self.h, self.w) != self.frame_shape:  # zero-padded at the far edges: the window is 0 there
            return scipy.fft.rfft2(f, s=(self.h, self.w), workers=self.workers)
        return scipy.fft.rfft2(f, workers=self.workers)

    def lobes(self, spec: np.ndarray):
        """The two lobes' integer bins (n, 2, 2: row index signed, column index) and peak ratios."""
        n = len(spec)
        power = np.abs(spec.reshape(n, -1).take(self.ring_flat, axis=1)) ** 2
        first = np.argmax(power, axis=1)
        a1 = self.ring_angle[first]
        diff = (self.ring_angle[None, :] - a1[:, None] - 90.0 + 90.0) % 180.0 - 90.0
        second_mask = np.abs(diff) < 20.0
        p2 = np.where(second_mask, power, -1.0)
        second = np.argmax(p2, axis=1)
        med = np.median(power, axis=1) + 1e-30
        ratio = np.stack([power[np.arange(n), first] / med, power[np.arange(n), second] / med], axis=1)
        idx = np.stack([first, second], axis=1)
        i = self.ring_i[idx]
        i = np.where(i > self.h // 2, i - self.h, i)
        j = self.ring_j[idx]
        return np.stack([i, j], axis=2), ratio

    def crop(self, spec: np.ndarray, k: int, i0: int, j0: int) -> np.ndarray:
        """Step 3: the box of frame k's spectrum around bin (i0, j0), conjugate-mirrored where j < 0."""
        if 0 <= j0 - self.bj and j0 + self.bj < spec.shape[2]:  # no column mirrored: a slice of them
            return spec[k, (i0 + self.di[:, 0]) % self.h, j0 - self.bj : j0 + self.bj + 1]
        ii = i0 + self.di
        jj = j0 + self.dj
        neg = jj < 0
        ie = np.where(neg, -ii, ii) % self.h
        je = np.where(neg, -jj, jj)
        vals = spec[k, ie, je]
        return np.where(neg, np.conj(vals), vals)

    def noise_power(self, spec: np.ndarray) -> np.ndarray:
        """Mean noise power per bin (n,), from the spectrum's corners beyond 0.4 cycle per pixel,
        where a microscope's optics leave only noise (an undersampled image overstates it)."""
        if self.corner is None:  # a frame too small to have corners
            return np.full(len(spec), np.nan)
        corner = np.abs(spec[:, self.corner[0], self.corner[1]]) ** 2
        return np.median(corner.reshape(len(spec), -1), axis=1) / math.log(2)

    def fit(self, spec: np.ndarray) -> Planes:
        """Steps 3–6 for every frame: a first pass with a box around each lobe's peak bin, then
        a Gaussian band-pass centred on the lobe's fitted frequency (symmetric about it, so that
        the missing dots, a real modulation, change the field's amplitude and not its phase)."""
        n = len(spec)
        bins, ratio = self.lobes(spec)
        crops = np.empty((n, 2) + self.di.shape, dtype=np.complex64)
        sub = np.zeros((n, 2, 2))
        for k in range(n):
            for lobe in (0, 1):
                crops[k, lobe] = self.crop(spec, k, *bins[k, lobe])
                sub[k, lobe] = subbin(np.abs(crops[k, lobe]), self.bi, self.bj)
        freq = np.stack(
            [(bins[..., 1] + sub[..., 1]) / self.w, (bins[..., 0] + sub[..., 0]) / self.h], axis=-1
        )
        first = self._planes(crops, bins, freq)
        sigma = CROP * self.f0 / GAUSS  # cycles per pixel
        # offsets of each crop bin from the fitted frequency, in cycles per pixel
        oy = (bins[..., 0, None, None] + self.di) / self.h - first[1][..., 1, None, None]
        ox = (bins[..., 1, None, None] + self.dj) / self.w - first[1][..., 0, None, None]
        H = np.exp(-(ox**2 + oy**2) / (2 * sigma**2))
        phase, freq, cov, fields, grads, share = self._planes(crops * H, bins, first[1], final=True)
        # the intercept's variance from the noise the spectrum shows (module docstring)
        n0 = self.noise_power(spec)
        pw = np.abs(crops) ** 2
        num = np.sum(H**4 * pw, axis=(2, 3))
        den = np.sum(H**2 * pw, axis=(2, 3)) ** 2
        # padded bins sample the same spectrum more finely (correlated): the sums grow by it
        var0 = 0.5 * n0[:, None] * num / np.maximum(den, 1e-300) * self.padding
        if self.envelope:  # fewer samples and two nuisance regressors: a larger variance
            cov = cov * (var0 * share / np.maximum(cov[..., 0, 0], 1e-300))[..., None, None]
        else:
            cov = cov * (var0 / np.maximum(cov[..., 0, 0], 1e-300))[..., None, None]
        amp = np.sqrt(np.sum(H**2 * pw, axis=(2, 3)) / self.padding) / (
            self.frame_shape[0] * self.frame_shape[1]
        )
        return Planes(
            phase=phase,
            freq=freq,
            cov=cov,
            peak_ratio=ratio,
            amplitude=amp,
            fields=fields,
            bins=bins,
            gradients=grads,
            var_all=var0,
        )

    def coarse_points(self) -> np.ndarray:
        """Pixel positions (x, y) of the coarse grid the lobes' fields are sampled on, (ni·nj, 2)."""
        return np.stack([self.xm.ravel(), self.ym.ravel()], axis=1)

    def region_share(self, fraction: float) -> np.ndarray:
        """Each coarse sample's share of its cell (the coarse step about it) that lies in the
        frame's central ``fraction``: the pixels from ⌊n·(1 − fraction)/2⌋ on each side of a side
        of n, as the Vernier library crops (pixel centres at integer coordinates). Weights that
        make a plane over the samples that of every pixel of the region alike, (ni·nj,). The
        samples' cells end half a coarse step before the far edges: a region reaching into that
        margin (a fraction near 1) is counted short there."""
        share = []
        for pos, step, n in (
            (self.xm1, self.w / self.nj, self.frame_shape[1]),
            (self.ym1, self.h / self.ni, self.frame_shape[0]),
        ):
            lo = int(n * (1.0 - fraction) / 2) - 0.5
            hi = n - int(n * (1.0 - fraction) / 2) - 0.5
            share.append(
                np.clip(np.minimum(pos + step / 2, hi) - np.maximum(pos - step / 2, lo), 0.0, None) / step
            )
        return (share[1][:, None] * share[0][None, :]).ravel()

    def refit(self, planes: Planes, k: int, keep: np.ndarray):
        """Frame k's two planes again, from the coarse samples in ``keep`` only (where the
        pattern is seen: not under dust, not beyond its edge). Returns (phase, freq, cov).

        Each sample is weighted by the lobe's power |z|² — the inverse of its phase's noise
        variance (σ²/2|z|² for additive noise of variance σ²), so the least-variance plane. The
        Vernier library's plane, every pixel of a region alike, is
        :func:`calflow.instruments.pattern.megarena.uniform.uniform_planes`."""
        phase = np.empty(2)
        freq = np.empty((2, 2))
        cov = np.empty((2, 3, 3))
        envelope = self.envelope and planes.gradients is not None
        for lobe in (0, 1):
            z = planes.fields[k, lobe].astype(np.complex128)
            wgt = np.abs(z) ** 2
            extra = planes.gradients[k, lobe] if envelope else None
            if envelope:
                kept = wgt * keep * self.flat
                phase[lobe], freq[lobe], c, infl = self._fit(
                    z, kept, planes.bins[k, lobe], planes.freq[k, lobe], extra
                )
                scale = planes.var_all[k, lobe] * infl * wgt.sum() / max(kept.sum(), 1e-300)
            else:
                kept = wgt * keep
                phase[lobe], freq[lobe], c, _ = self._fit(z, kept, planes.bins[k, lobe], planes.freq[k, lobe])
                # the noise's share grows as samples are left out (the same noise per sample)
                scale = planes.cov[k, lobe, 0, 0] * wgt.sum() / max(kept.sum(), 1e-300)
            cov[lobe] = c * (scale / max(c[0, 0], 1e-300))
        return phase, freq, cov

    def _planes(self, crops, bins, freq, final: bool = False):
        """Inverse transforms of the crops (step 4), then per lobe the demodulated phase
        unwrapped (step 5) and its weighted least-squares plane (step 6), from ``freq``
        (n, 2, (x, y)) cycles per pixel. Returns (phase at the centre, frequency, covariance,
        the fields, and — for the ``final`` pass of an envelope fit — the fields' log-amplitude
        gradients and each fit's variance factor over a plain fit on every sample)."""
        n = len(crops)
        envelope = self.envelope and final
        boxes = np.zeros(((3 if envelope else 1) * n, 2, self.ni, self.nj), dtype=np.complex64)
        self._into_boxes(boxes[:n], crops)
        if envelope:  # the fields' derivatives along x and y, exactly, from the same boxes
            self._into_boxes(boxes[n : 2 * n], crops * self.ddx)
            self._into_boxes(boxes[2 * n :], crops * self.ddy)
        import scipy.fft

        every = scipy.fft.ifft2(boxes, workers=self.workers).reshape(len(boxes), 2, -1)
        flat = every[:n]
        grads = share = None
        if envelope:
            # Re(∇z/z) = Re(∇z·z̄)/|z|², without a complex division
            zc = np.conj(flat)
            power = flat.real**2 + flat.imag**2
            inv = np.divide(1.0, power, out=np.zeros_like(power), where=power > 0)
            grads = np.stack([(every[n : 2 * n] * zc).real * inv, (every[2 * n :] * zc).real * inv], axis=2)
            share = np.empty((n, 2))
        phase = np.empty((n, 2))
        out_f = np.empty((n, 2, 2))
        cov = np.empty((n, 2, 3, 3))
        for k in range(n):
            for lobe in (0, 1):
                z = flat[k, lobe].astype(np.complex128)
                if envelope:
                    wgt = np.abs(z) ** 2
                    used = wgt * self.flat
                    phase[k, lobe], out_f[k, lobe], cov[k, lobe], infl = self._fit(
                        z, used, bins[k, lobe], freq[k, lobe], grads[k, lobe]
                    )
                    share[k, lobe] = infl * wgt.sum() / max(used.sum(), 1e-300)
                else:  # the first pass gives the frequency only: no covariance
                    phase[k, lobe], out_f[k, lobe], cov[k, lobe], _ = self._fit(
                        z, np.abs(z) ** 2, bins[k, lobe], freq[k, lobe], covariance=final
                    )
        return phase, out_f, cov, flat, grads, share

    def _into_boxes(self, boxes, crops):
        """Each crop (offsets −b…b from its lobe) into its box at those offsets modulo the box:
        four blocks, the offsets ≥ 0 at the start of each axis and the negative ones at its end
        (``boxes[..., di % ni, dj % nj] = crops``, by slices)."""
        bi, bj, ni, nj = self.bi, self.bj, self.ni, self.nj
        boxes[..., : bi + 1, : bj + 1] = crops[..., bi:, bj:]
        boxes[..., : bi + 1, nj - bj :] = crops[..., bi:, :bj]
        boxes[..., ni - bi :, : bj + 1] = crops[..., :bi, bj:]
        boxes[..., ni - bi :, nj - bj :] = crops[..., :bi, :bj]

    def _fit(self, z, wgt, bin_, freq, extra=None, covariance=True, noise=None):
        """One lobe: demodulate by ``freq``, unwrap, weighted LS plane, twice (steps 5–6), with
        the rows of ``extra`` (m, samples) as nuisance regressors when given. Returns (phase at
        the frame centre, frequency (x, y) cycles/px, covariance of (phase, slopes), and the
        factor by which the regressors raise the intercept's variance; NaN for the last two
        without ``covariance``). With ``noise`` (each sample's phase variance, up to one
        constant) the covariance is the sandwich N⁻¹·Aᵀ·diag(wgt²·noise)·A·N⁻¹ in that
        constant's units, for weights that are not the noise's inverse."""
        A = self.A
        if extra is not None:  # the samples that count only, and the regressors' columns
            used = np.flatnonzero(wgt)
            rows, cols = self.sample_row[used], self.sample_col[used]
            A = np.empty((len(used), 3 + len(extra)))
            A[:, :3] = self.A[used]
            A[:, 3:] = extra[:, used].T
            z, wgt = z[used], wgt[used]
            if noise is not None:
                noise = noise[used]
        base_x, base_y = bin_[1] / self.w, bin_[0] / self.h
        gx, gy = freq
        if not (np.isfinite(wgt).all() and np.count_nonzero(wgt) > A.shape[1]):
            return math.nan, (math.nan, math.nan), np.full((3, 3), math.nan), math.nan
        Aw = A * wgt[:, None]
        N = A.T @ Aw
        seen = wgt > 0
        every = extra is not None or bool(seen.all())  # no sample to leave out of the reference
        for _ in range(2):  # demodulate by the current frequency, fit, again
            # exp(2πi(a·x + b·y)) over the coarse grid, as the product of its row and column parts
            ey = np.exp(2j * np.pi * (base_y - gy) * self.ym1)
            ex = np.exp(2j * np.pi * (base_x - gx) * self.xm1)
            if extra is None:
                zz = z * (ey[:, None] * ex[None, :]).ravel()
            else:  # at the samples that count only
                zz = z * (ey[rows] * ex[cols])
            ref = np.angle(np.sum(zz * np.abs(zz) if every else zz * np.abs(zz) * seen))
            psi = np.angle(zz * np.exp(-1j * ref))
            try:
                coef = np.linalg.solve(N, Aw.T @ psi)
            except np.linalg.LinAlgError:
                return math.nan, (math.nan, math.nan), np.full((3, 3), math.nan), math.nan
            used_x, used_y = gx, gy
            gx, gy = gx + coef[1] / (2 * np.pi), gy + coef[2] / (2 * np.pi)
        phase = ref + coef[0] + 2 * np.pi * (used_x * self.xc + used_y * self.yc)
        if not covariance:
            return phase, (gx, gy), np.full((3, 3), math.nan), math.nan
        if noise is not None:
            inv = np.linalg.inv(N)
            return phase, (gx, gy), (inv @ (A.T @ (A * (wgt**2 * noise)[:, None])) @ inv)[:3, :3], math.nan
        res = psi - A @ coef
        s2 = float(np.sum(wgt * res**2) / max(int(seen.sum()) - A.shape[1], 1))
        inv = np.linalg.inv(N)
        infl = 1.0 if extra is None else float(inv[0, 0] / np.linalg.inv(N[:3, :3])[0, 0])
        return phase, (gx, gy), inv[:3, :3] * s2, infl
