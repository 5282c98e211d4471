"""The random inputs of a Monte Carlo U, drawn in blocks of trials and groups of cells.

A metric's Monte Carlo (:mod:`calflow.metrics.uncertainty`) perturbs the mean reading of
every cell (a target, or a target and direction) by the sample term and the declared
terms. For a long sweep the whole (M, cells, d) array of one term is gigabytes (1890
targets × 2 directions at M = 50 000: 1.5 GB a term), so the inputs are never drawn whole:
trials come in blocks (:data:`BLOCK`, JCGM 101 §7.9.2's M = max(100/(1 − p), 10⁴)) and
cells in groups (:data:`GROUP` cells, or the caller's groups), and every (block, input,
group) has its own generator, seeded from the Monte Carlo's seed and those three indices
(``SeedSequence(seed, spawn_key=(block, input, group))``). Any block of any group can then
be drawn again, alone and in any order, to the byte: memory holds one group of one block,
and a cell's draws that an interval needs are drawn again when it needs them. After the first
block the sample term and the terms acting on each cell apart are drawn as one normal from
the sample's generator (:meth:`Draws.error`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

BLOCK = 10_000  #: trials per block: JCGM 101 §7.9.2, M = max(J, 10⁴), J = 100/(1 − p) = 2000 at 95 %
GROUP = 128  #: cells drawn together (the groups of :class:`Draws` when the caller gives none)

# the inputs' indices in the seed's spawn key (the terms follow, one index each)
_SCALE, _EXTRA, _SAMPLE, _TERMS = 0, 1, 2, 3


def block_sizes(trials: int, block: int = BLOCK) -> list[int]:
    """The sizes of the blocks of a fixed number of trials: full blocks, then the rest."""
    full, rest = divmod(int(trials), block)
    return [block] * full + ([rest] if rest else [])


class Draws:
    """Seeded inputs of one Monte Carlo (module notes): the scatter's σ per trial (scaled
    inverse χ², ν s²/χ²_ν, JCGM 101 §6.4.9), the sample term's normals and each declared
    term's, per block of trials and group of cells.

    ``s`` (d,): the pooled per-axis scatter with ``dof`` degrees of freedom; ``cells``,
    ``d``: the cells and axes; ``terms``: the declared terms (``reading`` ones are in the
    scatter already and are dropped); ``groups``: index arrays that partition the cells
    (default: consecutive runs of :data:`GROUP`); ``seed``: the Monte Carlo's seed.
    """

    def __init__(self, s, dof: float, cells: int, d: int, terms: Sequence, seed: int, groups=None):
        self.s, self.dof = np.asarray(s, float).reshape(d), float(dof)
        self.cells, self.d, self.seed = int(cells), int(d), int(seed)
        self.terms = [t for t in terms if t.scope != "reading"]
        if groups is None:
            groups = [np.arange(i, min(i + GROUP, cells)) for i in range(0, cells, GROUP)]
        self.groups = [np.asarray(g, int) for g in groups]
        self._scale: tuple = (None, None)  # (block, m) and its scale, the last asked for
        self.group_of = np.empty(self.cells, int)
        for i, g in enumerate(self.groups):
            self.group_of[g] = i

    def rng(self, block: int, source: int, group: int = 0) -> np.random.Generator:
        """The generator of one input (``source``) of one block and group (module notes)."""
        seq = np.random.SeedSequence(self.seed, spawn_key=(int(block), int(source), int(group)))
        return np.random.Generator(np.random.PCG64(seq))

    def scale(self, block: int, m: int) -> np.ndarray:
        """(m,): σ_trial / s, the scatter's scale in each trial of the block (the last block's
        kept: every group of a block asks for it)."""
        if self._scale[0] != (block, m):
            self._scale = (
                (block, m),
                np.sqrt(self.dof / self.rng(block, _SCALE).chisquare(self.dof, size=m)),
            )
        return self._scale[1]

    def chisquare(self, block: int, m: int, dof: float, which: int = 0) -> np.ndarray:
        """(m,): χ²_dof draws of the block for a metric's own use (``which`` tells them apart)."""
        return self.rng(block, _EXTRA, which).chisquare(dof, size=m)

    def pieces(self, block: int, m: int, group: int, positions: np.ndarray, n: np.ndarray) -> dict:
        """``{"sample": (m, G, d), <term>: (m, G, d) or (m, 1, d)}``: each input's error of the
        means of the group's cells in the block's trials. ``positions`` (cells, d): where
        relative terms scale from; ``n`` (cells,): readings per cell. A common term is one
        error shared by every cell ((m, 1, d) unless it is relative)."""
        idx = self.groups[group]
        sigma = self.s[None, :] * self.scale(block, m)[:, None]  # (m, d)
        z = self.rng(block, _SAMPLE, group).standard_normal((m, idx.size, self.d))
        z *= sigma[:, None, :]
        z /= np.sqrt(n[idx])[None, :, None]
        out = {"sample": z}
        for i, t in enumerate(self.terms):
            if t.scope == "common":
                e = self.rng(block, _TERMS + i).standard_normal((m, 1, self.d))
            else:
                e = self.rng(block, _TERMS + i, group).standard_normal((m, idx.size, self.d))
            e *= t.per_axis(self.d)
            out[t.name] = e * (1e-6 * positions[idx][None]) if t.relative else e
        return out

    def error(self, block: int, m: int, group: int, positions, n) -> tuple[np.ndarray, dict]:
        """(m, G, d): the error of the group's means in the block (every input), and the pieces.

        Block 0 draws every input apart (:meth:`pieces`: the budget is each input's effect
        alone, from the first block). The blocks after it need only the sum: the sample term
        and the terms acting on each cell apart are independent normals given the trial's
        scatter, so their sum is one normal with the sum of their variances, drawn once (half
        the normals of a sweep with a per-target term); common terms are drawn as they are.
        The pieces of those blocks are not given (``{}``)."""
        if block == 0:
            parts = self.pieces(block, m, group, positions, n)
            total = np.zeros((m, self.groups[group].size, self.d))
            for e in parts.values():
                total += e
            return total, parts
        idx = self.groups[group]
        sigma = self.s[None, :] * self.scale(block, m)[:, None]  # (m, d)
        counts = n[idx]
        terms = [(i, t, t.per_axis(self.d)) for i, t in enumerate(self.terms)]
        common = [(i, t, u) for i, t, u in terms if t.scope == "common"]
        own = [(t, u) for _, t, u in terms if t.scope != "common"]
        # every cell of the group alike (the same readings, no relative term of its own): the
        # variance of one cell is every cell's, the same numbers without a (m, G, d) array of them
        alike = counts.size > 0 and bool(np.all(counts == counts[0])) and not any(t.relative for t, _ in own)
        var = (sigma * sigma)[:, None, :] / (counts[:1] if alike else counts)[None, :, None]  # (m, 1 or G, d)
        for t, u in own:
            u = u * (1e-6 * positions[idx]) if t.relative else np.broadcast_to(u, (var.shape[1], self.d))
            var += (u * u)[None]
        total = self.rng(block, _SAMPLE, group).standard_normal((m, idx.size, self.d))
        total *= np.sqrt(var, out=var)
        for i, t, u in common:
            e = self.rng(block, _TERMS + i).standard_normal((m, 1, self.d)) * u
            total += e * (1e-6 * positions[idx][None]) if t.relative else e
        return total, {}
