"""The Megarena pattern (André et al., IEEE/ASME T-Mech 25, 2020): one binary m-sequence keeps
or leaves out whole rows and columns of a square dot grid.

Layout. A sequence ``s`` of ``3 · (2^d − 1 + d − 1)`` entries (``d`` the code depth, 4 to 12):
entry ``3j + 1`` is bit ``j`` of the code, every other entry is 1. Site (row r, column c) — row
along y, column along x — sits at pattern coordinates ``(c·p, r·p)`` µm (``p`` the period) and
carries a dot when ``s[r] = s[c] = 1`` and not both ``r`` and ``c`` are multiples of 3. The
holes at (3i, 3j) tell the three rows (and columns) of a code period apart, and which way the
sequence runs; the code rows (3j + 1) spell the code, any ``d`` consecutive bits of which occur
once: a view of ``d`` code rows and ``d`` code columns is absolute.

The code. Bits ``j ≥ d − 1`` follow the linear recurrence of a primitive feedback polynomial per
depth (Eq. (1) of the paper; the taps in :data:`TAPS`), started from ``d`` ones; the first
``d − 1`` and the last code entries are 1. These are the sequences the Vernier library
generates, so a pattern file it wrote (``{"MegarenaPattern": {"period", "codeDepth", …}}``)
describes the same target here.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from calflow.errors import CalflowError

FORMAT = "calflow-pattern"
VERSION = 1
LAYOUT = "megarena"
FOREIGN_KEY = "MegarenaPattern"  # the top-level key of a Vernier library pattern file
DEPTHS = range(4, 13)
# new bit b[n] = XOR of b[n − 1 − k] for k in TAPS[d]: primitive trinomials and pentanomials
TAPS = {
    4: (0, 3),
    5: (1, 4),
    6: (0, 5),
    7: (2, 6),
    8: (0, 1, 6, 7),
    9: (3, 8),
    10: (6, 9),
    11: (1, 10),
    12: (0, 1, 7, 11),
}


def code_bits(depth: int) -> np.ndarray:
    """The ``2^d − 1 + d − 1`` code bits of depth ``d`` (uint8): ``d − 1`` ones, the m-sequence
    from the all-ones state (one period less its last bit), and a closing 1."""
    if depth not in TAPS:
        raise ValueError(f"code depth: expected an integer from 4 to 12, got {depth!r}")
    n = (1 << depth) - 1
    taps = TAPS[depth]
    bits = np.ones(n + depth - 1, dtype=np.uint8)
    history = [1] * depth  # the all-ones state; its newest bit is bit 0 of the code
    for j in range(1, n - 1):
        new = 0
        for k in taps:
            new ^= history[-1 - k]
        history.append(new)
        bits[depth - 1 + j] = new
    return bits


def sequence(depth: int) -> np.ndarray:
    """The row/column sequence ``s`` (uint8, length 3·(2^d + d − 2)): code bit j at 3j + 1."""
    bits = code_bits(depth)
    s = np.ones(3 * len(bits), dtype=np.uint8)
    s[1::3] = bits
    return s


@dataclass(frozen=True, eq=False)
class MegarenaPattern:
    """A Megarena target: period (µm), code depth, region of interest (x, y, width, height µm)."""

    period_um: float
    depth: int
    region_um: tuple[float, float, float, float] | None = None
    dot_diameter_um: float | None = None
    layout: str = LAYOUT
    origin_um: tuple[float, float] = (0.0, 0.0)  # site (0, 0) is at (−origin_x, −origin_y)

    def __post_init__(self):
        if not (
            isinstance(self.period_um, (int, float)) and self.period_um > 0 and math.isfinite(self.period_um)
        ):
            raise ValueError(f"period_um: expected a positive number (µm), got {self.period_um!r}")
        if isinstance(self.depth, bool) or self.depth not in TAPS:
            raise ValueError(f"code depth: expected an integer from 4 to 12, got {self.depth!r}")
        if self.dot_diameter_um is None:
            object.__setattr__(self, "dot_diameter_um", 0.5 * self.period_um)
        if self.region_um is None:
            side = (self.n_sites - 0.5) * self.period_um
            object.__setattr__(self, "region_um", (0.0, 0.0, side, side))

    @cached_property
    def seq(self) -> np.ndarray:
        return sequence(self.depth)

    @cached_property
    def bits(self) -> np.ndarray:
        return self.seq[1::3].copy()

    @property
    def n_sites(self) -> int:
        return 3 * ((1 << self.depth) + self.depth - 2)

    @property
    def shape(self) -> tuple[int, int]:
        return self.n_sites, self.n_sites

    @property
    def size_um(self) -> tuple[float, float]:
        return (self.n_sites - 1) * self.period_um, (self.n_sites - 1) * self.period_um

    @property
    def min_fov_um(self) -> tuple[float, float]:
        """Side of the field of view that sees ``d + 3`` code rows and columns wherever it sits:
        ``d`` place a reading, 3 more keep the next place 3 bits away (the decoder's margin)."""
        side = 3 * (self.depth + 4) * self.period_um
        return side, side

    def present(self, rows, cols) -> np.ndarray:
        """Whether the sites (rows, cols) carry a dot (off the pattern: none)."""
        rows = np.asarray(rows)
        cols = np.asarray(cols)
        n = self.n_sites
        inside = (rows >= 0) & (rows < n) & (cols >= 0) & (cols < n)
        r = np.clip(rows, 0, n - 1)
        c = np.clip(cols, 0, n - 1)
        s = self.seq.astype(bool)
        return inside & s[r] & s[c] & ~((r % 3 == 0) & (c % 3 == 0))

    @property
    def range_um(self) -> tuple[float, float]:
        """(x, y): every frame centre in [0, x] × [0, y] decodes — the region of interest less
        half a field of view on each side, in pattern coordinates; (0, 0) when the region's
        decodable part does not reach the origin (the library's files: origin at site (0, 0))."""
        x, y, w, h = self.region_um
        half = self.min_fov_um[0] / 2
        lo = (x + half - self.origin_um[0], y + half - self.origin_um[1])
        hi = (x + w - half - self.origin_um[0], y + h - half - self.origin_um[1])
        if lo[0] > 1e-9 or lo[1] > 1e-9 or hi[0] <= 0 or hi[1] <= 0:
            return 0.0, 0.0
        return hi

    @property
    def region_sites(self) -> tuple[range, range]:
        """The rows and columns of the sites in the region of interest."""
        x, y, w, h = self.region_um
        p, n = self.period_um, self.n_sites

        def span(lo, size):
            first = max(0, math.ceil(lo / p - 1e-9))
            return range(first, min(n, math.floor((lo + size) / p + 1e-9) + 1))

        return span(y, h), span(x, w)

    @property
    def matrix(self) -> np.ndarray:
        """Present (True) / missing dots of the region of interest, rows along y."""
        rows, cols = self.region_sites
        return self.present(np.asarray(rows)[:, None], np.asarray(cols)[None, :])

    # -- the file ----------------------------------------------------------------------------
    def to_dict(self) -> dict:
        return {
            "format": FORMAT,
            "version": VERSION,
            "layout": LAYOUT,
            "units": "um",
            "period_um": self.period_um,
            "code_depth": self.depth,
            "dot_diameter_um": self.dot_diameter_um,
            "region_um": list(self.region_um),
            "origin_um": list(self.origin_um),
            "min_fov_um": list(self.min_fov_um),
            "shape": list(self.shape),
            "code_bits": (self.bits + ord("0")).tobytes().decode(),
        }

    def to_library_dict(self) -> dict:
        """The same target as the Vernier library writes it (``MegarenaPattern``); the library
        has no origin: its coordinates are calflow's plus ``origin_um``."""
        return {
            FOREIGN_KEY: {
                "description": f"{self.depth}-bit megarena pattern (calflow)",
                "unit": "µm",
                "codeDepth": self.depth,
                "period": float(self.period_um),
                "regionOfInterest": [float(v) for v in self.region_um],
            }
        }

    def save(self, path) -> Path:
        """Write the pattern file (JSON) atomically: a temporary name, then renamed."""
        from calflow.data.io import write_text

        return write_text(json.dumps(self.to_dict(), indent=1) + "\n", path)

    @classmethod
    def from_dict(cls, data, where: str = "pattern") -> MegarenaPattern:
        """calflow's file (``layout: megarena``) or the library's (``{"MegarenaPattern": …}``);
        anything else raises one line naming ``where``, the key and what was expected."""

        def bad(key, expected, got=None):
            tail = "" if got is None else f", got {got!r}"
            return CalflowError(f"{where}: {key}: expected {expected}{tail}")

        if not isinstance(data, dict):
            raise bad("(top level)", "a JSON object")
        if FOREIGN_KEY in data:
            return _from_library(data[FOREIGN_KEY], bad)
        if data.get("format") != FORMAT:
            raise bad("format", repr(FORMAT), data.get("format"))
        if data.get("version") != VERSION:
            raise bad("version", str(VERSION), data.get("version"))
        if data.get("layout") != LAYOUT:
            raise bad("layout", repr(LAYOUT), data.get("layout"))
        period = _number(data, "period_um", bad)
        depth = data.get("code_depth")
        if isinstance(depth, bool) or depth not in TAPS:
            raise bad("code_depth", "an integer from 4 to 12", depth)
        diameter = _number(data, "dot_diameter_um", bad)
        if diameter >= period:
            raise bad("dot_diameter_um", f"less than period_um {period:g}", diameter)
        region = _region(data, "region_um", bad)
        origin = data.get("origin_um", [0.0, 0.0])
        if not (
            isinstance(origin, list)
            and len(origin) == 2
            and all(
                not isinstance(e, bool) and isinstance(e, (int, float)) and 0 <= e < math.inf for e in origin
            )
        ):
            raise bad("origin_um", "two non-negative numbers [x, y] (µm)", origin)
        pattern = cls(
            period_um=period,
            depth=int(depth),
            region_um=region,
            dot_diameter_um=diameter,
            origin_um=(float(origin[0]), float(origin[1])),
        )
        derived = pattern.to_dict()
        for key in ("units", "min_fov_um", "shape", "code_bits"):
            if key not in data or data[key] != derived[key] and not _close(data[key], derived[key]):
                want = "the code of this depth" if key == "code_bits" else repr(derived[key])
                raise bad(key, f"{want} (from the period and code depth)", data.get(key, "nothing"))
        return pattern


def _from_library(body, bad) -> MegarenaPattern:
    key = FOREIGN_KEY
    if not isinstance(body, dict):
        raise bad(key, "an object with period and codeDepth")
    period = _number(body, "period", lambda k, e, g=None: bad(f"{key}.{k}", e, g))
    if "bitSequence" in body:
        raise bad(
            f"{key}.bitSequence",
            "no explicit bit sequence (calflow reads Megarena targets by codeDepth)",
            "a list",
        )
    depth = body.get("codeDepth", body.get("codeSize"))
    if isinstance(depth, bool) or depth not in TAPS:
        raise bad(f"{key}.codeDepth", "an integer from 4 to 12", depth)
    region = None
    if "regionOfInterest" in body:
        region = _region(body, "regionOfInterest", lambda k, e, g=None: bad(f"{key}.{k}", e, g))
    diameter = None
    if "dotSize" in body:
        diameter = _number(body, "dotSize", lambda k, e, g=None: bad(f"{key}.{k}", e, g))
        if diameter >= period:
            raise bad(f"{key}.dotSize", f"less than period {period:g}", diameter)
    if body.get("unit", "µm") not in ("µm", "um"):
        raise bad(f"{key}.unit", "'µm'", body.get("unit"))
    return MegarenaPattern(period_um=period, depth=int(depth), region_um=region, dot_diameter_um=diameter)


def _number(data, key, bad) -> float:
    v = data.get(key)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not (v > 0 and math.isfinite(v)):
        raise bad(key, "a positive number (µm)", v)
    return float(v)


def _region(data, key, bad) -> tuple[float, float, float, float]:
    v = data.get(key)
    ok = (
        isinstance(v, list)
        and len(v) == 4
        and all(not isinstance(e, bool) and isinstance(e, (int, float)) and math.isfinite(e) for e in v)
        and v[2] > 0
        and v[3] > 0
    )
    if not ok:
        raise bad(key, "four numbers [x, y, width, height] (µm), width and height positive", v)
    return tuple(float(e) for e in v)


def _close(a, b) -> bool:
    if isinstance(b, list):
        return isinstance(a, list) and len(a) == len(b) and all(map(_close, a, b))
    if isinstance(b, (int, float)) and not isinstance(b, bool):
        return isinstance(a, (int, float)) and not isinstance(a, bool) and math.isclose(a, b, rel_tol=1e-9)
    return a == b


def read_megarena(data, where: str = "pattern") -> MegarenaPattern:
    """The layout's ``read`` hook (:mod:`calflow.instruments.pattern.layouts`)."""
    return MegarenaPattern.from_dict(data, where)
