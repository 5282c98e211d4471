"""The Monte Carlo of maxima and ranges over many cells, streamed block by block and group by
group (:mod:`.draws`), until JCGM 101 §7.9's stopping rule holds (:mod:`.adaptive`).

A metric hands :func:`simulate` its cells (a function turning one group's error into the
values of its cell sets: ISO 9283's |mean deviation| per target, ISO 230-2's cell means,
mid-points and reversals), the intervals it reports (:class:`Maximum`, :class:`Span`) and
their per-trial statistics. Per block, memory holds one group of cells; what is kept of every
trial is a handful of numbers (each set's largest and smallest cell and where they are, the
metric's statistics, each term's alone), and of every cell its extremes and how often it is
the largest or smallest. A maximum's rule (:func:`.montecarlo.largest_bounds` with the count
of :func:`.montecarlo.candidates`) reads each cell's tails, kept by every block
(:mod:`.tails`), and the first block's first draws of its cells; a range's needs the draws of
the few cells that are its largest or smallest in some trial: kept by the block as it is drawn
(a cell that becomes the largest or smallest so far in a trial keeps its draws until a later
group overtakes it in every such trial; later blocks keep the cells earlier ones found), else
drawn again, a few at a time, from their blocks' seeds. The numbers are those of the whole (M, cells) array; memory
grows with the cells through the per-cell counters and tails (5.6 kB a cell a block of 10⁴) and the
count's first draws (40 kB a cell, once).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from calflow.metrics.uncertainty.adaptive import DIGITS, MAX_BLOCKS, stable
from calflow.metrics.uncertainty.budget import P95
from calflow.metrics.uncertainty.draws import BLOCK, Draws, block_sizes
from calflow.metrics.uncertainty.looks import Looks, Maximum, Span
from calflow.metrics.uncertainty.montecarlo import COUNT_TRIALS
from calflow.metrics.uncertainty.tails import BlockTails

WATCH = 64  #: cells of a set whose draws every block keeps: those with the largest (and smallest) estimates
KEPT_BYTES = 320e6  #: the watched cells' draws the blocks keep, all blocks together (bytes)
FIRST_BYTES = 160e6  #: the first block's first draws of a maximum's cells, kept for the count (bytes)


@dataclass
class Outcome:
    """What :func:`simulate` found: per interval ``(low, high, T_eff)``; ``stats[name]`` and
    ``parts[name][input]`` the per-trial statistics (with every input, with one alone);
    ``extras`` the per-trial additions; ``record`` M and the tolerance reached."""

    intervals: dict[str, tuple[float, float, float]]
    stats: dict[str, np.ndarray]
    parts: dict[str, dict[str, np.ndarray]]
    extras: dict[str, np.ndarray]
    record: dict = field(default_factory=dict)


class _Block:
    """One block's trials: per set, the per-trial extremes and where they are, per cell its
    extremes, and the draws of the watched cells; per input alone, the per-trial extremes."""

    def __init__(
        self,
        m: int,
        sizes: dict[str, int],
        inputs: list[str],
        watch: dict[str, np.ndarray],
        room: float,
        maxima: dict[str, Maximum],
        first: int = 0,
        records: frozenset[str] = frozenset(),
    ):
        self.m, self.watch, self.room = m, watch, room  # room: bytes the block may keep
        self.maxima = maxima
        #: the sets of a range, whose cells that become the largest or smallest so far in some
        #: trial keep their draws (:meth:`settle` drops those another cell overtook later)
        self.records = records
        #: per set of a maximum, its cells' first ``first`` draws (cells, first): what the count
        #: of candidates reads (:func:`.montecarlo.candidates`), kept by the first block
        self.first = (
            {sp.cells: np.empty((sizes[sp.cells], min(m, first))) for sp in maxima.values()} if first else {}
        )
        self.tails = {name: BlockTails(m, sizes[spec.cells]) for name, spec in maxima.items()}
        self.tmax = {s: np.full(m, -np.inf) for s in sizes}
        self.tmin = {s: np.full(m, np.inf) for s in sizes}
        self.amax = {s: np.zeros(m, int) for s in sizes}
        self.amin = {s: np.zeros(m, int) for s in sizes}
        self.cmax = {s: np.full(k, -np.inf) for s, k in sizes.items()}
        self.cmin = {s: np.full(k, np.inf) for s, k in sizes.items()}
        self.add_cmax: dict[tuple[str, str], np.ndarray] = {}
        self.kept: dict[str, dict[int, np.ndarray]] = {s: {} for s in sizes}
        self.pmax = {i: {s: np.full(m, -np.inf) for s in sizes} for i in inputs}
        self.pmin = {i: {s: np.full(m, np.inf) for s in sizes} for i in inputs}
        self.extras: dict[str, np.ndarray] = {}

    def take(self, values: dict, adds: set[tuple[str, str]]) -> None:
        rows = np.arange(self.m)
        for s, (v, idx) in values.items():
            a, b = v.argmax(axis=1), v.argmin(axis=1)
            hi, lo = v[rows, a], v[rows, b]
            up, down = hi > self.tmax[s], lo < self.tmin[s]
            self.tmax[s][up], self.amax[s][up] = hi[up], idx[a[up]]
            self.tmin[s][down], self.amin[s][down] = lo[down], idx[b[down]]
            if s in self.records:  # a range's cells are the largest or smallest in some trial
                self._keep(s, v, idx, np.union1d(a[up], b[down]))
            self.cmax[s][idx] = v.max(axis=0)
            self.cmin[s][idx] = v.min(axis=0)
            mine = [(name, spec) for name, spec in self.maxima.items() if spec.cells == s]
            # each cell's draws in a row (the tails' layout), transposed once for every maximum
            # of the set; a per-trial addition is added to the rows, computed once
            by_cell = v.T.copy() if mine else None
            added = {}
            for cells, add in adds:
                if cells == s:
                    added[add] = by_cell + self.extras[add][None, :]
                    self.add_cmax.setdefault((s, add), np.full(self.cmax[s].size, -np.inf))
                    self.add_cmax[(s, add)][idx] = added[add].max(axis=1)
            if s in self.first:
                self.first[s][idx] = v[: self.first[s].shape[1]].T
            for name, spec in mine:  # the tails may reorder a row: its values stay the same
                cols = added[spec.add] if spec.add else by_cell
                self.tails[name].take_rows(cols, idx, np.asarray(spec.estimates, float)[idx])
            del added, by_cell
            self._keep(s, v, idx, np.flatnonzero(np.isin(idx, self.watch[s])))

    def _keep(self, s: str, v: np.ndarray, idx: np.ndarray, columns: np.ndarray) -> None:
        """Keep the draws of the group's ``columns`` of ``v`` (not kept yet) while there is room."""
        for q in columns:
            if int(idx[q]) in self.kept[s]:
                continue
            if self.room < 8 * self.m:
                break
            self.kept[s][int(idx[q])] = np.ascontiguousarray(v[:, q])
            self.room -= 8 * self.m

    def extreme_cells(self, s: str) -> np.ndarray:
        """The cells of set ``s`` that are the largest or the smallest in some trial of the block."""
        return np.union1d(self.amax[s], self.amin[s])

    def settle(self) -> None:
        """Drop the draws of a range's cells that were the largest or smallest so far in some
        trial but not at the end of it (a later group overtook them): no look asks for them."""
        for s in self.records:
            wanted = set(self.extreme_cells(s).tolist()) | set(self.watch[s].tolist())
            for j in [j for j in self.kept[s] if j not in wanted]:
                self.room += self.kept[s].pop(j).nbytes

    def take_part(self, name: str, values: dict) -> None:
        for s, (v, _) in values.items():
            np.maximum(self.pmax[name][s], v.max(axis=1), out=self.pmax[name][s])
            np.minimum(self.pmin[name][s], v.min(axis=1), out=self.pmin[name][s])


