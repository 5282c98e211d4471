"""Outlier handling of a least-squares identification: the robust noise scale, the robust
losses scipy offers, and the k-σ rejection of whole readings.

A gross error (a misread pattern period of the vision sensor, thesis Sec. 3.3) is one
reading off by many σ. A robust loss (:func:`scipy.optimize.least_squares`, ``loss``
soft_l1, huber or cauchy, ``f_scale`` a few σ) keeps it from pulling the fit; the
readings whose residual still exceeds ``reject_sigma`` σ are then rejected and the
parameters refitted by least squares on the rest, so the estimate and its σ are those of
the clean data.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import median_abs_deviation

#: Losses of :func:`scipy.optimize.least_squares` usable for the screening fit.
LOSSES = ("linear", "soft_l1", "huber", "cauchy")


@dataclass(frozen=True)
class Robust:
    """How an identification treats outliers.

    ``loss``: the screening fit's loss (``linear`` screens with plain least squares, i.e.
    iterative k-σ rejection alone); ``f_scale_sigma``: the loss's soft threshold in units
    of the robust noise scale; ``reject_sigma``: a reading whose residual on either axis
    exceeds this many robust σ is rejected; ``max_rounds``: rejection rounds at most.
    """

    loss: str = "soft_l1"
    f_scale_sigma: float = 2.0
    reject_sigma: float = 5.0
    max_rounds: int = 5

    def __post_init__(self) -> None:
        if self.loss not in LOSSES:
            raise ValueError(f"robust loss {self.loss!r}: expected one of {LOSSES}")
        if not (self.f_scale_sigma > 0 and self.reject_sigma > 0 and self.max_rounds >= 1):
            raise ValueError("robust: f_scale_sigma and reject_sigma must be > 0 and max_rounds >= 1")

    @classmethod
    def from_config(cls, spec: dict | None) -> Robust | None:
        """From a campaign's ``identification.robust``; None when its loss is ``none``."""
        spec = dict(spec or {})
        if spec.get("loss", cls.loss) == "none":
            return None
        return cls(**spec)


def mad_sigma(residuals: np.ndarray) -> float:
    """Robust σ (same unit as ``residuals``): the median absolute deviation from the median
    scaled by 1 / Φ⁻¹(3/4) ≈ 1.4826 (:func:`scipy.stats.median_abs_deviation`,
    ``scale="normal"``), consistent for normal noise and unmoved by a few gross errors.
    Non-finite residuals are left out; NaN when none is left."""
    r = np.asarray(residuals, dtype=float).ravel()
    r = r[np.isfinite(r)]
    if r.size == 0:
        return float("nan")
    return float(median_abs_deviation(r, scale="normal"))


def outliers(residuals: np.ndarray, sigma: float, k: float) -> np.ndarray:
    """Boolean mask of the rows of ``residuals`` (readings × axes) with an axis beyond
    ``k`` σ of the axis's median."""
    r = np.asarray(residuals, dtype=float)
    r = r.reshape(r.shape[0], -1)
    if not np.isfinite(sigma) or sigma <= 0:
        return np.zeros(r.shape[0], dtype=bool)
    return np.any(np.abs(r - np.median(r, axis=0)) > k * sigma, axis=1)
