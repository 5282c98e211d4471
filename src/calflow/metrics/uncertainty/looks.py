"""Looks at a streamed Monte Carlo's intervals (:mod:`.stream`): after a block (the stopping
rule's per-block values) and over every block (the result). An interval's rule is
:func:`.montecarlo.largest_bounds` with the count of :func:`.montecarlo.candidates` (the cells
that can be the maximum); both need the draws of the cells that can set
its bounds, which the blocks kept (the watched cells) or which are drawn again here from their
seeds, group by group, once for every interval, and stored within :data:`STORE_BYTES` for
the next look.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from calflow.metrics.uncertainty.draws import Draws
from calflow.metrics.uncertainty.montecarlo import COUNT_TRIALS, candidates, largest_bounds
from calflow.metrics.uncertainty.tails import Column, TailSample

STORE_BYTES = 128e6  #: draws drawn again and kept for the next look at the intervals (bytes)


@dataclass(frozen=True)
class Maximum:
    """Interval of max_j θ_j (:func:`.montecarlo.maximum_interval`): the set ``cells``, their
    estimates, and the name of a per-trial addition to every cell's draws (or None)."""

    cells: str
    estimates: np.ndarray
    add: str | None = None


@dataclass(frozen=True)
class Span:
    """Interval of max_i θ_i − min_j θ_j (+ ``add_est`` / the per-trial ``add``), as a maximum
    over pairs of cells (:func:`calflow.metrics.uncertainty_iso.iso230_2_uncertainty`)."""

    cells: str
    estimates: np.ndarray
    add_est: float = 0.0
    add: str | None = None


def kept_by_all(blocks, s: str, j: int) -> bool:
    """Whether every one of ``blocks`` kept the draws of cell ``j`` of set ``s``."""
    return all(int(j) in blk.kept[s] for blk in blocks)


