"""One pixel size for a sequence of HP-code frames: the frames' own estimates pooled, with
an uncertainty from their scatter, and a test that the magnification did not drift.

A frame's own pixel size (each marker's, from its grid's lattice: :mod:`.pose`) scatters
from frame to frame more than its fit says — on the Vernier library's Image140 sequence by
σ ≈ 0.6·10⁻⁴ (relative), five times the fit's stated uncertainty, the fixed and the moving
marker's estimates uncorrelated — and a relative pose multiplies the scale by the markers'
separation (716 µm there: 0.07 µm). When the optics are the same for the whole sequence,
the mean of the frames' estimates is the better scale.

:func:`pool_pixel` pools it:

1. per frame, the mean of the pixel sizes of the markers measured (``numbers``: the marker
   and its reference in a replay; every marker decoded when None) that are "ok" — they see
   the same optics and their errors are uncorrelated;
2. frames farther than :data:`REJECT` robust standard deviations (1.4826 · MAD) from the
   median are left out (a marker misfitted in one frame must not move the sequence's scale),
   then, until no frame changes side, those within :data:`REJECT` standard deviations of
   the kept frames' mean are taken back (a MAD from a few tens of frames can fall well short
   of their scatter);
3. the pooled pixel size is the mean of the frames kept, its standard uncertainty their
   standard deviation over √n_eff, with n_eff = n (1 − r₁)/(1 + r₁) when the frames'
   lag-one autocorrelation r₁ is positive (a slow wander is not n independent draws);
4. a straight line of the kept frames' pixel sizes against the frames' times (or their
   order) tests for a drifting magnification: a slope whose two-sided p-value is below
   :data:`DRIFT_P` is a drift, stated in plain words (:attr:`SequenceScale.statement`) —
   the sequence is still pooled, but the record says the pool's scale is not each frame's.
   Each marker's own pixel size is tested the same way: a change of magnification changes
   every marker's alike, so when one marker's trends and another's does not, the record says
   it is not the magnification but what differs between them (their places in the field of
   view, a tilt, the fit) — on Image140 the moving marker's pixel size follows its travel
   (2.6·10⁻⁴ over 13 pixels) while the fixed marker's does not move.

The mean of the kept frames, not their median: with the outliers gone the scatter is
Gaussian-like and the mean's variance is 0.64 of the median's. The uncertainty comes from
the scatter, never from the fits' stated uncertainties (shown too small); those are kept
beside it (``u_fit_um``) for comparison.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from calflow.instruments.pattern.hpcode.decode import Markers

REJECT = 5.0  # robust standard deviations from the median beyond which a frame is left out
DRIFT_P = 0.01  # two-sided p-value of the pixel size's slope against time below which it drifts
MIN_FRAMES = 5  # frames with a pixel size needed to pool and to test a trend
RECORD_KEYS = (  # what a run dataset keeps of a pool (SequenceScale.attrs), in its attributes
    "pixel_size",
    "pixel_size_um",
    "u_pixel_size_um",
    "pixel_size_frames",
    "pixel_size_drift_um",
    "pixel_size_drift_p",
    "pixel_size_drifts",
    "pixel_size_trend_markers",
    "pixel_size_statement",
)


@dataclass(frozen=True)
class SequenceScale:
    """A sequence's pooled pixel size (µm) and what supports it."""

    pixel_um: float  # the pooled pixel size
    u_pixel_um: float  # its standard uncertainty, from the frames' scatter
    scatter_um: float  # one frame's standard deviation about the pool
    u_fit_um: float  # the median of the frames' own fits' stated uncertainty (for comparison)
    n_frames: int  # frames pooled
    rejected: tuple[int, ...]  # frames left out as outliers (their indices)
    n_eff: float  # the frames' effective number (autocorrelation)
    drift_um: float  # the trend line's change over the sequence
    u_drift_um: float  # its standard uncertainty
    drift_p: float  # two-sided p-value of the slope
    numbers: tuple[int, ...]  # the markers pooled (empty: every marker decoded)
    # each marker's own trend: (number, change over the sequence µm, its uncertainty, p-value)
    marker_trends: tuple[tuple[int, float, float, float], ...] = ()

    @property
    def trending(self) -> tuple[int, ...]:
        """The markers whose own pixel size has a trend against time beyond its scatter."""
        return tuple(k for k, _, _, p in self.marker_trends if p < DRIFT_P)

    @property
    def drifts(self) -> bool:
        """A trend of the frames' pixel sizes against time beyond their scatter: the pool's or
        one marker's."""
        return self.drift_p < DRIFT_P or bool(self.trending)

    @property
    def magnification_drifts(self) -> bool:
        """The pool's trend, and no marker steady while another trends: what a change of the
        optics' magnification does (it changes every marker's pixel size alike)."""
        steady = [k for k, *_ in self.marker_trends if k not in self.trending]
        return self.drift_p < DRIFT_P and not (self.trending and steady)

    @property
    def statement(self) -> str:
        """The pool and its trend test, in plain words."""
        rel = 1e6 * self.u_pixel_um / self.pixel_um
        which = "every marker decoded" if not self.numbers else "markers " + ", ".join(map(str, self.numbers))
        pooled = (
            f"pixel size {self.pixel_um:.7f} ± {self.u_pixel_um:.7f} µm ({rel:.1f} ppm) pooled over "
            f"{self.n_frames} frames ({which}; {len(self.rejected)} frame(s) left out as outliers); "
            f"a frame's own scatters by {self.scatter_um:.2g} µm, its fit states {self.u_fit_um:.2g} µm"
        )
        if self.magnification_drifts:
            return (
                f"{pooled}. The magnification drifts: the frames' pixel size changes by "
                f"{self.drift_um:+.2g} ± {self.u_drift_um:.2g} µm over the sequence (p = {self.drift_p:.1g}), "
                "beyond their scatter; the pooled scale is not each frame's — use each frame's own pixel "
                "size, or steady the optics"
            )
        if self.drifts:  # one marker's pixel size trends and another's does not, or the other way
            words = [
                f"marker {k}'s by {d:+.2g} ± {u:.2g} µm (p = {p:.1g})"
                for k, d, u, p in self.marker_trends
                if k in self.trending
            ]
            words += [
                f"marker {k}'s not (p = {p:.2g})"
                for k, _, _, p in self.marker_trends
                if k not in self.trending
            ]
            return (
                f"{pooled}. The pixel size changes over the sequence: {'; '.join(words)}. Not a change of "
                "the magnification, which would change every marker's alike, but of what differs between "
                "the markers — their places in the field of view (distortion), a tilt, or the fit: calflow "
                "cannot tell which, and the pooled scale averages it"
            )
        return (
            f"{pooled}; no drift of the magnification found (change over the sequence "
            f"{self.drift_um:+.2g} ± {self.u_drift_um:.2g} µm, p = {self.drift_p:.2g})"
        )

    def attrs(self) -> dict:
        """The record a run dataset keeps (strings and numbers), under :data:`RECORD_KEYS`."""
        values = (
            "sequence",
            self.pixel_um,
            self.u_pixel_um,
            self.n_frames,
            self.drift_um,
            self.drift_p,
            "yes" if self.drifts else "no",
            ",".join(map(str, self.trending)),
            self.statement,
        )
        return dict(zip(RECORD_KEYS, values, strict=True))


