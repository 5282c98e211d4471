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
    scores = []
    for a0 in range(3):
        for b0 in range(3):
            for ds in (1, -1):
                a2 = (a0 + (2 if ds > 0 else 1)) % 3
                for dt in (1, -1):
                    b2 = (b0 + (2 if dt > 0 else 1)) % 3
                    # the hole (b0, a0) must be empty; the three other pairs of the two
                    # always-full classes must carry dots
                    full = [(t, s) for t in (b0, b2) for s in (a0, a2) if (t, s) != (b0, a0)]
                    sure = int(seen[b0, a0] + sum(seen[c] for c in full))
                    if sure == 0:
                        continue
                    bad = int(dot[b0, a0] + sum(empty[c] for c in full))
                    scores.append((bad / sure, (a0, ds, b0, dt)))
    if not scores:
        return None
    scores.sort(key=lambda s: s[0])
    best = scores[0]
    if best[0] > 0.2:
        return None
    return best[1], scores[1][0] - best[0], best[0]
