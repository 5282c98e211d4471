"""The Monte Carlo side of the uncertainty of a headline figure (JCGM 101:2008): the interval of a
maximum over targets (:func:`maximum_interval`) and a result from the trials (:func:`mc_result`).
The draws are :mod:`.draws`', streamed by :mod:`.stream` until :mod:`.adaptive` says they are
enough. The package's docstring describes the method (:mod:`calflow.metrics.uncertainty`)."""

from __future__ import annotations

import math

import numpy as np

from calflow.metrics.uncertainty.budget import P95, Uncertainty, coverage_factor, welch_satterthwaite
from calflow.metrics.uncertainty.tails import Column


def chi_rp_factor(d: int) -> float:
    """E[χ_d] + 3 SD[χ_d]: RP∞ / σ of an isotropic normal scatter in d axes (Eq. 3.5–3.8, n → ∞)."""
    from scipy import special

    mean = math.sqrt(2.0) * math.exp(special.gammaln((d + 1) / 2) - special.gammaln(d / 2))
    return mean + 3.0 * math.sqrt(max(d - mean * mean, 0.0))


def effective_count(draws) -> float:
    """1/Σ p_j²: how many cells are the maximum in the draws (p_j: share of the draws (M, T)
    where j is). It follows the estimates (the one that came out largest wins most draws), so
    it counts the cells of a range's pairs, not those that may tie (:func:`candidates`)."""
    d = np.asarray(draws, float)
    p = np.bincount(np.argmax(d, axis=1), minlength=d.shape[1]) / len(d)
    return float(1.0 / np.sum(p**2))


#: The draws the candidates are counted from (the first ones): the count screens cells, the
#: bounds use every draw; a sweep's thousands of cells cost a tenth of the time.
COUNT_TRIALS = 5000


def _sorted_quantile(x: np.ndarray, q: float) -> float:
    """The q-quantile of sorted ``x`` by linear interpolation between order statistics (numpy's
    default method, the same numbers to rounding), without a partition per call."""
    pos = q * (x.size - 1)
    i = min(max(int(math.floor(pos)), 0), x.size - 1)
    k = min(i + 1, x.size - 1)
    t = pos - i
    return float(x[i] + (x[k] - x[i]) * t) if t < 0.5 else float(x[k] - (x[k] - x[i]) * (1.0 - t))


def candidates(estimates, column, upper, trials: int, level: float = P95) -> int:
    """How many cells can be the maximum: subset selection (S. S. Gupta, Technometrics 7
    (1965) 225), the cells whose difference to the cell of the largest estimate (the top) is
    not significantly negative; the bounds are JCGM 101's, from the Monte Carlo's trials.

    Cell j stays while the upper bound of θ_j − θ_top reaches 0: the bias-corrected
    percentile bound of the paired differences x_j − x_top of the same trials, one-sided at
    1 − (1 − level)/2 (the lower bound's side, :func:`lower_risk`), Šidák-adjusted over the
    m − 1 comparisons of the m cells kept. A cell that truly ties with the maximum is then
    dropped with at most that risk, and C is found by shrinking from every cell until it
    holds (fewer comparisons narrow the bounds, so C only shrinks). Differences of the same
    trials cancel what the cells share (a common term, the scatter's scale, a per-trial
    addition): they do not make cells look tied. Comparing the cells' own intervals instead
    (do they overlap?) tests the difference at a far stricter level than its own (by up to
    √2 in the half-width: Schenker and Gentleman, Am. Stat. 55 (2001) 182) and counts as
    candidates cells that are clearly below the top, which widens the interval where the
    targets' values are spread (the coverage benchmark, docs/benchmarks.md).

    ``column(j)``: cell j's draws (M,), each asked once; ``upper`` (T,): a number no smaller
    than any of them. A difference is at most cell j's largest draw minus the top's smallest:
    cells whose ``upper`` lies below the top's smallest draw are not candidates and their
    draws are not read. The callers count from the first :data:`COUNT_TRIALS` draws
    (:func:`candidate_count`).
    """
    from scipy.special import ndtr, ndtri

    y = np.atleast_1d(np.asarray(estimates, float))
    if y.size == 1:
        return 1
    upper = np.asarray(upper, float)
    top = int(np.argmax(y))
    x_top = np.asarray(column(top), float)
    floor = float(x_top.min())
    diffs: dict[int, tuple[float, np.ndarray, int]] = {}  # j → (z0, differences, how many < 0)
    for j in np.argsort(-y, kind="stable"):
        j = int(j)
        if j == top or upper[j] < floor:
            continue
        x = np.asarray(column(j), float) - x_top
        share = np.count_nonzero(x < y[j] - y[top]) / x.size  # np.mean's number
        z0 = float(ndtri(np.clip(share, 1.0 / trials, 1.0 - 1.0 / trials)))
        diffs[j] = (z0, x, int(np.count_nonzero(x < 0.0)))
    m = y.size
    while m > 1:
        za = float(ndtri(1.0 - (1.0 - (1.0 - level) / 2.0) ** (1.0 / (m - 1))))
        c = 1 + sum(1 for z0, x, neg in diffs.values() if _reaches_zero(x, neg, ndtr(2 * z0 - za)))
        if c >= m:
            return m
        m = c
    return 1