def pool_pixel(found: Markers, numbers=None, time_s=None) -> SequenceScale:
    """The pixel size pooled over the frames of ``found`` (module docstring, steps 1–4) from the
    markers numbered ``numbers`` (None: every marker decoded); ``time_s`` the frames' times
    (s; None: their order). Raises ValueError when fewer than :data:`MIN_FRAMES` frames
    hold a pixel size."""
    numbers = tuple(int(k) for k in numbers if k is not None) if numbers is not None else ()
    ok = found.status == "ok"
    if numbers:
        ok &= np.isin(found.number, numbers)
    t_all = np.arange(found.n_frames, dtype=float) if time_s is None else np.asarray(time_s, float)
    frames = np.unique(found.frame[ok])
    value = np.array([found.pixel_um[ok & (found.frame == f)].mean() for f in frames])
    u_fit = np.array([found.u_pixel_um[ok & (found.frame == f)].mean() for f in frames])
    if len(frames) < MIN_FRAMES:
        raise ValueError(
            f"pixel_size: expected at least {MIN_FRAMES} frames with a decoded marker to pool the "
            f"pixel size over the sequence, got {len(frames)}"
        )
    med = float(np.median(value))
    mad = 1.4826 * float(np.median(np.abs(value - med)))
    keep = np.abs(value - med) <= REJECT * mad if mad > 0 else value == med
    for _ in range(len(value)):  # a MAD from few frames can fall short: the kept frames say again
        if keep.sum() <= 2:
            break
        kept = value[keep]
        again = np.abs(value - kept.mean()) <= REJECT * max(kept.std(ddof=1), mad)
        if (again == keep).all():
            break
        keep = again
    v, t = value[keep], t_all[frames[keep]]
    n = len(v)
    mean = float(v.mean())
    sd = float(v.std(ddof=1)) if n > 1 else 0.0
    r = v - mean
    r1 = float(r[:-1] @ r[1:] / (r @ r)) if n > 2 and r @ r > 0 else 0.0
    n_eff = n * (1 - r1) / (1 + r1) if r1 > 0 else float(n)
    n_eff = max(n_eff, 2.0)
    drift, u_drift, p = _trend(t, v)
    trends = []
    for number in numbers or sorted(set(found.number[ok].tolist()) - {-1}):
        mine = ok & (found.number == number) & np.isin(found.frame, frames[keep])
        if mine.sum() >= MIN_FRAMES:
            trends.append((int(number), *_trend(t_all[found.frame[mine]], found.pixel_um[mine])))
    return SequenceScale(
        pixel_um=mean,
        u_pixel_um=sd / math.sqrt(n_eff),
        scatter_um=sd,
        u_fit_um=float(np.median(u_fit)),
        n_frames=n,
        rejected=tuple(int(f) for f in frames[~keep]),
        n_eff=float(n_eff),
        drift_um=float(drift),
        u_drift_um=float(u_drift),
        drift_p=p,
        numbers=numbers,
        marker_trends=tuple(trends),
    )


