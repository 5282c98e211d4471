"""The Monte Carlo side of the uncertainty of a headline figure (JCGM 101:2008): the shared
random draws of the budget's terms (:class:`Draws`), the interval of a maximum over targets
(:func:`maximum_interval`) and a result from the trials (:func:`mc_result`). The package's
docstring describes the method (:mod:`calflow.metrics.uncertainty`)."""

from __future__ import annotations

import math

import numpy as np

from calflow.metrics.uncertainty.budget import P95, Uncertainty, coverage_factor, welch_satterthwaite


def chi_rp_factor(d: int) -> float:
    """E[χ_d] + 3 SD[χ_d]: RP∞ / σ of an isotropic normal scatter in d axes (Eq. 3.5–3.8, n → ∞)."""
    from scipy import special

    mean = math.sqrt(2.0) * math.exp(special.gammaln((d + 1) / 2) - special.gammaln(d / 2))
    return mean + 3.0 * math.sqrt(max(d - mean * mean, 0.0))


def effective_count(draws) -> float:
    """1/Σ p_j²: how many cells can be the maximum (p_j: share of the draws (M, T) where j is)."""
    d = np.asarray(draws, float)
    p = np.bincount(np.argmax(d, axis=1), minlength=d.shape[1]) / len(d)
    return float(1.0 / np.sum(p**2))


#: The draws the candidates are counted from (the first ones): the count screens cells, the
#: bounds use every draw; a sweep's thousands of cells cost a tenth of the time.
COUNT_TRIALS = 5000


def candidate_count(estimates, draws, level: float = P95) -> int:
    """How many cells can be the maximum: the size of the set C of cells whose upper bound
    reaches the largest lower bound, each cell's interval at the Šidák level that makes the
    intervals of the |C| candidates simultaneous (two-sided, 1 − (1 − level)/2 per side to
    the power 1/|C|), found by shrinking C from every cell until it holds (a smaller C raises
    the lower bounds, so C only shrinks). Unlike the draws' shares of being the maximum,
    which follow the estimates (the one that came out largest wins most draws), this counts
    every cell whose truth may tie with the maximum's.

    A percentile of a cell's draws is at most their maximum: cells whose maximum lies below
    the largest lower bound are neither searched for it nor candidates, so only the cells
    near the top have their percentiles computed, one column at a time (a sweep's thousands
    of cells never need a sorted copy of the draws), from the first :data:`COUNT_TRIALS` draws.
    """
    from scipy.special import ndtr, ndtri

    y = np.atleast_1d(np.asarray(estimates, float))
    d = np.asarray(draws, float).reshape(len(draws), y.size)[:COUNT_TRIALS]
    trials = len(d)
    upper = d.max(axis=0)
    order = [int(j) for j in np.argsort(-upper, kind="stable")]
    z0: dict[int, float] = {}

    def bounds(j: int, za: float) -> tuple[float, float]:
        x = d[:, j]
        if j not in z0:
            z0[j] = float(ndtri(np.clip(np.mean(x < y[j]), 1.0 / trials, 1.0 - 1.0 / trials)))
        low, high = np.quantile(x, [ndtr(2 * z0[j] + za), ndtr(2 * z0[j] - za)])
        return float(low), float(high)

    m = y.size
    while True:
        za = float(ndtri(1.0 - (1.0 - (1.0 - level) / 2.0) ** (1.0 / m)))
        best, seen = -math.inf, {}
        for j in order:
            if upper[j] < best:
                break
            seen[j] = bounds(j, za)
            best = max(best, seen[j][0])
        c = max(sum(1 for low, high in seen.values() if high >= best), 1)
        if c >= m:
            return m
        m = c


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

    ``column(j)``: cell j's draws (M,); ``upper`` (T,): a number no smaller than any of
    them (their maximum). A percentile of a cell's draws is at most their maximum, so a cell
    whose ``upper`` lies below both bounds found so far cannot change them and its
    percentiles are not computed: the result is the same as from every cell, at the cost of
    the few cells near the top (and the draws of a range's many pairs of cells need never be
    in memory at once, :func:`calflow.metrics.uncertainty_iso.iso230_2_uncertainty`).
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
        z0 = ndtri(np.clip(np.mean(x < y[j]), 1.0 / trials, 1.0 - 1.0 / trials))
        if upper[j] >= lo:
            lo = max(lo, float(np.quantile(x, ndtr(2 * z0 + za))))
        if upper[j] >= hi:
            hi = max(hi, float(np.quantile(x, ndtr(2 * z0 - zb))))
    return lo, hi


MAX_METHOD = (
    "Monte Carlo (JCGM 101:2008), M = {M} trials (fixed), per target; the 95 % interval of the maximum "
    "from the targets' bias-corrected percentile intervals, the lower bound Šidák-adjusted over the "
    "{t:.3g} target(s) that can be the maximum"
)