def _watch(intervals: dict, sizes: dict[str, int]) -> dict[str, np.ndarray]:
    """Per set, the cells whose draws every block keeps: the largest and smallest estimates of
    a range (usually every cell its pairs need). A maximum's bounds are read off its cells'
    tails (:mod:`.tails`), and its count off the first block's first draws."""
    out = {s: [] for s in sizes}
    for spec in intervals.values():
        if not isinstance(spec, Span):
            continue
        order = np.argsort(-np.asarray(spec.estimates, float), kind="stable")
        out[spec.cells] += list(order[:WATCH]) + list(order[::-1][:WATCH])
    return {s: np.unique(np.asarray(v, int)) for s, v in out.items()}


def simulate(
    draws: Draws,
    positions: np.ndarray,
    n: np.ndarray,
    cells: Callable[[np.ndarray, int], dict],
    sizes: dict[str, int],
    intervals: dict[str, Maximum | Span],
    statistic: Callable[[str, dict, dict, dict], np.ndarray],
    extras: Callable[[int, int], dict] | None = None,
    trials: int | None = None,
    level: float = P95,
    u_of: Callable[[str, float, dict], float] | None = None,
    digits: int = DIGITS,
    block: int = BLOCK,
    max_blocks: int = MAX_BLOCKS,
) -> Outcome:
    """Run a metric's Monte Carlo (module notes).

    ``positions`` (cells, d), ``n`` (cells,): where relative terms scale from, readings per
    cell (:meth:`.draws.Draws.pieces`); ``cells(error, group)``: ``{set: (values (m, k),
    cell indices (k,))}`` of a group's error (m, G, d), which it may overwrite when it is
    writeable (nothing reads it after; a single input's is not); ``sizes``: each set's number of
    cells; ``statistic(name, tmax, tmin, extras)``: the per-trial statistic of interval
    ``name`` from each set's per-trial extremes; ``extras(block, m)``: per-trial additions
    (``{name: (m,)}``). ``trials``: a fixed M; None: adaptive (JCGM 101 §7.9), stopping when
    ``u_of(name, U, parts)`` — the standard uncertainty from the mean of the blocks' U and
    the parts so far — gives a tolerance every interval's ends and U have reached;
    ``block``, ``max_blocks``: the trials of a block and the cap (tests make them small).
    """
    inputs = ["sample", *(t.name for t in draws.terms)]
    adds = {(sp.cells, sp.add) for sp in intervals.values() if isinstance(sp, Maximum) and sp.add}
    fixed = block_sizes(trials, block) if trials is not None else None
    maxima = {name: sp for name, sp in intervals.items() if isinstance(sp, Maximum)}
    spans = frozenset(sp.cells for sp in intervals.values() if isinstance(sp, Span))
    run = Looks(
        draws,
        positions,
        n,
        cells,
        level,
        {s: np.zeros(k, int) for s, k in sizes.items()},
        _watch(intervals, sizes),
    )
    per_block: dict[str, list] = {name: [] for name in intervals}
    status: dict = {}
    found = None
    for b in range(len(fixed) if fixed is not None else max_blocks):
        m = fixed[b] if fixed is not None else block
        kept = sum(8 * blk.m * len(c) for blk in run.blocks for c in blk.kept.values())
        first = {sp.cells for sp in maxima.values()}
        first = (
            COUNT_TRIALS if b == 0 and 8 * COUNT_TRIALS * sum(sizes[c] for c in first) <= FIRST_BYTES else 0
        )
        blk = _Block(m, sizes, inputs, run.watch, KEPT_BYTES - kept, maxima, first, spans)
        blk.extras = extras(b, m) if extras else {}
        for g in range(len(draws.groups)):
            total, pieces = draws.error(b, m, g, positions, n)
            values = cells(total, g)
            if b == 0:
                for s, (_, idx) in values.items():
                    run.where[s][idx] = g
            blk.take(values, adds)
            del total, values
            shape = (m, draws.groups[g].size, draws.d)
            for name, piece in pieces.items() if b == 0 else ():  # the budget: the first block's
                # a common term's is every cell's; a whole piece is summed already and cells
                # may form its values in its memory
                whole = piece.shape == shape and piece.flags.writeable
                blk.take_part(name, cells(piece if whole else np.broadcast_to(piece, shape), g))
        blk.settle()
        run.blocks.append(blk)
        for s in spans:  # the next blocks keep these too: a look over every block reads them
            run.watch[s] = np.union1d(run.watch[s], blk.extreme_cells(s))
        if fixed is not None:
            continue
        for name, found_b in run.intervals(intervals, [b]).items():
            per_block[name].append(found_b[:2])
        if b == 0:
            continue
        parts = _parts(intervals, statistic, run.blocks, inputs)
        mean_u = {name: u_of(name, float(np.mean([(h - lo) / 2 for lo, h in per_block[name]])), parts[name])
                  for name in intervals}  # fmt: skip
        if not all(st["reached"] for st in stable(per_block, mean_u, digits).values()):
            continue
        # stable by the blocks' u: the tolerance is that of u from every trial (§7.9.4 g)
        found = run.intervals(intervals, range(len(run.blocks)))
        status = stable(
            per_block, {n: u_of(n, (f[1] - f[0]) / 2, parts[n]) for n, f in found.items()}, digits
        )
        if all(st["reached"] for st in status.values()):
            break
        found = None
    if found is None:
        found = run.intervals(intervals, range(len(run.blocks)))
        if fixed is None:
            parts = _parts(intervals, statistic, run.blocks, inputs)
            status = stable(
                per_block, {n: u_of(n, (f[1] - f[0]) / 2, parts[n]) for n, f in found.items()}, digits
            )
    tmax = {s: np.concatenate([blk.tmax[s] for blk in run.blocks]) for s in sizes}
    tmin = {s: np.concatenate([blk.tmin[s] for blk in run.blocks]) for s in sizes}
    ext = {k: np.concatenate([blk.extras[k] for blk in run.blocks]) for k in run.blocks[0].extras}
    stats = {name: statistic(name, tmax, tmin, ext) for name in intervals}
    record = {
        "trials": sum(blk.m for blk in run.blocks),
        "blocks": len(run.blocks),
        "block": block if fixed is None else None,
        "adaptive": fixed is None,
    }
    if fixed is None:
        record.update(digits=digits, status=status)
    return Outcome(found, stats, _parts(intervals, statistic, run.blocks, inputs), ext, record)


def _parts(intervals, statistic, blocks, inputs) -> dict[str, dict[str, np.ndarray]]:
    """Each interval's statistic with one input alone, over the first block's trials (the
    budget's robust standard deviations and the Welch–Satterthwaite dof: 10⁴ trials give
    them to about 1 %)."""
    blocks = blocks[:1]
    ext = {k: blocks[0].extras[k] for k in blocks[0].extras}
    out: dict[str, dict[str, np.ndarray]] = {name: {} for name in intervals}
    for i in inputs:
        pmax = {s: np.concatenate([blk.pmax[i][s] for blk in blocks]) for s in blocks[0].pmax[i]}
        pmin = {s: np.concatenate([blk.pmin[i][s] for blk in blocks]) for s in blocks[0].pmin[i]}
        for name in intervals:
            out[name][i] = statistic(name, pmax, pmin, ext)
    return out