def _trend(t: np.ndarray, v: np.ndarray) -> tuple[float, float, float]:
    """A straight line of ``v`` against ``t``: its change over the span of ``t``, that change's
    standard uncertainty and the slope's two-sided p-value (no line: 0, 0, 1)."""
    from scipy import stats

    if len(v) < 3 or np.ptp(t) == 0 or np.ptp(v) == 0:
        return 0.0, 0.0, 1.0
    fit = stats.linregress(t, v)
    span = float(np.ptp(t))
    return float(fit.slope * span), float(fit.stderr * span), float(fit.pvalue)


def at_scale(found: Markers, pixel_um: float, u_pixel_um: float = 0.0) -> Markers:
    """The markers of ``found`` at one pixel size (µm) for every frame: each marker's lengths in
    µm (its pose, the centre's uncertainty, its pixel sizes) scaled by pixel_um / its own, the
    directions kept; ``u_pixel_um`` (the scale's uncertainty, common to the frames) added to
    the pose's, |x| · u_pixel_um / pixel_um."""
    c = {k: np.array(v, float) for k, v in found.columns.items()}
    f = pixel_um / c["pixel_um"]
    rel = u_pixel_um / pixel_um
    for k in ("x_um", "y_um", "pixel_x_um", "pixel_y_um", "u_centre_x_um", "u_centre_y_um"):
        c[k] = c[k] * f
    c["u_x_um"] = np.hypot(c["u_x_um"] * f, c["x_um"] * rel)
    c["u_y_um"] = np.hypot(c["u_y_um"] * f, c["y_um"] * rel)
    ok = np.isfinite(c["pixel_um"])
    c["pixel_um"] = np.where(ok, pixel_um, np.nan)
    c["u_pixel_um"] = np.where(ok, u_pixel_um, np.nan)
    return Markers(found.frame, found.number, c, found.status, found.reason, found.n_frames, found.shape)
