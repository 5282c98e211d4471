"""The encoded dot pattern: a periodic grid of dots whose missing dots spell two m-sequences.

Layout (``cell2x2``): dots sit on a square grid of period ``p``; node (r, c) — row r along y,
column c along x — is at pattern coordinates ``(c·p − origin_x, r·p − origin_y)`` µm. The grid
is cut into 2 × 2 cells; in each cell

* the two nodes with r ≡ c (mod 2) always carry a dot (the periodic frame the phase sees);
* node (r even, c odd) carries a dot when ``x_bits[c // 2] XOR ((r // 2) mod 2)`` is 1 — the x
  code, constant along a column of cells but flipped on every other row of cells;
* node (r odd, c even) carries a dot when ``y_bits[r // 2] XOR ((c // 4) mod 2)`` is 1 — the y
  code, flipped on every other pair of columns of cells.

The flips do two things. They move each code's random content off the grid's lobes, so that
the missing dots average out of the phase planes instead of biasing them (by ~0.2 nm without
them). And, being different along x (period 2 cells) and y (period 4 cells), they break the
square grid's quarter-turn symmetry in the layout itself: read a quarter turn off, neither
code class keeps one value along the direction its votes are taken, so no bit of such a
reading is sure. A reading only knows the flips up to where it sits, so the x bits are read
as they are and complemented (the m-sequence's complements are far from its windows), and
the y flips follow from the x place. The half turn is left to the codes: the x and y bits are
the first bits of two m-sequences (primitive feedback polynomials, neither self-reciprocal),
and a view read backwards must disagree with every forward window of both codes in at least
:data:`MIN_DISTANCE` bits together, while two places along one axis, or an x window and a
complemented one, must differ in that many bits on that axis alone. ``window_bits`` bits per
axis (the polynomial's order plus redundancy, more where those distances need it) locate a
view absolutely; :func:`code_distances` checks them on the code. The field of view decoding
needs follows: ``window_bits + 1`` cells per axis (``min_fov_um``).

The pattern file (``save``/``load``) is plain JSON, versioned, documented in docs/instruments.md.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np

from calflow.errors import CalflowError
from calflow.instruments.pattern import codes
from calflow.instruments.pattern.windows import (  # noqa: F401  (part of this module's names)
    MIN_DISTANCE,
    cells_needed,
    choose_windows,
    code_distances,
    distances_ok,
    polynomial_pair,
)

FORMAT = "calflow-pattern"
VERSION = 1
LAYOUT = "cell2x2"


@dataclass(frozen=True, eq=False)
class Pattern:
    """An encoded dot pattern (lengths in µm). ``matrix`` is present (True) / missing, rows = y."""

    period_um: float
    dot_diameter_um: float
    x_polynomial: tuple[int, ...]
    y_polynomial: tuple[int, ...]
    x_bits: np.ndarray = field(repr=False)
    y_bits: np.ndarray = field(repr=False)
    window_bits: tuple[int, int]
    range_um: tuple[float, float]
    origin_um: tuple[float, float]
    layout: str = LAYOUT

    # -- derived -----------------------------------------------------------------------------
    @property
    def x_order(self) -> int:
        return max(self.x_polynomial)

    @property
    def y_order(self) -> int:
        return max(self.y_polynomial)

    @property
    def shape(self) -> tuple[int, int]:
        """(rows, columns) of dot sites."""
        return 2 * len(self.y_bits), 2 * len(self.x_bits)

    @property
    def cell_um(self) -> float:
        return 2.0 * self.period_um

    @property
    def min_fov_um(self) -> tuple[float, float]:
        """Side of the pattern-aligned field of view (x, y) a frame must cover to be decoded."""
        return ((self.window_bits[0] + 1) * self.cell_um, (self.window_bits[1] + 1) * self.cell_um)

    @property
    def size_um(self) -> tuple[float, float]:
        """Extent of the dotted area (x, y)."""
        rows, cols = self.shape
        return ((cols - 1) * self.period_um, (rows - 1) * self.period_um)

    @cached_property
    def matrix(self) -> np.ndarray:
        """Present (True) / missing dots, shape (rows, cols), rows along y."""
        return site_matrix(self.x_bits, self.y_bits)

    def matrix_sha256(self) -> str:
        """SHA-256 of the matrix as rows of '0'/'1' characters joined by newlines."""
        h = hashlib.sha256()
        m = self.matrix
        for i, row in enumerate(m):
            h.update((b"\n" if i else b"") + (row.astype(np.uint8) + ord("0")).tobytes())
        return h.hexdigest()

    def present(self, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """Whether the sites (rows, cols) carry a dot; sites off the pattern carry none."""
        rows = np.asarray(rows)
        cols = np.asarray(cols)
        nr, nc = self.shape
        inside = (rows >= 0) & (rows < nr) & (cols >= 0) & (cols < nc)
        r = np.clip(rows, 0, nr - 1)
        c = np.clip(cols, 0, nc - 1)
        frame = (r % 2) == (c % 2)
        xb = self.x_bits[c // 2].astype(bool) ^ ((r // 2) % 2 == 1)
        yb = self.y_bits[r // 2].astype(bool) ^ ((c // 4) % 2 == 1)
        return inside & np.where(frame, True, np.where(r % 2 == 0, xb, yb))

    # -- construction ------------------------------------------------------------------------
    @classmethod
    def make(
        cls,
        range_um=(9500.0, 4200.0),
        period_um: float = 4.0,
        dot_diameter_um: float = 2.0,
        x_order: int | None = None,
        y_order: int | None = None,
        redundancy_bits: int = 6,
        check: bool = True,
    ) -> Pattern:
        """A pattern whose every frame centre in [0, range_x] × [0, range_y] µm decodes.

        The code orders are the smallest that cover the range (or the given ones, which must);
        ``redundancy_bits`` bits are read beyond the order, more if the code's windows need
        them to stay :data:`MIN_DISTANCE` apart (``check``, which costs ~1 s at 10 cm).
        """
        rx, ry = (float(v) for v in range_um)
        if not (rx > 0 and ry > 0 and math.isfinite(rx) and math.isfinite(ry)):
            raise ValueError(f"range_um: expected two positive lengths in µm, got {range_um!r}")
        if not (period_um > 0 and 0 < dot_diameter_um < period_um):
            raise ValueError(
                f"period_um {period_um}, dot_diameter_um {dot_diameter_um}: expected 0 < diameter < period"
            )
        cell = 2.0 * period_um
        orders = [x_order or 2, y_order or 2]
        while True:
            for i, (span, given) in enumerate(((rx, x_order), (ry, y_order))):
                while (1 << orders[i]) - 1 < cells_needed(
                    span, (orders[i] + redundancy_bits + 1) * cell, cell
                ):
                    if given or orders[i] >= codes.MAX_ORDER:
                        break
                    orders[i] += 1
            window, bits = choose_windows(orders, (rx, ry), cell, redundancy_bits, check)
            short = [
                i
                for i in (0, 1)
                if cells_needed((rx, ry)[i], (window[i] + 1) * cell, cell) > (1 << orders[i]) - 1
            ]
            if not short:
                break
            for i in short:
                axis, given = "xy"[i], (x_order, y_order)[i]
                if given or orders[i] >= codes.MAX_ORDER:
                    cells = cells_needed((rx, ry)[i], (window[i] + 1) * cell, cell)
                    raise ValueError(
                        f"{axis}_order {orders[i]}: an m-sequence of order {orders[i]} has "
                        f"{(1 << orders[i]) - 1} cells of {cell:g} µm, the range {(rx, ry)[i]:g} µm needs {cells}"
                    )
                orders[i] += 1
        polys = polynomial_pair(*orders)
        origin = tuple(math.ceil((w + 1) * cell / 2 / period_um) * period_um for w in window)
        return cls(
            period_um=float(period_um),
            dot_diameter_um=float(dot_diameter_um),
            x_polynomial=polys[0],
            y_polynomial=polys[1],
            x_bits=bits[0],
            y_bits=bits[1],
            window_bits=(window[0], window[1]),
            range_um=(rx, ry),
            origin_um=(float(origin[0]), float(origin[1])),
        )

    # -- the file ----------------------------------------------------------------------------
    def to_dict(self) -> dict:
        return {
            "format": FORMAT,
            "version": VERSION,
            "layout": LAYOUT,
            "units": "um",
            "period_um": self.period_um,
            "dot_diameter_um": self.dot_diameter_um,
            "range_um": list(self.range_um),
            "origin_um": list(self.origin_um),
            "min_fov_um": list(self.min_fov_um),
            "shape": list(self.shape),
            "x_code": _code_dict(self.x_polynomial, self.x_bits, self.window_bits[0]),
            "y_code": _code_dict(self.y_polynomial, self.y_bits, self.window_bits[1]),
            "matrix_sha256": self.matrix_sha256(),
        }

    def save(self, path) -> Path:
        """Write the pattern file (JSON) atomically: a temporary name, then renamed."""
        from calflow.data.io import write_text

        return write_text(json.dumps(self.to_dict(), indent=1) + "\n", path)

    @classmethod
    def load(cls, path) -> Pattern:
        """Read and check a pattern file; a bad one raises one line naming file, field, expectation."""
        path = Path(path)
        try:
            data = json.loads(path.read_text())
        except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
            raise CalflowError(f"{path}: not a calflow pattern file (expected JSON: {exc})") from None
        return cls.from_dict(data, str(path))

    @classmethod
    def from_dict(cls, data, where: str = "pattern") -> Pattern:
        def bad(key, expected, got=None):
            tail = "" if got is None else f", got {got!r}"
            return CalflowError(f"{where}: {key}: expected {expected}{tail}")

        if not isinstance(data, dict):
            raise bad("(top level)", "a JSON object")
        if data.get("format") != FORMAT:
            raise bad("format", repr(FORMAT), data.get("format"))
        if data.get("version") != VERSION:
            raise bad("version", str(VERSION), data.get("version"))
        if data.get("layout", LAYOUT) != LAYOUT:
            raise bad("layout", repr(LAYOUT), data.get("layout"))
        period = _positive(data, "period_um", bad)
        diameter = _positive(data, "dot_diameter_um", bad)
        if diameter >= period:
            raise bad("dot_diameter_um", f"less than period_um {period:g}", diameter)
        rng = _pair(data, "range_um", bad)
        origin = _pair(data, "origin_um", bad, positive=False)
        parts = []
        for axis in ("x", "y"):
            key = f"{axis}_code"
            code = data.get(key)
            if not isinstance(code, dict):
                raise bad(key, "an object with polynomial, bits, window_bits")
            poly = code.get("polynomial")
            if not (
                isinstance(poly, list)
                and poly
                and all(
                    isinstance(e, int) and not isinstance(e, bool) and 0 <= e <= codes.MAX_ORDER for e in poly
                )
            ) or not codes.is_primitive(poly):
                raise bad(
                    f"{key}.polynomial",
                    f"the exponents of a primitive GF(2) polynomial of order 2 to {codes.MAX_ORDER}",
                    poly,
                )
            text = code.get("bits")
            if not (isinstance(text, str) and text and set(text) <= {"0", "1"}):
                raise bad(f"{key}.bits", "a string of 0 and 1")
            bits = np.frombuffer(text.encode(), dtype=np.uint8) - ord("0")
            broken = codes.check_recurrence(bits, poly)
            if broken >= 0:
                raise bad(f"{key}.bits", f"the m-sequence of {poly} (bit {broken} breaks it)")
            window = code.get("window_bits")
            if not (isinstance(window, int) and max(poly) <= window <= len(bits)):
                raise bad(
                    f"{key}.window_bits", f"an integer from the order {max(poly)} to {len(bits)}", window
                )
            if len(bits) > (1 << max(poly)) - 1:
                raise bad(f"{key}.bits", f"at most one period ({(1 << max(poly)) - 1} bits)", len(bits))
            parts.append((tuple(int(e) for e in sorted(poly, reverse=True)), bits, window))
        pattern = cls(
            period_um=period,
            dot_diameter_um=diameter,
            x_polynomial=parts[0][0],
            y_polynomial=parts[1][0],
            x_bits=parts[0][1],
            y_bits=parts[1][1],
            window_bits=(parts[0][2], parts[1][2]),
            range_um=rng,
            origin_um=origin,
        )
        for i, axis in enumerate("xy"):
            need = pattern.origin_um[i] + pattern.range_um[i] + pattern.min_fov_um[i] / 2
            have = pattern.size_um[i]
            if have + 1e-9 < need:
                raise bad(
                    f"{axis}_code.bits",
                    f"a code covering range_um {pattern.range_um[i]:g} µm "
                    f"({math.ceil(need / pattern.cell_um) + 1} cells)",
                    f"{len(parts[i][1])} cells",
                )
        # the keys another program renders from must say what the codes and numbers above give
        derived = pattern.to_dict()
        checks = [(k, data, derived) for k in ("units", "min_fov_um", "shape", "matrix_sha256")]
        checks += [
            (f"{a}_code.{k}", data[f"{a}_code"], derived[f"{a}_code"]) for a in "xy" for k in CODE_KEYS
        ]
        for key, given, want in checks:
            name = key.rsplit(".", 1)[-1]
            if name not in given or not _same(given[name], want[name]):
                what = (
                    "the SHA-256 of the matrix the codes generate"
                    if name == "matrix_sha256"
                    else repr(want[name])
                )
                raise bad(key, f"{what} (from the period, range and codes)", given.get(name, "nothing"))
        return pattern


def read_cell2x2(data, where: str = "pattern") -> Pattern:
    """The layout's ``read`` hook (:mod:`calflow.instruments.pattern.layouts`)."""
    return Pattern.from_dict(data, where)


