"""The tails of each cell's draws, kept block by block, that a maximum's bounds are read from.

A maximum's interval (:func:`.montecarlo.largest_bounds`) needs of each cell only the share of
its draws below its estimate (the bias correction z₀) and two percentiles: the upper bound at
ndtr(2 z₀ + 1.96) and the lower one at ndtr(2 z₀ + z_a), z_a ≤ −1.96 (:func:`.montecarlo.lower_risk`).
While z₀ is small these lie in the cell's top and bottom few per cent. So every block keeps,
for every cell of a maximum, how many of its draws lie below the estimate and its
:data:`TAIL` lowest and highest draws (sorted): a few kilobytes a cell, where the whole column
is 8 bytes a trial. A percentile is read off the tails of the blocks looked at when it is
provably there — the order statistic of all their draws at that rank is one of the kept ones,
no block's unkept draws being on its side of it — and is then the same number as
``np.quantile`` of the whole column; otherwise (a large z₀, a short block) the column is asked
for (drawn again, :mod:`.looks`). Without the tails, a sweep whose hundreds of cells tie for
the maximum (ISO 230-2's B and R, a constant backlash) had every one of them drawn again at
every look.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

TAIL = 0.035  #: share of a block's draws kept at each end of every cell of a maximum (the upper bound of a cell whose bias correction is slightly negative, z₀ ≥ −0.07, lies in them)
SUBSAMPLE = 16  #: every how many draws of a cell the thresholds of its tails are read from


def tail_size(m: int) -> int:
    """Draws kept at each end of a cell in a block of ``m`` trials (all of them in a short block)."""
    return min(int(m), max(2, math.ceil(TAIL * m)))


class BlockTails:
    """One block's tails of one maximum's cells: ``low``/``high`` (cells, k) sorted ascending,
    ``below`` (cells,) the draws under each cell's estimate."""

    def __init__(self, m: int, cells: int):
        self.m, self.k = int(m), tail_size(m)
        self.low = np.full((cells, self.k), np.nan)
        self.high = np.full((cells, self.k), np.nan)
        self.below = np.zeros(cells, np.int64)

    def take(self, values: np.ndarray, idx: np.ndarray, estimates: np.ndarray) -> None:
        """``values`` (m, G): the block's draws of cells ``idx``, compared with their ``estimates``."""
        self.take_rows(values.T.copy(), idx, estimates)

    def take_rows(self, cols: np.ndarray, idx: np.ndarray, estimates: np.ndarray) -> None:
        """:meth:`take` of the draws laid out a cell a row, ``cols`` (G, m), which it may reorder."""
        self.below[idx] = np.count_nonzero(cols < estimates[:, None], axis=1)
        self.low[idx], self.high[idx] = extremes(cols, self.k)


def extremes(cols: np.ndarray, k: int, step: int = SUBSAMPLE) -> tuple[np.ndarray, np.ndarray]:
    """(G, k) each, sorted ascending: the k smallest and the k largest values of each row of
    ``cols`` (G, m), which it may reorder.

    A partial sort of every row at k and m − k costs about as much as the rest of a block
    together. The rows are draws in random order, so every ``step``-th of them is a sample of
    the row: its order statistic at rank ⌈2.5 k / step⌉ from each end is a threshold that about
    2.5 k of the row's values lie beyond; those are picked out and partially sorted (a few
    per cent of the row). Whenever fewer than k lie beyond a threshold (rare: a 4σ event a row)
    the row is partially sorted whole. The k values at each end are the same whatever picks
    them, so the result is the whole row's partial sort's, to the byte."""
    G, m = cols.shape
    r = math.ceil(2.5 * k / step)
    if k >= m or 2 * r >= (m - 1) // step:  # a short row: no sample to speak of
        if k < m:
            cols.partition(sorted({k - 1, m - k}), axis=1)
        return np.sort(cols[:, :k], axis=1), np.sort(cols[:, m - k :], axis=1)
    sample = cols[:, ::step]
    n = sample.shape[1]
    sample = np.partition(sample, [r, n - 1 - r], axis=1)
    low_side = cols <= sample[:, r : r + 1]
    high_side = cols >= sample[:, n - 1 - r : n - r]
    low, n_low = _beyond(cols, low_side, k, np.inf)
    high, n_high = _beyond(cols, high_side, k, -np.inf)
    low.partition(k - 1, axis=1)
    high.partition(high.shape[1] - k, axis=1)
    low, high = np.sort(low[:, :k], axis=1), np.sort(high[:, high.shape[1] - k :], axis=1)
    for j in np.flatnonzero((n_low < k) | (n_high < k)):
        row = np.partition(cols[j], [k - 1, m - k])
        low[j], high[j] = np.sort(row[:k]), np.sort(row[m - k :])
    return low, high


def _beyond(cols: np.ndarray, mask: np.ndarray, k: int, fill: float) -> tuple[np.ndarray, np.ndarray]:
    """The values of ``cols`` (G, m) where ``mask``, row by row, padded with ``fill`` to at least
    k a row: (G, width) and how many each row has."""
    counts = np.count_nonzero(mask, axis=1)
    values = np.compress(mask.ravel(), cols.ravel())  # row after row (cols[mask]'s, a third faster)
    out = np.full((cols.shape[0], max(int(counts.max(initial=0)), k)), fill)
    row = np.repeat(np.arange(cols.shape[0]), counts)
    out[row, np.arange(values.size) - (np.cumsum(counts) - counts)[row]] = values
    return out, counts


