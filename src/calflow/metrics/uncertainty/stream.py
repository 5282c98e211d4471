"""The Monte Carlo of maxima and ranges over many cells, streamed block by block and group by
group (:mod:`.draws`), until JCGM 101 §7.9's stopping rule holds (:mod:`.adaptive`).

A metric hands :func:`simulate` its cells (a function turning one group's error into the
values of its cell sets: ISO 9283's |mean deviation| per target, ISO 230-2's cell means,
mid-points and reversals), the intervals it reports (:class:`Maximum`, :class:`Span`) and
their per-trial statistics. Per block, memory holds one group of cells; what is kept of every
trial is a handful of numbers (each set's largest and smallest cell and where they are, the
metric's statistics, each term's alone), and of every cell its extremes and how often it is
the largest or smallest. An interval's rule (:func:`.montecarlo.maximum_interval`,
:func:`.montecarlo.largest_bounds`, :func:`.montecarlo.candidates`) then needs the draws of the few cells that can
set its bounds: those are drawn again, a few at a time, from their blocks' seeds. The numbers
are those of the whole (M, cells) array; memory grows with the cells only through those
per-cell counters (a few dozen bytes a cell) and the candidates' columns (8 bytes a trial).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from calflow.metrics.uncertainty.adaptive import DIGITS, MAX_BLOCKS, stable
from calflow.metrics.uncertainty.budget import P95
from calflow.metrics.uncertainty.draws import BLOCK, Draws, block_sizes
from calflow.metrics.uncertainty.montecarlo import candidates, largest_bounds

WATCH = 64  #: cells of a set whose draws every block keeps: those with the largest (and smallest) estimates
STORE_BYTES = 128e6  #: draws drawn again and kept for the next look at the intervals (bytes)
KEPT_BYTES = 320e6  #: the watched cells' draws the blocks keep, all blocks together (bytes)
WATCH_MORE = 512  #: the first block's candidates of a maximum whose draws the blocks after it keep too


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
        self, m: int, sizes: dict[str, int], inputs: list[str], watch: dict[str, np.ndarray], room: float
    ):
        self.m, self.watch, self.room = m, watch, room  # room: bytes the block may keep
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
            self.cmax[s][idx] = v.max(axis=0)
            self.cmin[s][idx] = v.min(axis=0)
            for cells, add in adds:
                if cells == s:
                    self.add_cmax.setdefault((s, add), np.full(self.cmax[s].size, -np.inf))
                    self.add_cmax[(s, add)][idx] = (v + self.extras[add][:, None]).max(axis=0)
            for q in np.flatnonzero(np.isin(idx, self.watch[s])):
                if self.room < 8 * self.m:
                    break
                self.kept[s][int(idx[q])] = np.ascontiguousarray(v[:, q])
                self.room -= 8 * self.m

    def take_part(self, name: str, values: dict) -> None:
        for s, (v, _) in values.items():
            np.maximum(self.pmax[name][s], v.max(axis=1), out=self.pmax[name][s])
            np.minimum(self.pmin[name][s], v.min(axis=1), out=self.pmin[name][s])


def _watch(intervals: dict, sizes: dict[str, int]) -> dict[str, np.ndarray]:
    """Per set, the cells whose draws every block keeps: the largest estimates of a maximum,
    the largest and smallest of a range (usually every cell an interval needs)."""
    out = {s: [] for s in sizes}
    for spec in intervals.values():
        order = np.argsort(-np.asarray(spec.estimates, float), kind="stable")
        out[spec.cells] += list(order[:WATCH])
        if isinstance(spec, Span):
            out[spec.cells] += list(order[::-1][:WATCH])
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
    cell indices (k,))}`` of a group's error (m, G, d); ``sizes``: each set's number of
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
    run = _Run(
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
        blk = _Block(m, sizes, inputs, run.watch, KEPT_BYTES - kept)
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
                blk.take_part(name, cells(np.broadcast_to(piece, shape), g))  # a common term: every cell's
        run.blocks.append(blk)
        if fixed is not None:
            continue
        for name, found_b in run.intervals(intervals, [b], grow=b == 0).items():
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


def _kept(blocks, s: str, j: int) -> bool:
    """Whether every one of ``blocks`` kept the draws of cell ``j`` of set ``s``."""
    return all(int(j) in blk.kept[s] for blk in blocks)


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


@dataclass
class _Run:
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

    def intervals(self, specs: dict, block_ids, grow: bool = False) -> dict[str, tuple[float, float, float]]:
        """``{name: (low, high, T_eff)}`` of every interval from the trials of ``block_ids``.

        A maximum's bounds are the largest of its cells' (:func:`largest_bounds`): from the
        cell of the largest estimate, then over the cells whose largest draw is not below both
        bounds found so far (no other can change them) — the same bounds as from every cell.
        Cells whose draws were not kept are drawn again group by group, each group once for
        every interval. ``grow``: keep the candidates' draws in the blocks still to come."""
        block_ids = list(block_ids)
        chosen = [self.blocks[b] for b in block_ids]
        trials = sum(blk.m for blk in chosen)
        state, out = {}, {}
        for name, spec in specs.items():
            s, y = spec.cells, np.asarray(spec.estimates, float)
            add = np.concatenate([blk.extras[spec.add] for blk in chosen]) if spec.add else None
            counts_max = sum(np.bincount(blk.amax[s], minlength=y.size) for blk in chosen)
            if isinstance(spec, Span):
                state[name] = ("span", spec, y, add, counts_max)
                continue
            upper = np.max(
                [blk.add_cmax[(s, spec.add)] if spec.add else blk.cmax[s] for blk in chosen], axis=0
            )
            t_eff = float(candidates(y, self._cell(spec, add, chosen, block_ids), upper, trials, self.level))
            first = int(np.argmax(y))
            drawn = (
                {}
                if _kept(chosen, s, first)
                else self._redraw(int(self.where[s][first]), {s: {first}}, block_ids)[s]
            )
            lo, hi = self._bounds(spec, y, add, upper, trials, t_eff, block_ids, np.array([first]), drawn)
            cands = np.array([j for j in np.argsort(-upper, kind="stable") if j != first], int)
            cands = cands[upper[cands] >= min(lo, hi)]
            kept = np.array([j for j in cands if _kept(chosen, s, j)], int)
            if kept.size:
                a, b = self._bounds(spec, y, add, upper, trials, t_eff, block_ids, kept, {})
                lo, hi = max(lo, a), max(hi, b)
            if grow and cands.size:
                self.grow(s, cands)
            state[name] = ("max", spec, y, add, upper, t_eff, [lo, hi], cands[~np.isin(cands, kept)])
        # the cells no block kept, group by group (the groups of the largest draws first)
        wanted: dict[int, dict[str, set]] = {}
        for st in state.values():
            if st[0] == "max":
                for j in st[-1]:
                    wanted.setdefault(int(self.where[st[1].cells][j]), {}).setdefault(st[1].cells, set()).add(
                        int(j)
                    )
            else:
                spec, counts_max = st[1], st[4]
                counts_min = sum(np.bincount(blk.amin[spec.cells], minlength=st[2].size) for blk in chosen)
                need = np.union1d(np.flatnonzero(counts_max), np.flatnonzero(counts_min))
                for j in need:
                    if not _kept(chosen, spec.cells, int(j)):
                        wanted.setdefault(int(self.where[spec.cells][j]), {}).setdefault(
                            spec.cells, set()
                        ).add(int(j))
        drawn: dict[str, dict[int, np.ndarray]] = {}
        for g, sets in wanted.items():
            cols = self._redraw(g, sets, block_ids)
            for st in state.values():
                if st[0] != "max" or st[1].cells not in cols:
                    continue
                spec, y, add, upper, t_eff, bounds, rest = st[1:]
                mine = cols[spec.cells]
                here = np.array([j for j in rest if int(j) in mine and upper[j] >= min(bounds)], int)
                if here.size:
                    a, b = self._bounds(spec, y, add, upper, trials, t_eff, block_ids, here, mine)
                    bounds[0], bounds[1] = max(bounds[0], a), max(bounds[1], b)
            for s_name, c in cols.items():  # a range's candidates are needed all at once
                if any(st[0] == "span" and st[1].cells == s_name for st in state.values()):
                    drawn.setdefault(s_name, {}).update(c)
        for name, st in state.items():
            if st[0] == "max":
                out[name] = (st[6][0], st[6][1], st[5])
            else:
                out[name] = self._span(
                    st[1], st[2], st[3], chosen, block_ids, trials, drawn.get(st[1].cells, {})
                )
        return out

    def grow(self, s: str, cells) -> None:
        """Keep the draws of ``cells`` of set ``s`` in the blocks to come (at most
        :data:`WATCH_MORE` more, those of the largest draws)."""
        current = self.watch[s]
        extra = np.asarray([j for j in cells if j not in set(current.tolist())], int)[:WATCH_MORE]
        self.watch = {**self.watch, s: np.union1d(current, extra)}

    def _redraw(self, g: int, sets: dict[str, set], block_ids) -> dict[str, dict[int, np.ndarray]]:
        """The draws of some cells of group ``g`` over ``block_ids``: those a block kept or an
        earlier look stored as they are, the others drawn again (the group once a block) and
        stored while :data:`STORE_BYTES` allows."""
        for b in block_ids:
            missing = {s: [j for j in cells if (s, j, b) not in self.store and j not in self.blocks[b].kept[s]]
                       for s, cells in sets.items()}  # fmt: skip
            if not any(missing.values()):
                continue
            total, _ = self.draws.error(b, self.blocks[b].m, g, self.positions, self.n)
            values = self.cells(total, g)
            for s, cells in sets.items():
                v, idx = values[s]
                for q in np.flatnonzero(np.isin(idx, list(cells))):
                    column = np.ascontiguousarray(v[:, q])
                    self.store[(s, int(idx[q]), b)] = column
                    self.stored += column.nbytes
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

    def _cell(self, spec, add, chosen, block_ids) -> Callable[[int], np.ndarray]:
        """Cell j's draws over ``block_ids`` (plus the per-trial addition): kept, or drawn again."""

        def column(j: int) -> np.ndarray:
            s = spec.cells
            if _kept(chosen, s, j):
                c = self._column(s, j, block_ids, {})
            else:
                c = self._redraw(int(self.where[s][j]), {s: {j}}, block_ids)[s][j]
            return c + add if add is not None else c

        return column

    def _column(self, s: str, j: int, block_ids, drawn: dict) -> np.ndarray:
        if j in drawn:
            return drawn[j]
        return np.concatenate([self.blocks[b].kept[s][j] for b in block_ids])

    def _bounds(self, spec, y, add, upper, trials, t_eff, block_ids, cells, drawn):
        def column(q):
            c = self._column(spec.cells, int(cells[q]), block_ids, drawn)
            return c + add if add is not None else c

        return largest_bounds(y[cells], column, upper[cells], trials, self.level, t_eff)

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
            return c + add if add is not None else c

        return (*largest_bounds(e, column, upper, trials, self.level, t_eff), t_eff)