def site_matrix(x_bits: np.ndarray, y_bits: np.ndarray) -> np.ndarray:
    """The present/missing matrix of the ``cell2x2`` layout, shape (2·len(y_bits), 2·len(x_bits))."""
    rows, cols = 2 * len(y_bits), 2 * len(x_bits)
    r = np.arange(rows)[:, None]
    c = np.arange(cols)[None, :]
    xb = np.asarray(x_bits, bool)[c // 2] ^ ((r // 2) % 2 == 1)
    yb = np.asarray(y_bits, bool)[r // 2] ^ ((c // 4) % 2 == 1)
    return np.where((r % 2) == (c % 2), True, np.where(r % 2 == 0, xb, yb))


def _code_dict(poly, bits, window) -> dict:
    return {
        "polynomial": [int(e) for e in poly],
        "order": int(max(poly)),
        "seed": "1" * int(max(poly)),
        "length": int(len(bits)),
        "window_bits": int(window),
        "bits": (np.asarray(bits, np.uint8) + ord("0")).tobytes().decode(),
    }


def _positive(data, key, bad) -> float:
    v = data.get(key)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not (v > 0 and math.isfinite(v)):
        raise bad(key, "a positive number (µm)", v)
    return float(v)


def _pair(data, key, bad, positive=True) -> tuple[float, float]:
    v = data.get(key)
    ok = (
        isinstance(v, list)
        and len(v) == 2
        and all(not isinstance(e, bool) and isinstance(e, (int, float)) and math.isfinite(e) for e in v)
    )
    if not ok or (positive and min(v) <= 0) or (not positive and min(v) < 0):
        raise bad(key, f"two {'positive' if positive else 'non-negative'} numbers [x, y] (µm)", v)
    return float(v[0]), float(v[1])


CODE_KEYS = ("order", "seed", "length")  # a code's keys that follow from its polynomial and bits


def _same(given, want) -> bool:
    """A value of the file equals the one derived (numbers within rounding, no booleans)."""
    if isinstance(want, list):
        return isinstance(given, list) and len(given) == len(want) and all(map(_same, given, want))
    if isinstance(want, (int, float)) and not isinstance(want, bool):
        return (
            isinstance(given, (int, float))
            and not isinstance(given, bool)
            and (given == want if isinstance(want, int) else math.isclose(given, want, rel_tol=1e-9))
        )
    return given == want