@dataclass
class Looks:
    """The blocks drawn so far, and how to draw a cell's trials again."""

    draws: Draws
    positions: np.ndarray
    n: np.ndarray
    cells: Callable
    level: float
    where: dict[str, np.ndarray]  #: per set, the group of each cell
    watch: dict[str, np.ndarray]  #: per set, the cells whose draws each new block keeps
    blocks: list = field(default_factory=list)
    store: dict = field(
        default_factory=dict
    )  #: (set, cell, block) → draws drawn again, kept for a later look
    stored: int = 0  #: their bytes
    #: per interval, how many cells can be its maximum: counted once, from the first block's
    #: first draws (:func:`.montecarlo.candidate_count`'s), and kept for every look after it
    counts: dict = field(default_factory=dict)

    def intervals(self, specs: dict, block_ids) -> dict[str, tuple[float, float, float]]:
        """``{name: (low, high, T_eff)}`` of every interval from the trials of ``block_ids``.

        A maximum's bounds are the largest of its cells' (:func:`largest_bounds`), read off the
        tails every block kept of its cells (:mod:`.tails`; a cell's column is drawn again
        only where a percentile is not in them). A range's need the draws of the cells that
        are the largest or smallest in some trial: kept, or drawn again group by group."""
        block_ids = list(block_ids)
        chosen = [self.blocks[b] for b in block_ids]
        trials = sum(blk.m for blk in chosen)
        spans, out = {}, {}
        for name, spec in specs.items():
            s, y = spec.cells, np.asarray(spec.estimates, float)
            add = np.concatenate([blk.extras[spec.add] for blk in chosen]) if spec.add else None
            if isinstance(spec, Span):
                spans[name] = (spec, y, add)
                continue
            upper = np.max(
                [blk.add_cmax[(s, spec.add)] if spec.add else blk.cmax[s] for blk in chosen], axis=0
            )
            if name not in self.counts:  # from the first draws, as candidate_count counts them
                counted = min(trials, COUNT_TRIALS)
                column = self._cell(spec, add, chosen, block_ids, counted)
                self.counts[name] = float(candidates(y, column, upper, counted, self.level))
            t_eff = self.counts[name]
            tails = [blk.tails[name] for blk in chosen]

            def sample(j, s=s, add=add, tails=tails):
                def whole():
                    c = self._redraw(int(self.where[s][j]), {s: {int(j)}}, block_ids, True)[s][int(j)]
                    return c + add if add is not None else c

                return TailSample(tails, int(j), whole)

            lo, hi = largest_bounds(y, sample, upper, trials, self.level, t_eff)
            out[name] = (lo, hi, t_eff)
        # a range's cells no block kept, group by group
        wanted: dict[int, dict[str, set]] = {}
        for spec, y, _ in spans.values():
            counts_max = sum(np.bincount(blk.amax[spec.cells], minlength=y.size) for blk in chosen)
            counts_min = sum(np.bincount(blk.amin[spec.cells], minlength=y.size) for blk in chosen)
            for j in np.union1d(np.flatnonzero(counts_max), np.flatnonzero(counts_min)):
                if not kept_by_all(chosen, spec.cells, int(j)):
                    wanted.setdefault(int(self.where[spec.cells][j]), {}).setdefault(spec.cells, set()).add(
                        int(j)
                    )
        drawn: dict[str, dict[int, np.ndarray]] = {}
        for g, sets in wanted.items():
            for s_name, c in self._redraw(g, sets, block_ids).items():
                drawn.setdefault(s_name, {}).update(c)
        for name, (spec, y, add) in spans.items():
            out[name] = self._span(spec, y, add, chosen, block_ids, trials, drawn.get(spec.cells, {}))
        return {name: out[name] for name in specs}

    def _redraw(
        self, g: int, sets: dict[str, set], block_ids, neighbours: bool = False
    ) -> dict[str, dict[int, np.ndarray]]:
        """The draws of some cells of group ``g`` over ``block_ids``: those a block kept or an
        earlier look stored as they are, the others drawn again (the group once a block) and
        stored while :data:`STORE_BYTES` allows; with ``neighbours``, the group's other cells
        of the sets too, while there is room (a maximum's cells whose percentiles the tails do
        not hold are asked for one after another, often from one group)."""
        for b in block_ids:
            missing = {s: [j for j in cells if (s, j, b) not in self.store and j not in self.blocks[b].kept[s]]
                       for s, cells in sets.items()}  # fmt: skip
            if not any(missing.values()):
                continue
            total, _ = self.draws.error(b, self.blocks[b].m, g, self.positions, self.n)
            values = self.cells(total, g)
            for s, cells in sets.items():
                v, idx = values[s]
                asked = np.isin(idx, list(cells))
                for q in np.flatnonzero(asked):
                    column = np.ascontiguousarray(v[:, q])
                    self.store[(s, int(idx[q]), b)] = column
                    self.stored += column.nbytes
                for q in np.flatnonzero(~asked) if neighbours else ():
                    key = (s, int(idx[q]), b)
                    if key in self.store or int(idx[q]) in self.blocks[b].kept[s]:
                        continue
                    if self.stored + 8 * v.shape[0] > STORE_BYTES:
                        break
                    self.store[key] = np.ascontiguousarray(v[:, q])
                    self.stored += self.store[key].nbytes
            while self.stored > STORE_BYTES and self.store:  # the oldest go first
                self.stored -= self.store.pop(next(iter(self.store))).nbytes
        out: dict[str, dict[int, np.ndarray]] = {}
        for s, cells in sets.items():
            out[s] = {}
            for j in cells:
                parts = [self.store.get((s, j, b)) for b in block_ids]
                if any(p is None and j not in self.blocks[b].kept[s] for p, b in zip(parts, block_ids)):
                    parts = self._redraw_one(g, s, j, block_ids)
                out[s][j] = np.concatenate(
                    [p if p is not None else self.blocks[b].kept[s][j] for p, b in zip(parts, block_ids)]
                )
        return out

    def _redraw_one(self, g: int, s: str, j: int, block_ids) -> list:
        """One cell's draws in each block, drawn again whatever was stored (the store overflowed)."""
        out = []
        for b in block_ids:
            v, idx = self.cells(self.draws.error(b, self.blocks[b].m, g, self.positions, self.n)[0], g)[s]
            out.append(np.ascontiguousarray(v[:, int(np.flatnonzero(idx == j)[0])]))
        return out

    def _cell(self, spec, add, chosen, block_ids, first: int) -> Callable[[int], np.ndarray]:
        """Cell j's ``first`` draws over ``block_ids`` (plus the per-trial addition): kept, or
        drawn again with the rest of its group, each group once (a sweep's tied cells, hundreds
        of a group, are counted one after another). ``upper`` stays a bound of these too. The
        first block keeps the first draws of every cell of a maximum when memory allows: then
        nothing is drawn again."""
        s = spec.cells
        kept = self.blocks[0].first.get(s) if block_ids and block_ids[0] == 0 else None
        if kept is not None and kept.shape[1] >= first:

            def first_draws(j: int) -> np.ndarray:
                c = kept[int(j), :first]
                return c + add[:first] if add is not None else c

            return first_draws
        ids, n = [], 0
        for b, blk in zip(block_ids, chosen):
            if n >= first:
                break
            ids.append(b)
            n += blk.m
        few = [self.blocks[b] for b in ids]
        groups: dict[int, dict[int, np.ndarray]] = {}

        def group(g: int) -> dict[int, np.ndarray]:
            if g not in groups:
                parts = []
                for b in ids:
                    v, idx = self.cells(
                        self.draws.error(b, self.blocks[b].m, g, self.positions, self.n)[0], g
                    )[s]
                    parts.append(v)
                values = np.concatenate(parts)[:first]
                del parts
                groups[g] = {int(c): np.ascontiguousarray(values[:, q]) for q, c in enumerate(idx)}
            return groups[g]

        def column(j: int) -> np.ndarray:
            if kept_by_all(few, s, j):
                c = self._column(s, j, ids, {})[:first]
            else:
                c = group(int(self.where[s][j])).pop(int(j))  # asked once: the count keeps it
            return c + add[: len(c)] if add is not None else c

        return column

    def _column(self, s: str, j: int, block_ids, drawn: dict) -> np.ndarray:
        if j in drawn:
            return drawn[j]
        return np.concatenate([self.blocks[b].kept[s][j] for b in block_ids])

    def _span(self, spec, y, add, chosen, block_ids, trials, drawn) -> tuple[float, float, float]:
        """A range's interval as a maximum over pairs (max cell − min cell), from the cells that
        are the largest or the smallest in some trial."""
        s = spec.cells
        counts_max = sum(np.bincount(blk.amax[s], minlength=y.size) for blk in chosen)
        counts_min = sum(np.bincount(blk.amin[s], minlength=y.size) for blk in chosen)
        top, bottom = np.flatnonzero(counts_max), np.flatnonzero(counts_min)
        t_eff = float(
            1.0 / np.sum((counts_max / trials) ** 2) + 1.0 / np.sum((counts_min / trials) ** 2) - 1.0
        )
        cmax = np.max([blk.cmax[s] for blk in chosen], axis=0)
        cmin = np.min([blk.cmin[s] for blk in chosen], axis=0)
        e = (y[top][:, None] - y[bottom][None, :]).ravel() + spec.add_est
        extra = add if add is not None else np.zeros(1)
        hi_top, lo_bottom = cmax[top], cmin[bottom]
        size = np.abs(hi_top)[:, None] + np.abs(lo_bottom)[None, :] + np.abs(extra).max()
        upper = ((hi_top[:, None] - lo_bottom[None, :]) + extra.max() + 1e-12 * size).ravel()
        rows_top = [self._column(s, int(j), block_ids, drawn) for j in top]
        rows_bottom = [self._column(s, int(j), block_ids, drawn) for j in bottom]
        nb = bottom.size

        def column(q):
            c = rows_top[q // nb] - rows_bottom[q % nb]
            return Column(c + add if add is not None else c, e[q])

        return (*largest_bounds(e, column, upper, trials, self.level, t_eff), t_eff)