def _reaches_zero(x: np.ndarray, negative: int, q: float) -> bool:
    """``_sorted_quantile(np.sort(x), q) >= 0`` of the unsorted ``x`` with ``negative`` values
    below 0, the same answer without the sort: the quantile lies between two neighbouring
    order statistics (and never outside them), so it is ≥ 0 when the lower one is and < 0
    when the upper one is; only when they straddle 0 is ``x`` sorted."""
    n = x.size
    i = min(max(int(math.floor(q * (n - 1))), 0), n - 1)
    if i >= negative:  # x₍ᵢ₎ ≥ 0
        return True
    if min(i + 1, n - 1) < negative:  # x₍ᵢ₊₁₎ < 0
        return False
    return _sorted_quantile(np.sort(x), q) >= 0.0


def candidate_count(estimates, draws, level: float = P95) -> int:
    """:func:`candidates` of the cells of a whole array of draws (M, T), counted from its first
    :data:`COUNT_TRIALS` draws."""
    y = np.atleast_1d(np.asarray(estimates, float))
    d = np.asarray(draws, float).reshape(len(draws), y.size)[:COUNT_TRIALS]
    return candidates(y, lambda j: np.ascontiguousarray(d[:, j]), d.max(axis=0), len(d), level)


def maximum_interval(
    estimates, draws, level: float = P95, t_eff: float | None = None
) -> tuple[float, float, float]:
    """95 % interval of max_j θ_j from per-cell estimates (T,) and Monte Carlo draws (M, T).

    Each cell's interval is the bias-corrected percentile interval of its draws (z₀ from the
    share of draws below the estimate). The maximum's bounds are the largest of the cells'
    bounds (:func:`largest_bounds`): the upper at the cells' own one-sided level, the lower
    at the Šidák level over the m cells that can be the maximum (:func:`candidate_count`),
    with the one-sided risks split so the interval's is (1 − level) both when one cell is
    the maximum and when m cells tie (:func:`lower_risk`). A maximum of noisy means is
    biased upwards: with ties the interval reaches further below the measured maximum.
    ``t_eff`` overrides the count (a range's pairs share their cells). Returns
    ``(low, high, m)``.
    """
    y = np.atleast_1d(np.asarray(estimates, float))
    d = np.asarray(draws, float).reshape(len(draws), y.size)
    t_eff = candidate_count(y, d, level) if t_eff is None else float(t_eff)
    lo, hi = largest_bounds(y, lambda j: np.ascontiguousarray(d[:, j]), d.max(axis=0), len(d), level, t_eff)
    return lo, hi, t_eff


def lower_risk(level: float, count: float) -> float:
    """The one-sided risk the lower bound of a maximum over ``count`` candidates may take.

    The upper bound, the largest of the cells' upper bounds at 1 − α/2 each (α = 1 − level),
    misses only if every candidate's does: α/2 with one clear maximum, (α/2)^m when m cells
    tie. The lower bound misses if any candidate's does; it gets the rest, α − (α/2)^m,
    shared over the m candidates (Šidák): α/2 for one cell, nearly α at a tie.
    """
    a = 1.0 - level
    return a - (a / 2.0) ** max(float(count), 1.0)


def largest_bounds(estimates, column, upper, trials: int, level: float, t_eff: float) -> tuple[float, float]:
    """The largest of the cells' bias-corrected bounds (:func:`maximum_interval`), cell by cell:
    the lower ones at the Šidák level over ``t_eff`` candidates with the risk
    :func:`lower_risk` leaves them, the upper ones at each cell's own 1 − (1 − level)/2.

    ``column(j)``: cell j's draws (M,), or a :class:`.tails.Column` (a cell's tails, a range's
    pair of cells); ``upper`` (T,): a number no smaller than any of them (their maximum). A
    percentile of a cell's draws is at most their maximum, so a cell whose ``upper`` lies below
    both bounds found so far cannot change them and its percentiles are not computed; nor is
    one that a count of the draws at or below the bound shows cannot exceed it: the result is
    the same as from every cell, at the cost of the few cells near the top (and the draws of a
    range's many pairs of cells need never be in memory at once,
    :func:`calflow.metrics.uncertainty_iso.iso230_2_uncertainty`).
    """
    y = np.atleast_1d(np.asarray(estimates, float))
    upper = np.asarray(upper, float)
    # a percentile may round one ulp above the draws' maximum: a margin far above that
    upper = upper + 1e-12 * np.abs(upper) + 1e-300
    from scipy.special import ndtr, ndtri  # stats.norm's cdf and ppf, without its per-call checks

    za = ndtri(1.0 - (1.0 - lower_risk(level, t_eff)) ** (1.0 / t_eff))  # the lower bound's side
    zb = ndtri((1.0 - level) / 2.0)  # the upper bound's: each cell's own (lower_risk)
    first = int(np.argmax(y))  # usually the maximum's bounds: the rest is pruned against them
    lo = hi = -math.inf
    for j in [first, *(int(i) for i in np.argsort(-upper, kind="stable") if i != first)]:
        if upper[j] < lo and upper[j] < hi:
            break
        x = column(j)
        if isinstance(x, np.ndarray):
            x = Column(x, y[j])
        z0 = ndtri(np.clip(x.share_below(), 1.0 / trials, 1.0 - 1.0 / trials))
        # a percentile is computed only where it can move its bound: not where the count of
        # draws at or below the bound (:meth:`.tails.Column.at_most`) says it cannot exceed
        # it — the same numbers, a count per cell instead of a partial sort
        sides = [
            (side, q)
            for side, q, bound in ((0, ndtr(2 * z0 + za), lo), (1, ndtr(2 * z0 - zb), hi))
            if upper[j] >= bound and not x.at_most(q, bound)
        ]
        for (side, _), v in zip(sides, x.quantile([q for _, q in sides]), strict=True):
            if side == 0:
                lo = max(lo, v)
            else:
                hi = max(hi, v)
    return lo, hi


