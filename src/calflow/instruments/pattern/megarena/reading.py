"""Reading a Megarena view: which rows and columns are the holes' and the code's, and the
bits decided by overwhelming majorities."""

from __future__ import annotations

import numpy as np

# a bit is read "strongly" from this many sites at least, agreeing this well (a wrong majority
# of 8 needs 4 misread sites; misreads are ~1 % on a decodable frame)
STRONG_VOTES = 8
STRONG_AGREEMENT = 0.95


def strong_reading(cells: np.ndarray, present: np.ndarray):
    """A reading (first cell, bits, sure) keeping only the bits :data:`STRONG_VOTES` sites or
    more decided with :data:`STRONG_AGREEMENT` agreement."""
    if len(cells) == 0:
        return 0, np.zeros(0, np.int8), np.zeros(0, bool)
    c0 = int(cells.min())
    n = np.bincount(cells - c0)
    ones = np.bincount(cells - c0, weights=present.astype(float), minlength=len(n))
    frac = np.where(n > 0, ones / np.maximum(n, 1), 0.5)
    sure = (n >= STRONG_VOTES) & (np.maximum(frac, 1 - frac) >= STRONG_AGREEMENT)
    return c0, (frac > 0.5).astype(np.int8), sure


def classes(present, known, S, T):
    """Step 3 of :mod:`.decode`: ((a0, ds, b0, dt), margin, contradicted) — the holes' class of each axis and its
    direction (+1: site index grows with S or T), the margin to the next arrangement and the
    fraction of sure sites contradicted — or None when no site is sure."""
    # every arrangement's counts are sums over the nine residue classes (S mod 3, T mod 3) of
    # the sites known to carry a dot and known to be empty
    rows = (T % 3)[None, :] == np.arange(3)[:, None]  # (3, len(T)): row T is of class t
    cols = (S % 3)[:, None] == np.arange(3)[None, :]  # (len(S), 3)
    seen = rows.astype(float) @ known.astype(float) @ cols  # [t class, s class]
    dot = rows.astype(float) @ (known & present).astype(float) @ cols
    empty = seen - dot
    hole, full = _ARRANGEMENTS[1], _ARRANGEMENTS[2]  # (36, 2) and (36, 3, 2) [t class, s class]
    # counts of whole sites (exact in floating point): the hole's and the three full pairs'
    sure = seen[hole[:, 0], hole[:, 1]] + seen[full[..., 0], full[..., 1]].sum(axis=1)
    bad = dot[hole[:, 0], hole[:, 1]] + empty[full[..., 0], full[..., 1]].sum(axis=1)
    keep = np.flatnonzero(sure > 0)
    if len(keep) == 0:
        return None
    score = bad[keep].astype(np.int64) / sure[keep].astype(np.int64)
    order = np.argsort(score, kind="stable")  # ties: the arrangements' order below
    best, second = score[order[:2]]
    if best > 0.2:
        return None
    return tuple(int(v) for v in _ARRANGEMENTS[0][keep[order[0]]]), float(second - best), float(best)


def _arrangements():
    """The 36 arrangements (a0, ds, b0, dt) in the order they are scored, the hole's class pair
    (b0, a0) of each and the three pairs of the two always-full classes that must carry dots."""
    which, hole, full = [], [], []
    for a0 in range(3):
        for b0 in range(3):
            for ds in (1, -1):
                a2 = (a0 + (2 if ds > 0 else 1)) % 3
                for dt in (1, -1):
                    b2 = (b0 + (2 if dt > 0 else 1)) % 3
                    which.append((a0, ds, b0, dt))
                    hole.append((b0, a0))
                    full.append([(t, s) for t in (b0, b2) for s in (a0, a2) if (t, s) != (b0, a0)])
    return np.array(which), np.array(hole), np.array(full)


_ARRANGEMENTS = _arrangements()
