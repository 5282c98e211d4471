"""The pattern for manufacturing (GDSII, through gdstk) and for the eye (a PNG preview).

GDSII: one cell ``DOT`` (a disc of the dot diameter, a polygon within 1 nm of the circle) and a
top cell ``PATTERN`` that places it with arrays only — the two always-present classes as two
arrays, each x-code column as one array of every other row of cells, each y-code row as two
arrays of every fourth cell — so a 10 cm pattern is a file of kilobytes, not millions of polygons. Units:
1 µm, precision 1 nm; layer 1, datatype 0. The GDS y axis is the pattern's −y, so that a
layout viewer (y up) shows the pattern as the camera sees it at Θ = 0 (rows downwards), like
the preview; the dot of site (r, c) is at (c·p − origin_x, −(r·p − origin_y)).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from calflow.instruments.pattern.pattern import Pattern


def write_gds(pattern: Pattern, path, layer: int = 1, datatype: int = 0) -> Path:
    """Write the pattern as GDSII (atomically) and return the path."""
    import gdstk

    p = pattern.period_um
    ox, oy = pattern.origin_um
    lib = gdstk.Library("CALFLOW_PATTERN", unit=1e-6, precision=1e-9)
    dot = lib.new_cell("DOT")
    dot.add(
        gdstk.ellipse((0, 0), pattern.dot_diameter_um / 2, tolerance=1e-3, layer=layer, datatype=datatype)
    )
    top = lib.new_cell("PATTERN")
    rows, cols = pattern.shape

    def place(r0: int, c0: int, nrows: int, ncols: int, dr: int, dc: int):
        if nrows > 0 and ncols > 0:
            top.add(
                gdstk.Reference(
                    dot,
                    origin=(c0 * p - ox, -(r0 * p - oy)),
                    columns=ncols,
                    rows=nrows,
                    spacing=(dc * p, -dr * p),
                )
            )

    half_r, half_c = rows // 2, cols // 2
    place(0, 0, half_r, half_c, 2, 2)  # sites (even, even)
    place(1, 1, half_r, half_c, 2, 2)  # sites (odd, odd)
    for cell, bit in enumerate(pattern.x_bits):  # x code: sites (2R, 2·cell + 1), bit XOR (R odd)
        first = 0 if bit else 1
        place(2 * first, 2 * cell + 1, (half_r - first + 1) // 2, 1, 4, 2)
    for cell_row, bit in enumerate(
        pattern.y_bits
    ):  # y code: sites (2·cell_row + 1, 2C), bit XOR (C // 2 odd)
        for first in (0, 1) if bit else (2, 3):
            place(2 * cell_row + 1, 2 * first, 1, (half_c - first + 3) // 4, 2, 8)
    from calflow.data.io import atomic_path

    with atomic_path(path) as tmp:
        lib.write_gds(str(tmp))
    return Path(path)


def read_gds_sites(path, pattern: Pattern) -> np.ndarray:
    """The present/missing matrix a GDSII file written by :func:`write_gds` places (for checks)."""
    import gdstk

    lib = gdstk.read_gds(str(path))
    top = next(c for c in lib.cells if c.name == "PATTERN")
    p = pattern.period_um
    ox, oy = pattern.origin_um
    out = np.zeros(pattern.shape, dtype=bool)
    for ref in top.references:
        rep = ref.repetition
        offsets = rep.get_offsets() if rep.size else np.zeros((1, 2))
        pts = np.asarray(offsets) + np.asarray(ref.origin)
        c = np.rint((pts[:, 0] + ox) / p).astype(int)
        r = np.rint((-pts[:, 1] + oy) / p).astype(int)
        out[r, c] = True
    return out


def write_png(pattern: Pattern, path, max_side: int = 4096) -> Path:
    """A preview: one pixel per dot site (white = dot), rows downwards, shrunk by an integer factor
    (a block is white when any of its sites is) when the pattern is wider than ``max_side``."""
    import matplotlib.image

    m = pattern.matrix
    step = max(1, int(np.ceil(max(m.shape) / max_side)))
    if step > 1:
        r, c = (m.shape[0] // step) * step, (m.shape[1] // step) * step
        m = m[:r, :c].reshape(r // step, step, c // step, step).mean(axis=(1, 3))
    img = (np.asarray(m, dtype=float) * 255).astype(np.uint8)
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    matplotlib.image.imsave(tmp, img, cmap="gray", vmin=0, vmax=255, format="png")
    os.replace(tmp, path)
    return path