MAX_METHOD = (
    "Monte Carlo (JCGM 101:2008), M = {M} trials ({how}), per target; the 95 % interval of the maximum "
    "from the targets' bias-corrected percentile intervals, the lower bound Šidák-adjusted over the "
    "{t:.3g} target(s) that can be the maximum"
)


def how_drawn(record: dict, name: str, unit_scale: float = 1.0) -> str:
    """In words, how many trials a Monte Carlo drew and why (``record``: :class:`.stream.Outcome`'s)."""
    if not record.get("adaptive"):
        return "fixed"
    st = record["status"].get(name)
    if st is None:
        return f"adaptive, JCGM 101 §7.9: {record['blocks']} block(s) of {record['block']}"
    verdict = "reached" if st["reached"] else f"NOT reached within the cap of {record['trials']} trials"
    return (
        f"adaptive, JCGM 101 §7.9: blocks of {record['block']} until the ends and U were stable to the "
        f"numerical tolerance of u at {record['digits']} significant digit(s), δ = {st['tolerance']:.2g}: {verdict}"
    )


def mc_record(record: dict, name: str) -> dict:
    """The ``monte_carlo`` entry of an :class:`.budget.Uncertainty`: M and the tolerance reached."""
    out = {"trials": int(record["trials"]), "adaptive": bool(record.get("adaptive"))}
    st = (record.get("status") or {}).get(name)
    if st is not None:
        out.update(
            blocks=int(record["blocks"]),
            tolerance=float(st["tolerance"]),
            spread=float(st["spread"]),
            reached=bool(st["reached"]),
        )
    return out


def budget_dof(parts: dict, dofs: dict) -> tuple[dict, float]:
    """Each term's robust standard deviation (:func:`robust_sd`) and the Welch–Satterthwaite dof."""
    budget = {n: robust_sd(v) for n, v in parts.items()}
    return budget, welch_satterthwaite(list(budget.values()), [dofs.get(n, math.inf) for n in budget])


def standard_u(U: float, parts: dict, dofs: dict) -> float:
    """u = U / k with k = t_0.975 at the budget's dof (:func:`mc_result`'s u for a given U)."""
    return float(U) / coverage_factor(budget_dof(parts, dofs)[1])


def robust_sd(x) -> float:
    """Half the central 68.27 % range of ``x``: the standard deviation of a normal, and finite
    for the heavy tails of a scatter known from few readings (a variance with ν ≤ 4 dof has
    no finite variance of its own)."""
    from scipy.special import ndtr  # stats.norm.cdf's own function, without importing scipy.stats

    lo, hi = np.quantile(np.asarray(x, float), [float(ndtr(-1.0)), float(ndtr(1.0))])
    return float(hi - lo) / 2.0


def mc_result(value, draws, parts, dofs, interval, method, note="", monte_carlo=None) -> Uncertainty:
    """A Monte Carlo result: U the interval's half-width, k = t_0.975(ν_eff) and u = U/k.

    ν_eff is the Welch–Satterthwaite dof of the budget, whose terms are the robust standard
    deviations (:func:`robust_sd`) of the metric with each term alone; u = U/k makes the
    Student's t that the decisions use (:mod:`calflow.certificate.conformity`) reproduce the Monte
    Carlo interval's half-width.
    """
    lo, hi = interval
    U = float(hi - lo) / 2.0
    budget, dof = budget_dof(parts, dofs)
    k = coverage_factor(dof)
    return Uncertainty(
        value=float(value),
        U=U,
        k=k,
        u=U / k,
        dof_eff=dof,
        interval=(float(lo), float(hi)),
        budget=budget,
        method=method,
        note=note,
        samples=draws,
        monte_carlo=monte_carlo,
    )
