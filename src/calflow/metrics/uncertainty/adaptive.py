"""When a Monte Carlo has drawn enough: JCGM 101:2008 §7.9, the adaptive procedure.

Trials are drawn in blocks of M = 10⁴ (:data:`calflow.metrics.uncertainty.draws.BLOCK`).
After each block h ≥ 2, each quantity the result reports (for an interval: its two ends
and U, its half-width) is computed from each block alone, and the standard deviation of
their average over the h blocks, s = √(Σ (x⁽ʳ⁾ − x̄)² / (h (h − 1))) (§7.9.4 f). The
procedure stops when 2 s ≤ δ for every quantity, δ the numerical tolerance of u (§7.2.2):
u written with ``digits`` significant digits, u = c × 10ˡ, δ = ½ × 10ˡ (one digit, the
guide's least demanding choice, is the default), or after :data:`MAX_BLOCKS` blocks, and
the record says which. The result is then computed from all h × M trials (§7.9.4 j).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

MAX_BLOCKS = 10  #: the cap: 10⁵ trials at most (twice the fixed M = 50 000 it replaces)
DIGITS = 1  #: significant digits of u the tolerance is stated for (JCGM 101 §7.2.2: 1 or 2)


def numerical_tolerance(u: float, digits: int = DIGITS) -> float:
    """δ = ½ × 10ˡ where u = c × 10ˡ, c an integer of ``digits`` digits (JCGM 101 §7.2.2).

    u = 0.0374 µm with one digit: c = 4, l = −2, δ = 0.005 µm. δ = 0 when u = 0 (nothing
    random: every block gives the same value)."""
    u = abs(float(u))
    if u == 0.0 or not math.isfinite(u):
        return 0.0 if u == 0.0 else math.inf
    l_exp = math.floor(math.log10(u)) - digits + 1
    if round(u / 10.0**l_exp) >= 10**digits:  # 0.096 with one digit rounds to 0.1: c = 1, l = −1
        l_exp += 1
    return 0.5 * 10.0**l_exp


def spread(values: Sequence[float]) -> float:
    """2 s: twice the standard deviation of the average of the blocks' values (§7.9.4 f)."""
    x = np.asarray(values, float)
    h = x.size
    if h < 2:
        return math.inf
    return float(2.0 * math.sqrt(np.sum((x - x.mean()) ** 2) / (h * (h - 1))))


def stable(blocks: dict[str, list[tuple[float, float]]], u: dict[str, float], digits: int = DIGITS) -> dict:
    """The stopping rule over the blocks' intervals ``{name: [(low, high) per block]}``, each
    interval's u (from the trials so far) giving its δ. Returns ``{name: {tolerance, spread,
    reached}}``: ``spread`` the largest 2 s of the low end, the high end and U."""
    out = {}
    for name, ends in blocks.items():
        lo, hi = (np.array([e[i] for e in ends], float) for i in (0, 1))
        worst = max(spread(lo), spread(hi), spread((hi - lo) / 2.0))
        delta = numerical_tolerance(u[name], digits)
        out[name] = {"tolerance": delta, "spread": worst, "reached": bool(worst <= delta)}
    return out
