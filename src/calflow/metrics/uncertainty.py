"""Expanded uncertainty U of the headline figures: the budget's terms, GUM, Welch–Satterthwaite,
Monte Carlo and the interval of a maximum (the figures themselves: :mod:`.uncertainty_iso`).

The budget of a metric has the finite sample of targets and cycles (Type A, from the data:
the within-target scatter pooled over targets, with its degrees of freedom) and the
sensor's own terms (Type B, declared by the robot family: calibration, alignment,
temperature, reference standard; :class:`Term`). A term acts on the mean reading at a
target in one of three ways (``scope``):

* ``common``: one error shared by every target of the measurement (an offset, or with
  ``relative`` a scale error in 1e-6 of the position: the sensor's calibration, its
  alignment's cosine error, the reference standard);
* ``target``: an independent error at each target (and direction): drift of the sensor
  with temperature between visits, nonlinearity;
* ``reading``: a per-reading error (noise, resolution). It is in the observed scatter
  already, so it enters through the sample term; the budget lists it for reference only.

Metrics linear in the inputs (the signed mean reversal B̄, a mean deviation) are
propagated with the GUM law (JCGM 100:2008, Eq. 10) and a coverage factor from Student's
t at the Welch–Satterthwaite effective degrees of freedom (JCGM 100 G.4.1). AP (the length
of a mean vector) and the maxima (AP and RP are maxima over targets; ISO 230-2's E, M, B,
A, R maxima and ranges) are propagated by Monte Carlo (JCGM 101:2008) with a fixed number
of trials M (``trials``, default 50 000, seeded so a result reproduces): the variance of
the scatter is drawn from its scaled inverse χ² (ν s²/χ²_ν), the means given it from
normals (JCGM 101 6.4.9), the Type B terms from normals with their standard uncertainty.
A maximum of noisy means is biased upwards and so are trials drawn around it, so the
JCGM 101 probabilistically symmetric interval of the maximum covers its true value too
rarely when targets nearly tie (≈ 86 % for eight targets three cycles each, measured);
the 95 % interval is built instead from each target's bias-corrected percentile interval
and Šidák's adjustment over the targets that can be the maximum
(:func:`maximum_interval`). U is the interval's half-width, ``dof_eff`` the
Welch–Satterthwaite degrees of freedom of the budget, k = t_0.975(ν_eff) and u = U/k (the
trials' own standard deviation does not exist when the scatter is known from few
readings). Each term's contribution in ``budget`` is the robust standard deviation (half
the central 68 % range) of the metric with that term alone.

The measurand of RP (and of ISO 230-2's A and R) is the population value of the scatter
(isotropic normal, pooled over targets): RP∞ = σ (E[χ_d] + 3 SD[χ_d]), what the ISO
formula l̄ + 3 S_l tends to with many cycles; with few cycles the ISO value is biased low
and may lie outside the interval — the record says so in ``note``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "Draws",
    "Term",
    "Uncertainty",
    "chi_rp_factor",
    "check_terms",
    "coverage_factor",
    "gum_linear",
    "largest_bounds",
    "maximum_interval",
    "mc_result",
    "pooled_scatter",
    "reading_budget",
    "robust_sd",
    "sigma_interval",
    "welch_satterthwaite",
]

SCOPES = ("common", "target", "reading")
TRIALS = 50_000
P95 = 0.95


@dataclass(frozen=True)
class Term:
    """One declared source of the sensor's uncertainty.

    ``u``: standard uncertainty per axis (one number for every axis, or one per axis) in
    the metric's length unit, or with ``relative`` in 1e-6 of the position (ppm).
    ``scope``: ``common``, ``target`` or ``reading`` (module notes). ``dof``: its degrees of
    freedom (∞ for a Type B term known well).
    """

    name: str
    u: float | tuple[float, ...]
    scope: str = "common"
    relative: bool = False
    dof: float = math.inf

    def __post_init__(self):
        if self.scope not in SCOPES:
            raise ValueError(
                f"uncertainty term {self.name!r}: scope {self.scope!r}; expected one of {SCOPES}"
            )
        u = np.atleast_1d(np.asarray(self.u, float))
        if not np.all(np.isfinite(u)) or np.any(u < 0):
            raise ValueError(f"uncertainty term {self.name!r}: u must be finite and >= 0, got {self.u!r}")

    def per_axis(self, d: int) -> np.ndarray:
        u = np.atleast_1d(np.asarray(self.u, float))
        if u.size == 1:
            return np.full(d, float(u[0]))
        if u.size != d:
            raise ValueError(f"uncertainty term {self.name!r}: {u.size} values for {d} axes")
        return u


@dataclass(frozen=True)
class Uncertainty:
    """The expanded uncertainty of one metric (its unit): ``value`` ± ``U`` at 95 %."""

    value: float
    U: float
    k: float
    u: float
    dof_eff: float
    interval: tuple[float, float]
    budget: dict[str, float]
    method: str
    note: str = ""
    samples: np.ndarray | None = field(default=None, repr=False, compare=False)

    def record(self) -> dict:
        """``{U, k, dof_eff, budget, u, interval, coverage, method, note}`` for a summary."""
        dof = None if not math.isfinite(self.dof_eff) else float(self.dof_eff)
        return {
            "U": float(self.U),
            "k": float(self.k),
            "dof_eff": dof,
            "budget": {k: float(v) for k, v in self.budget.items()},
            "u": float(self.u),
            "interval": [float(self.interval[0]), float(self.interval[1])],
            "coverage": P95,
            "method": self.method,
            **({"note": self.note} if self.note else {}),
        }


def welch_satterthwaite(u: Sequence[float], dof: Sequence[float]) -> float:
    """Effective degrees of freedom, JCGM 100 Eq. (G.2b): u_c⁴ / Σ u_i⁴/ν_i (∞ terms drop)."""
    u, dof = np.asarray(u, float), np.asarray(dof, float)
    uc4 = float(np.sum(u**2)) ** 2
    finite = np.isfinite(dof) & (u > 0)
    den = float(np.sum(u[finite] ** 4 / dof[finite]))
    return math.inf if den == 0 else uc4 / den


def coverage_factor(dof: float, p: float = P95) -> float:
    """k = t_{(1+p)/2}(ν) (JCGM 100 G.3.4); the normal quantile for ν = ∞."""
    from scipy import stats

    q = (1.0 + p) / 2.0
    return float(stats.norm.ppf(q) if not math.isfinite(dof) else stats.t.ppf(q, dof))


def gum_linear(
    value: float, contributions: dict[str, float], dofs: dict[str, float], p: float = P95
) -> Uncertainty:
    """GUM law of propagation for a metric linear in its inputs (JCGM 100 Eq. 10).

    ``contributions``: each input's |c_i| u(x_i) in the metric's unit (uncorrelated);
    ``dofs``: their degrees of freedom (missing: ∞).
    """
    names = list(contributions)
    u_i = [float(contributions[n]) for n in names]
    nu = [float(dofs.get(n, math.inf)) for n in names]
    uc = math.sqrt(sum(x * x for x in u_i))
    dof = welch_satterthwaite(u_i, nu)
    k = coverage_factor(dof, p)
    return Uncertainty(
        value=float(value),
        U=k * uc,
        k=k,
        u=uc,
        dof_eff=dof,
        interval=(value - k * uc, value + k * uc),
        budget=dict(zip(names, u_i)),
        method="GUM law of propagation (JCGM 100:2008), k from Student's t at the Welch–Satterthwaite dof",
    )


def pooled_scatter(groups: Sequence[np.ndarray]) -> tuple[np.ndarray, int]:
    """Within-group standard deviation per axis pooled over groups, and its dof Σ(n_j − 1).

    ``groups``: arrays (n_j, d) (or (n_j,)) of readings; NaN rows are dropped.
    """
    ss, dof = None, 0
    for g in groups:
        g = np.asarray(g, float)
        g = g.reshape(len(g), -1)
        g = g[np.all(np.isfinite(g), axis=1)]
        if len(g) < 2:
            continue
        dev = ((g - g.mean(axis=0)) ** 2).sum(axis=0)
        ss = dev if ss is None else ss + dev
        dof += len(g) - 1
    if ss is None or dof == 0:
        raise ValueError("no group with two or more readings: the scatter is unknown")
    return np.sqrt(ss / dof), dof


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


def maximum_interval(
    estimates, draws, level: float = P95, t_eff: float | None = None
) -> tuple[float, float, float]:
    """95 % interval of max_j θ_j from per-cell estimates (T,) and Monte Carlo draws (M, T).

    Each cell's interval is the bias-corrected percentile interval of its draws (z₀ from the
    share of draws below the estimate); the maximum's bounds are the largest of the cells'
    bounds, at the one-sided level (1 − (1 − level)/2)^(1/T_eff) (Šidák) where T_eff =
    1/Σ p_j² counts the cells that can be the maximum (p_j: share of the draws in which
    cell j is). With one clear maximum this is that cell's interval; with ties it widens,
    which a maximum of noisy means needs (its estimate is biased upwards and so are the
    draws around it). ``t_eff`` overrides the count (a range's pairs share their cells).
    Returns ``(low, high, T_eff)``.
    """
    y = np.atleast_1d(np.asarray(estimates, float))
    d = np.asarray(draws, float).reshape(len(draws), y.size)
    t_eff = effective_count(d) if t_eff is None else float(t_eff)
    lo, hi = largest_bounds(y, lambda j: np.ascontiguousarray(d[:, j]), d.max(axis=0), len(d), level, t_eff)
    return lo, hi, t_eff


def largest_bounds(estimates, column, upper, trials: int, level: float, t_eff: float) -> tuple[float, float]:
    """The largest of the cells' bias-corrected bounds (:func:`maximum_interval`), cell by cell.

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

    za = ndtri(1.0 - (1.0 - (1.0 - level) / 2.0) ** (1.0 / t_eff))
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
            hi = max(hi, float(np.quantile(x, ndtr(2 * z0 - za))))
    return lo, hi


MAX_METHOD = (
    "Monte Carlo (JCGM 101:2008), M = {M} trials (fixed), per target; the 95 % interval of the maximum "
    "from the targets' bias-corrected percentile intervals, Šidák-adjusted over the {t:.1f} target(s) "
    "that can be the maximum"
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


def check_terms(terms: Sequence[Term]) -> list[Term]:
    names = [t.name for t in terms]
    if len(set(names)) != len(names) or "sample" in names:
        raise ValueError(f"uncertainty terms: names must be unique and not 'sample', got {names}")
    return list(terms)


def reading_budget(terms: Sequence[Term]) -> dict:
    return {
        f"{t.name} (in the sample term)": float(np.max(t.per_axis(1))) for t in terms if t.scope == "reading"
    }


def sigma_interval(s: float, dof: int, level: float = P95) -> tuple[float, float]:
    """Exact interval of a normal σ from its estimate s with ν dof (χ² quantiles)."""
    from scipy import stats

    a = (1.0 - level) / 2.0
    return s * math.sqrt(dof / stats.chi2.ppf(1 - a, dof)), s * math.sqrt(dof / stats.chi2.ppf(a, dof))
