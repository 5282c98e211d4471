"""Control charts of a stage's history: Shewhart individuals and EWMA.

* Individuals (X) chart (ISO 7870-2:2023, Sec. 8; Montgomery, *Introduction to Statistical
  Quality Control*, 7th ed., Sec. 6.4): centre line the mean of the points, limits
  mean ± 3·MR̄/d₂ with MR̄ the mean moving range of consecutive points and d₂ = 1.128
  (the bias constant of the range of two), i.e. ± 2.66·MR̄.
* EWMA chart (ISO 7870-6:2016; Montgomery Sec. 9.2): z_i = λ x_i + (1 − λ) z_{i−1},
  z_0 the centre line, limits centre ± L σ √(λ/(2−λ)·(1 − (1−λ)^{2i})), with σ = MR̄/d₂.
  λ = 0.2 and L = 2.7 are the literature's usual choice for slow drift (Lucas & Saccucci
  1990, Table 3: in-control ARL ≈ 370 with these values ≈ the 3σ Shewhart chart).

Units are those of the points (µm, degrees).
"""

from __future__ import annotations

import numpy as np

D2 = 1.128  # E[range of two normal values] / σ


def _phase_one(x: np.ndarray, baseline: int | None) -> tuple[float, float]:
    """Centre and σ (moving range / d₂) from the first ``baseline`` points (all when None)."""
    ref = x if baseline is None else x[: max(2, baseline)]
    return float(np.mean(ref)), float(np.mean(np.abs(np.diff(ref)))) / D2


def individuals(x, baseline: int | None = None) -> dict:
    """Centre line, limits and out-of-limit points of an individuals chart of ``x``, its
    centre and σ from the first ``baseline`` points (all by default: limits from the
    data); the limits need at least two points (``lcl``/``ucl`` None otherwise)."""
    x = np.asarray(x, float)
    centre = float(np.mean(x)) if x.size else None
    if x.size < 2:
        return {"centre": centre, "lcl": None, "ucl": None, "sigma": None, "out": []}
    centre, sigma = _phase_one(x, baseline)
    lcl, ucl = centre - 3 * sigma, centre + 3 * sigma
    out = [int(i) for i in np.flatnonzero((x < lcl) | (x > ucl))]
    return {"centre": centre, "lcl": lcl, "ucl": ucl, "sigma": sigma, "out": out}


def ewma(x, lam: float = 0.2, width: float = 2.7, baseline: int | None = None) -> dict:
    """The EWMA statistic of ``x`` with its time-varying limits (lists) and the points
    beyond them; centre and σ as for :func:`individuals`."""
    x = np.asarray(x, float)
    if x.size < 2:
        return {
            "lambda": lam,
            "L": width,
            "z": x.tolist(),
            "lcl": [None] * x.size,
            "ucl": [None] * x.size,
            "out": [],
        }
    centre, sigma = _phase_one(x, baseline)
    z = np.empty_like(x)
    prev = centre
    for i, v in enumerate(x):
        prev = lam * v + (1 - lam) * prev
        z[i] = prev
    i = np.arange(1, x.size + 1)
    half = width * sigma * np.sqrt(lam / (2 - lam) * (1 - (1 - lam) ** (2 * i)))
    lcl, ucl = centre - half, centre + half
    out = [int(k) for k in np.flatnonzero((z < lcl) | (z > ucl))]
    return {
        "lambda": lam,
        "L": width,
        "centre": centre,
        "z": z.tolist(),
        "lcl": lcl.tolist(),
        "ucl": ucl.tolist(),
        "out": out,
    }
