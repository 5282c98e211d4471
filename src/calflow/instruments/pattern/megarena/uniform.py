"""The phase planes in the Vernier library's convention: equal weight per pixel of the fit region.

calflow's own planes weight each coarse phase sample by the lobe's power |z|² (the
least-variance plane, :meth:`PhaseFitter.refit <calflow.instruments.pattern.phase.PhaseFitter.refit>`).
The library's estimand is the equal-weight least-squares plane of the lattice's coordinates over
the frame's central half (docs/instruments.md): here each sample is weighted by its cell's share
of the region (:meth:`~calflow.instruments.pattern.phase.PhaseFitter.region_share`), the lobe's
power used only to leave out the samples with no lobe (amplitude below :data:`NO_LOBE` of the
region's median: under dust, off the pattern).

The code's envelope. The band-passed phase carries Δψ = c·∇ln|z| (the phase module's docstring),
c one coefficient per lobe and frame, fitted from the samples. Fitted beside a plane alone, c also
takes up whatever of the lattice's curvature looks like ∇ln|z| — on a frame the optics distort,
the regressors' smooth part (the light's fall-off, the code's density across the region) against
the curved phase — and the plane moves with it: tens of µrad on a strongly distorted frame. Here
c is fitted beside a polynomial surface of degree :data:`ENVELOPE_DEGREE` instead: a radial lens
distortion q = p·(1 + k|p|²) makes the lattice's phase, affine in q, a cubic in the pixel p, which
the surface takes up whole. The envelope ĉ·∇ln|z| is then taken out of the phase and the plane is
the equal-weight least-squares plane of what is left (both fits linear in the samples' phases ψ):

    ĉ = S·ψ   (S: the regressors' rows of the weighted fit on [surface, ∇ln|z|])
    β = P·(ψ − G·ĉ) = M·ψ,   M = P − (P·G)·S   (P: the weighted plane fit, G: the regressors)

Its covariance is the sandwich M·diag(1/|z|²)·Mᵀ (the phase's noise is σ²/2|z|²), scaled by the
same noise as the power-weighted plane.
"""

from __future__ import annotations

import math

import numpy as np

PLANE_WEIGHTS = ("power", "uniform")  # the phase planes' weights (Megarena's ``plane_weights``)
NO_LOBE = 0.1  # a sample whose lobe amplitude is below this of the region's median has no lobe
ENVELOPE_DEGREE = 3  # the surface the envelope's coefficient is fitted beside (a radial lens: cubic)


def uniform_planes(fitter, planes, k: int, keep: np.ndarray):
    """Frame k's two planes with every pixel of the region alike, from the coarse samples'
    shares ``keep`` (:meth:`region_share`). Returns (phase at the frame centre (2,) rad,
    frequency (2, 2) cycles per pixel, covariance (2, 3, 3)) as ``PhaseFitter.refit`` does."""
    phase = np.empty(2)
    freq = np.empty((2, 2))
    cov = np.empty((2, 3, 3))
    envelope = fitter.envelope and planes.gradients is not None
    for lobe in (0, 1):
        z = planes.fields[k, lobe].astype(np.complex128)
        wgt = np.abs(z) ** 2
        region = keep * fitter.flat if envelope else keep
        seen = wgt[region > 0]
        floor = NO_LOBE**2 * float(np.median(seen)) if seen.size else math.inf
        kept = (region * (wgt > floor)).astype(float)
        noise = np.divide(1.0, wgt, out=np.zeros_like(wgt), where=wgt > 0)
        extra = planes.gradients[k, lobe] if envelope else None
        bin_ = planes.bins[k, lobe]
        # with the envelope this first fit only unwraps the samples: its covariance is not kept
        p, f, c, _ = fitter._fit(
            z, kept, bin_, planes.freq[k, lobe], extra, covariance=extra is None, noise=noise
        )
        if extra is not None and math.isfinite(p):
            p, f, c = _envelope_out(fitter, z, kept, bin_, p, f, extra, noise)
        phase[lobe], freq[lobe] = p, f
        # the noise constant: the power-weighted plane over every sample has var_all
        n_all = np.linalg.inv(fitter.A.T @ (fitter.A * wgt[:, None]))[0, 0]
        cov[lobe] = c * (planes.var_all[k, lobe] / max(n_all, 1e-300))
    return phase, freq, cov


def _envelope_out(fitter, z, kept, bin_, phase, freq, extra, noise):
    """The plane of the samples' phase less the envelope ĉ·∇ln|z|, ĉ fitted beside the surface
    (module docstring), from the plane first fitted (``phase``, ``freq``), which unwraps them."""
    used = np.flatnonzero(kept)
    A = fitter.A[used]  # (1, x − x_c, y − y_c)
    x, y = fitter.xm.ravel()[used], fitter.ym.ravel()[used]
    carrier = 2 * np.pi * (bin_[1] / fitter.w * x + bin_[0] / fitter.h * y)  # the lobe's bin
    first = phase + 2 * np.pi * (freq[0] * A[:, 1] + freq[1] * A[:, 2])
    psi = np.angle(z[used] * np.exp(1j * (carrier - first)))  # about the first plane: small
    w = kept[used]
    s = max(fitter.frame_shape) / 2.0
    u, v = A[:, 1] / s, A[:, 2] / s
    G = extra[:, used].T
    D = np.column_stack(
        [u**a * v ** (n - a) for n in range(ENVELOPE_DEGREE + 1) for a in range(n, -1, -1)] + [G]
    )
    Dw = D * w[:, None]
    S = np.linalg.solve(D.T @ Dw, Dw.T)[-G.shape[1] :]  # ĉ = S·ψ
    Aw = A * w[:, None]
    P = np.linalg.solve(A.T @ Aw, Aw.T)  # the weighted plane
    M = P - (P @ G) @ S
    beta = M @ psi
    out_freq = (freq[0] + beta[1] / (2 * np.pi), freq[1] + beta[2] / (2 * np.pi))
    return phase + beta[0], out_freq, (M * noise[used]) @ M.T
