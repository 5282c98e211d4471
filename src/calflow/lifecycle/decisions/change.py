"""Did the stage change between two calibrations? A joint test per model on the parameter vector.

For one model, two calibrations give parameter vectors θ₁, θ₂ (free parameters) with
covariances Σ₁, Σ₂. With d = θ₂ − θ₁ the Wald statistic

    W = dᵀ (Σ₁ + Σ₂)⁻¹ d / k²

is χ² with p = dim θ degrees of freedom when the stage did not change and the σ are
honest (Wald 1943; ISO/IEC Guide 98-3 for the covariance of two independent results).
Within-campaign σ are not the whole story: plans, seeds and unmodelled errors make two
calibrations of an unchanged stage differ more (or less) than their σ say. Once the stage
has ``min_pairs`` earlier pairs judged unchanged, their pooled Birge ratio (W/p, Birge 1932)
estimates that between-campaign factor k², and the scaled statistic is referred to
p·F(p, Σp) — the F distribution accounts for k² being estimated from the earlier pairs' Σp
degrees of freedom (the same argument as a pooled reproducibility standard deviation, ISO
5725-2). The pairs kept are those below the χ² quantile, so their mean W is that of a
truncated χ²: E[χ²_p | χ²_p ≤ q] = p·F_{p+2}(q)/F_p(q) (the χ² density's recurrence), by which
the pooled ratio is divided — else k² would be biased low and the test would flag too often.
k² is not floored at 1: σ that overstate the spread would make the test blind, a floor only
trades α for that. The pair just before the one tested is left out of k²: it shares a
calibration with it, so their statistics are positively correlated and a large W would
bring its own large k² (the test was conservative, 2.4 % at α 5 %). Until then the test uses
within-campaign σ and says so.

The models of a campaign are tested together: their p-values are corrected with Holm's
step-down method (Holm 1979) so that the chance of flagging any model of an unchanged
stage is at most α.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats


@dataclass(frozen=True)
class Estimate:
    """One model of one calibration: free-parameter names, values and covariance (their units)."""

    names: tuple[str, ...]
    value: np.ndarray
    covariance: np.ndarray


def wald(a: Estimate, b: Estimate) -> tuple[float, int]:
    """(W, p): the Wald statistic of b − a over the parameters both estimated with a
    positive variance, and their number. A pseudo-inverse keeps a singular sum usable
    (its rank is then the dof)."""
    common = [n for n in a.names if n in b.names]
    ia = [a.names.index(n) for n in common]
    ib = [b.names.index(n) for n in common]
    d = np.asarray(b.value, float)[ib] - np.asarray(a.value, float)[ia]
    cov = np.asarray(a.covariance, float)[np.ix_(ia, ia)] + np.asarray(b.covariance, float)[np.ix_(ib, ib)]
    keep = np.isfinite(d) & np.isfinite(np.diag(cov)) & (np.diag(cov) > 0)
    d, cov = d[keep], cov[np.ix_(keep, keep)]
    if d.size == 0:
        return float("nan"), 0
    scale = np.sqrt(np.diag(cov))  # equilibrate: parameters in µm and degrees differ by 10⁶
    corr = cov / np.outer(scale, scale)
    z = d / scale
    pinv = np.linalg.pinv(corr, rcond=1e-12, hermitian=True)
    rank = int(np.linalg.matrix_rank(corr, tol=1e-12 * max(1.0, float(np.max(np.abs(corr))))))
    return float(z @ pinv @ z), rank


def inflation(prior: list[tuple[float, int]], min_pairs: int = 3, alpha: float = 0.05) -> tuple[float, int]:
    """(k², m): the between-campaign factor of the σ² from the Wald statistics of the
    earlier pairs judged unchanged, and the degrees of freedom it rests on (Σp over those
    pairs); (1, 0) below ``min_pairs`` pairs.

    k² = Σ W / Σ p·F_{p+2}(q_p)/F_p(q_p) over those pairs, q_p the χ²_p quantile 1 − α: the
    pooled Birge ratio, corrected for the pairs being those below q_p. A pair is judged
    unchanged when its W/k² ≤ q_p: the pairs and k² are found together, starting from every
    earlier pair and dropping the changed ones until nothing moves (a pair flagged before the
    stage's reproducibility was known may be re-admitted, a re-mount is left out).
    """
    usable = [(w, p) for w, p in prior if p > 0 and np.isfinite(w)]
    dofs = sorted({p for _, p in usable})  # q_p and the kept pairs' mean, once per distinct p
    q = dict(zip(dofs, stats.chi2.ppf(1 - alpha, dofs), strict=True))
    ratio = {p: float(stats.chi2.cdf(q[p], p + 2) / stats.chi2.cdf(q[p], p)) for p in dofs}
    keep = usable
    k2 = 1.0
    for _ in range(20):
        if len(keep) < min_pairs:
            return 1.0, 0
        k2 = sum(w for w, _ in keep) / sum(p * ratio[p] for _, p in keep)
        now = [(w, p) for w, p in usable if w / k2 <= q[p]]
        if now == keep:
            break
        keep = now
    if len(keep) < min_pairs:
        return 1.0, 0
    return k2, sum(p for _, p in keep)


def p_value(w: float, dof: int, k2: float, k2_dof: int) -> tuple[float, str]:
    """The p-value of W (already divided by k²) and its reference distribution: χ²(p) with
    the within-campaign σ (``k2_dof`` 0), p·F(p, ``k2_dof``) with the estimated k²."""
    if dof == 0 or not np.isfinite(w):
        return float("nan"), "none"
    if k2_dof == 0:
        return float(stats.chi2.sf(w, dof)), f"chi2({dof})"
    return float(stats.f.sf(w / dof, dof, k2_dof)), f"{dof}·F({dof}, {k2_dof})"


def holm(p_values: dict[str, float], alpha: float) -> dict[str, bool]:
    """Which hypotheses Holm's step-down procedure rejects at family-wise level ``alpha``
    (NaN p-values are not tested): sorted p₍₁₎ ≤ … ≤ p₍ₘ₎, reject while p₍ᵢ₎ ≤ α/(m − i + 1).

    Written out (a few lines) rather than ``statsmodels.stats.multitest.multipletests``,
    which gives the same decisions (a test checks it) but costs ~0.3 s a call here, and the
    benchmark makes tens of thousands.
    """
    tested = sorted((v, k) for k, v in p_values.items() if np.isfinite(v))
    out = {k: False for k in p_values}
    m = len(tested)
    for i, (v, k) in enumerate(tested):
        if v > alpha / (m - i):
            break
        out[k] = True
    return out


def changes(series: list[dict[str, Estimate]], alpha: float = 0.05, min_pairs: int = 3) -> list[dict]:
    """The change test between consecutive calibrations of ``series`` (per calibration, model
    name → :class:`Estimate`). Returns per pair ``{models: {M: {statistic, dof, p_value,
    significant, reference, inflation, inflation_dof}}}``; the inflation of a model rests on
    its earlier pairs judged unchanged that share no calibration with the pair tested
    (:func:`inflation`)."""
    out = []
    history: dict[str, list[tuple[float, int]]] = {}
    for a, b in zip(series, series[1:]):
        raw, res = {}, {}
        for m in [m for m in a if m in b]:
            w, dof = wald(a[m], b[m])
            # the earlier pairs that share no calibration with this one
            k2, k2_dof = inflation(history.get(m, [])[:-1], min_pairs, alpha)
            pv, ref = p_value(w / k2, dof, k2, k2_dof)
            raw[m] = (w, dof)
            res[m] = {
                "statistic": w / k2,
                "dof": dof,
                "p_value": pv,
                "reference": ref,
                "inflation": k2,
                "inflation_dof": k2_dof,
            }
        flags = holm({m: r["p_value"] for m, r in res.items()}, alpha)
        for m, r in res.items():
            r["significant"] = flags[m]
            history.setdefault(m, []).append(raw[m])
        out.append({"models": res})
    return out