def robust_sd(x) -> float:
    """Half the central 68.27 % range of ``x``: the standard deviation of a normal, and finite
    for the heavy tails of a scatter known from few readings (a variance with ν ≤ 4 dof has
    no finite variance of its own)."""
    from scipy import stats

    lo, hi = np.quantile(np.asarray(x, float), [stats.norm.cdf(-1.0), stats.norm.cdf(1.0)])
    return float(hi - lo) / 2.0


def mc_result(value, draws, parts, dofs, interval, method, note="") -> Uncertainty:
    """A Monte Carlo result: U the interval's half-width, k = t_0.975(ν_eff) and u = U/k.

    ν_eff is the Welch–Satterthwaite dof of the budget, whose terms are the robust standard
    deviations (:func:`robust_sd`) of the metric with each term alone; u = U/k makes the
    Student's t that the decisions use (:mod:`calflow.certificate.conformity`) reproduce the Monte
    Carlo interval's half-width.
    """
    lo, hi = interval
    U = float(hi - lo) / 2.0
    budget = {n: robust_sd(v) for n, v in parts.items()}
    dof = welch_satterthwaite(list(budget.values()), [dofs.get(n, math.inf) for n in budget])
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
    )


class Draws:
    """Shared random inputs of one Monte Carlo: a sample term and the declared terms.

    The large inputs — the sample's standard normals and each per-target term's, (M, cells,
    d) each, 1.5 GB for a 1890-target sweep at M = 50 000 — are not kept: the generator's
    state where each begins is, and :meth:`error` draws them again, ``BLOCK`` trials at a
    time, into its result. The numbers are those of drawing each array whole (a generator
    fills an array element by element, so blocks continue one another), and the stream after
    the constructor is where it would be; memory holds the result, not every input.
    """

    BLOCK = 1024  #: trials drawn at a time

    def __init__(self, s: np.ndarray, dof: int, shape: tuple[int, int], terms, trials: int, seed: int):
        self.rng = np.random.default_rng(seed)
        self.trials, (self.cells, self.d) = trials, shape
        self.s, self.dof = np.asarray(s, float), dof
        # scaled inverse χ²: σ² = ν s² / χ²_ν, one per trial (the variance shared by the cells)
        self.scale = np.sqrt(dof / self.rng.chisquare(dof, size=trials))[:, None]
        self._z = self._skip((self.cells, self.d))
        self.terms = [t for t in terms if t.scope != "reading"]
        self._noise: dict[str, tuple] = {}
        for t in self.terms:
            if t.scope == "common":  # (M, 1, d): small, kept
                self._noise[t.name] = self.rng.standard_normal((trials, 1, self.d)) * t.per_axis(self.d)
            else:
                self._noise[t.name] = self._skip((self.cells, self.d))

    def _skip(self, shape: tuple[int, ...]) -> dict:
        """The generator's state, then the stream moved past an (M, *shape) array of normals."""
        state = self.rng.bit_generator.state
        scratch = np.empty((min(self.BLOCK, self.trials), *shape))
        for i in range(0, self.trials, self.BLOCK):
            self.rng.standard_normal(out=scratch[: min(self.BLOCK, self.trials - i)])
        return state

    def _blocks(self, state: dict, shape: tuple[int, ...]):
        """``(slice of trials, normals of those trials)`` of the array drawn from ``state``."""
        rng = np.random.Generator(type(self.rng.bit_generator)())
        rng.bit_generator.state = state
        scratch = np.empty((min(self.BLOCK, self.trials), *shape))
        for i in range(0, self.trials, self.BLOCK):
            block = scratch[: min(self.BLOCK, self.trials - i)]
            rng.standard_normal(out=block)
            yield slice(i, i + len(block)), block

    def sigma(self) -> np.ndarray:
        """(M, d): the scatter's σ per axis in each trial."""
        return self.s[None, :] * self.scale

    def error(self, positions: np.ndarray, n: np.ndarray, only: str | None = None) -> np.ndarray:
        """(M, cells, d): the error of each cell's mean; ``only`` one term (or "sample")."""
        out = np.zeros((self.trials, self.cells, self.d))
        shape = (self.cells, self.d)
        if only in (None, "sample"):
            sigma, root_n = self.sigma(), np.sqrt(n)[None, :, None]
            for rows, z in self._blocks(self._z, shape):
                out[rows] += z * (sigma[rows][:, None, :] / root_n)
        for t in self.terms:
            if only not in (None, t.name):
                continue
            if t.scope == "common":
                e = self._noise[t.name]
                out += e * 1e-6 * positions[None, :, :] if t.relative else e
                continue
            per_axis = t.per_axis(self.d)
            for rows, z in self._blocks(self._noise[t.name], shape):
                e = z * per_axis
                out[rows] += e * 1e-6 * positions[None, :, :] if t.relative else e
        return out
