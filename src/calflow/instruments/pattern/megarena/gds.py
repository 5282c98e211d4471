"""A Megarena target for manufacturing: GDSII through gdstk, the region of interest only.

The sites fall in nine blocks by the classes of their row and column modulo 3; each block is
the product of a set of rows and a set of columns, each set a union of runs of sites 3
periods apart (all of them for classes 0 and 2, runs of consecutive 1 bits for the code class
1). Each pair of runs is one GDS array of the ``DOT`` cell (a square of the dot size, as the
pattern is drawn in the literature), so a file holds as many references as pairs of runs — a
few thousand for a few millimetres, about a million for a whole 12-bit target (11 cm). Units
1 µm, precision 1 nm, layer 1, datatype 0; the GDS y axis is the pattern's −y, the dot of site
(r, c) centred at (c·p, −r·p), as :func:`calflow.instruments.pattern.gds.write_gds` does.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from calflow.instruments.pattern.megarena.pattern import MegarenaPattern


def runs(indices: np.ndarray) -> list[tuple[int, int]]:
    """(first, count) of the runs of ``indices`` (sorted) that are 3 apart."""
    if len(indices) == 0:
        return []
    breaks = np.flatnonzero(np.diff(indices) != 3) + 1
    starts = np.concatenate([[0], breaks])
    ends = np.concatenate([breaks, [len(indices)]])
    return [(int(indices[a]), int(b - a)) for a, b in zip(starts, ends)]


def write_gds(pattern: MegarenaPattern, path, layer: int = 1, datatype: int = 0) -> Path:
    """Write the pattern's region of interest as GDSII (atomically) and return the path."""
    import gdstk

    p = pattern.period_um
    lib = gdstk.Library("CALFLOW_MEGARENA", unit=1e-6, precision=1e-9)
    dot = lib.new_cell("DOT")
    half = pattern.dot_diameter_um / 2
    dot.add(gdstk.rectangle((-half, -half), (half, half), layer=layer, datatype=datatype))
    top = lib.new_cell("PATTERN")
    rows, cols = (np.asarray(r) for r in pattern.region_sites)
    seq = pattern.seq.astype(bool)
    for a in range(3):
        for b in range(3):
            if a == 0 and b == 0:
                continue
            rr = rows[(rows % 3 == a) & seq[rows]]
            cc = cols[(cols % 3 == b) & seq[cols]]
            for r0, nr in runs(rr):
                for c0, nc in runs(cc):
                    top.add(
                        gdstk.Reference(
                            dot, origin=(c0 * p, -r0 * p), columns=nc, rows=nr, spacing=(3 * p, -3 * p)
                        )
                    )
    from calflow.data.io import atomic_path

    with atomic_path(path) as tmp:
        lib.write_gds(str(tmp))
    return Path(path)


def read_gds_sites(path, pattern: MegarenaPattern) -> np.ndarray:
    """The present/missing matrix of the region of interest a file of :func:`write_gds` places."""
    import gdstk

    lib = gdstk.read_gds(str(path))
    top = next(c for c in lib.cells if c.name == "PATTERN")
    rows, cols = pattern.region_sites
    out = np.zeros((len(rows), len(cols)), dtype=bool)
    p = pattern.period_um
    for ref in top.references:
        rep = ref.repetition
        offsets = rep.get_offsets() if rep.size else np.zeros((1, 2))
        pts = np.asarray(offsets) + np.asarray(ref.origin)
        c = np.rint(pts[:, 0] / p).astype(int) - cols.start
        r = np.rint(-pts[:, 1] / p).astype(int) - rows.start
        out[r, c] = True
    return out
