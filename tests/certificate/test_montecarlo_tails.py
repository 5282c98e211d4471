"""The tails a streamed Monte Carlo keeps of every cell (calflow.metrics.uncertainty.tails):
picked out beyond thresholds read from a sample of the draws, the same values as a partial
sort of every draw."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import example, given, settings
from hypothesis import strategies as st

from calflow.metrics.uncertainty.tails import extremes, tail_size


def _by_partial_sort(cols: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    m = cols.shape[1]
    part = np.partition(cols, sorted({k - 1, m - k}), axis=1) if k < m else cols
    return np.sort(part[:, :k], axis=1), np.sort(part[:, m - k :], axis=1)


@settings(max_examples=60, deadline=None)
@given(
    rows=st.integers(1, 6),
    m=st.integers(1, 6000),
    kind=st.sampled_from(["normal", "folded", "ties", "ordered", "constant"]),
    step=st.integers(2, 32),
    seed=st.integers(0, 2**32 - 1),
)
@example(rows=3, m=10_000, kind="folded", step=16, seed=0)  # a block of ISO 230-2's |reversal|
@example(rows=2, m=3000, kind="ordered", step=16, seed=1)  # every threshold misses: the fallback
def test_the_tails_picked_beyond_thresholds_are_the_partial_sorts(rows, m, kind, step, seed):
    """Each row's k smallest and k largest values, sorted, to the byte, whatever the rows hold:
    draws, ties, a constant, values in order (the sample then misjudges every threshold)."""
    rng = np.random.default_rng(seed)
    cols = rng.standard_normal((rows, m)) * rng.uniform(0.01, 100.0) + rng.uniform(-5.0, 5.0)
    if kind == "folded":
        cols = np.abs(cols)
    elif kind == "ties":
        cols = np.round(cols, 0)
    elif kind == "ordered":
        cols = np.sort(cols, axis=1)
    elif kind == "constant":
        cols[:] = 1.5
    k = tail_size(m)
    low, high = extremes(cols.copy(), k, step)
    want_low, want_high = _by_partial_sort(cols, k)
    assert low.tobytes() == want_low.tobytes() and high.tobytes() == want_high.tobytes()
    assert low.shape == (rows, k) and math.isfinite(float(np.sum(low[:, :1])))