def _virtual_index(n: int, q: float) -> float:
    """Where ``np.quantile``'s default (linear) method reads quantile q of n sorted values, by
    the same arithmetic (Hyndman and Fan's method 7), so the numbers are the same."""
    return (n - 1) * q


def _lerp(a: float, b: float, t: float) -> float:
    """numpy's interpolation between neighbouring order statistics (the same rounding)."""
    d = b - a
    return float(b - d * (1.0 - t)) if t >= 0.5 else float(a + d * t)


def _upper_rank(n: int, q: float) -> int:
    """The rank (0-based) of the larger of the two order statistics quantile q of n values is
    read between: its value is never below the quantile (:func:`_lerp` stays within its ends)."""
    v = _virtual_index(n, q)
    return n - 1 if v >= n - 1 else min(math.floor(v) + 1, n - 1)


def quantile(x: np.ndarray, q: float) -> float:
    """``np.quantile(x, q)`` of a 1-D array without NaN (its default, linear method): the same
    number, from a partial sort at the two order statistics it reads only. ``np.quantile``
    also places the smallest and the largest draw (its NaN check), which costs a column's
    percentile 2–4 times as much where the percentile lies in a tail."""
    n = x.size
    v = _virtual_index(n, q)
    if v >= n - 1 or v < 0:
        return float(x.max() if v >= 0 else x.min())
    i = math.floor(v)
    part = np.partition(x, [i, i + 1])
    return _lerp(float(part[i]), float(part[i + 1]), v - i)


class Column:
    """A cell's whole column of draws (M,) and its estimate, as :func:`.montecarlo.largest_bounds`
    reads a cell: the share below the estimate and percentiles (``np.quantile``'s)."""

    def __init__(self, x: np.ndarray, estimate: float):
        self.x, self.estimate = x, estimate

    def share_below(self) -> float:
        return np.count_nonzero(self.x < self.estimate) / self.x.size  # np.mean's number

    def quantile(self, qs) -> list[float]:
        return [quantile(self.x, float(q)) for q in qs]

    def at_most(self, q: float, bound: float) -> bool:
        """Whether the q-percentile is provably no larger than ``bound`` — it cannot raise a
        bound found so far — by one count instead of a partial sort: the order statistic
        above it is ≤ ``bound`` when at least rank + 1 draws are."""
        return bool(np.count_nonzero(self.x <= bound) > _upper_rank(self.x.size, q))


class TailSample:
    """One cell's draws over some blocks, as far as its tails tell: the share below its
    estimate and percentiles (:meth:`quantile`), the whole column asked of ``column`` when a
    percentile is not provably in the tails."""

    def __init__(self, blocks: list[BlockTails], j: int, column: Callable[[], np.ndarray]):
        self.n = sum(b.m for b in blocks)
        self.below = int(sum(int(b.below[j]) for b in blocks))
        self._blocks, self._j, self._column, self._full = blocks, j, column, None
        self._low = self._high = None

    def share_below(self) -> float:
        """The share of the draws below the estimate (``np.mean(x < y)``: the same number)."""
        return self.below / self.n

    def at_most(self, q: float, bound: float) -> bool:
        """Whether the q-percentile is provably ≤ ``bound`` (:meth:`Column.at_most`), from
        the tails (False where they do not tell)."""
        v = self._order(_upper_rank(self.n, q))
        return v is not None and v <= bound

    def _order(self, r: int) -> float | None:
        """The r-th smallest of all the draws (0-based), if the tails hold it provably."""
        if self._low is None:
            self._low = np.sort(np.concatenate([b.low[self._j] for b in self._blocks]))
            self._high = np.sort(np.concatenate([b.high[self._j] for b in self._blocks]))
            # a block's unkept draws lie between its kept low and high tails
            short = [b for b in self._blocks if b.k < b.m]
            self._low_ok = min((b.low[self._j, -1] for b in short), default=np.inf)
            self._high_ok = max((b.high[self._j, 0] for b in short), default=-np.inf)
        if r < self._low.size and self._low[r] <= self._low_ok:
            return float(self._low[r])
        top = self.n - 1 - r  # rank from the top
        if 0 <= top < self._high.size:
            v = self._high[self._high.size - 1 - top]
            if v >= self._high_ok:
                return float(v)
        return None

    def quantile(self, qs) -> list[float]:
        """``np.quantile(column, qs)`` from the tails, or from the column where they do not tell."""
        out = []
        for q in qs:
            v = self._one(float(q))
            if v is None:
                if self._full is None:
                    self._full = np.asarray(self._column(), float)
                v = quantile(self._full, float(q))
            out.append(v)
        return out

    def _one(self, q: float) -> float | None:
        n = self.n
        v = _virtual_index(n, q)
        if v >= n - 1:
            return self._order(n - 1)
        if v < 0:
            return self._order(0)
        i = math.floor(v)
        a, b = self._order(i), self._order(i + 1)
        if a is None or b is None:
            return None
        return _lerp(a, b, v - i)
