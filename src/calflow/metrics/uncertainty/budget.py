"""The budget of a headline figure and its GUM propagation: the declared terms
(:class:`Term`), the result (:class:`Uncertainty`), the Welch–Satterthwaite degrees of
freedom, the coverage factor, the GUM law for a metric linear in its inputs and the pooled
scatter of the readings (the sample term). The package's docstring describes the method
(:mod:`calflow.metrics.uncertainty`)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

SCOPES = ("common", "target", "reading")
TRIALS = None  #: M: None, adaptive (JCGM 101 §7.9, :mod:`.adaptive`); a number fixes it
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
    #: a Monte Carlo's M and the numerical tolerance it reached (:mod:`.adaptive`), or None
    monte_carlo: dict | None = None

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
            **({"monte_carlo": dict(self.monte_carlo)} if self.monte_carlo else {}),
        }


def welch_satterthwaite(u: Sequence[float], dof: Sequence[float]) -> float:
    """Effective degrees of freedom, JCGM 100 Eq. (G.2b): u_c⁴ / Σ u_i⁴/ν_i (∞ terms drop)."""
    u, dof = np.asarray(u, float), np.asarray(dof, float)
    uc4 = float(np.sum(u**2)) ** 2
    finite = np.isfinite(dof) & (u > 0)
    den = float(np.sum(u[finite] ** 4 / dof[finite]))
    return math.inf if den == 0 else uc4 / den


def coverage_factor(dof: float, p: float = P95) -> float:
    """k = t_{(1+p)/2}(ν) (JCGM 100 G.3.4); the normal quantile for ν = ∞. By the functions
    ``scipy.stats.norm.ppf`` and ``t.ppf`` call (the same numbers; importing scipy.stats
    costs a summary job about half a second of CPU)."""
    from scipy.special import ndtri, stdtrit

    q = (1.0 + p) / 2.0
    return float(ndtri(q) if not math.isfinite(dof) else stdtrit(dof, q))


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
    """Exact interval of a normal σ from its estimate s with ν dof (χ² quantiles: ``scipy.stats.chi2.ppf``'s
    function, 2 P⁻¹(ν/2, q) by the inverse regularised incomplete gamma function)."""
    from scipy.special import gammaincinv

    a = (1.0 - level) / 2.0

    def chi2_ppf(q: float) -> float:
        return float(2 * gammaincinv(dof / 2, q))

    return s * math.sqrt(dof / chi2_ppf(1 - a)), s * math.sqrt(dof / chi2_ppf(a))
