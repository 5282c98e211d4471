"""HP-code markers (André et al., IJCV 130, 2022): small square dot targets framed by three
QR-like fiducials and numbered, several in one frame.

A marker of ``size`` dots a side (the library's ``4k + 1`` half periods: ``2·size − 1``) is a
square grid of square dots, each half a period wide, on a period ``p``. Three of its corners
carry a fiducial instead of dots: a ring 7 half periods wide, one half period thick, around a
square 3 half periods wide. In the marker's own frame — origin on its centre dot, x along the
line from the corner fiducial ("top") to the one beside it ("right"), y towards the third
("bottom") — the half-period cell of a point (u, v) µm is

    c = ⌊(u + p/4) / (p/2)⌋ + size − 1,   r = ⌊(v + p/4) / (p/2)⌋ + size − 1,   0 ≤ c, r ≤ 2·size − 2,

dots sit on the even cells, the fiducials on cells 0–6 of the three corners (c, r) ∈
{(0, 0), (2·size − 8, 0), (0, 2·size − 8)} + 0–6. The number is written in the first row of
dots (r = 0) between the top and right fiducials: bit n is set when the dot of column
``size − 5 − n`` is missing (``size − 8`` bits, the lowest next to the right fiducial), as
the Vernier library reads it.

The pattern file is calflow's (``layout: hpcode``) or the library's, read as it writes it:
``{"HPCodePattern": {"period": p, "size": dots}}`` or ``{"PeriodicPattern": {"period": p,
"nRows": n, "nCols": n}}`` for the square grid the markers are drawn on.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calflow.errors import CalflowError

LAYOUT = "hpcode"
FORMAT = "calflow-pattern"
VERSION = 1
FOREIGN_KEYS = ("HPCodePattern", "PeriodicPattern")
FIDUCIAL = 7  # half periods across a fiducial
MIN_SIZE = 9  # dots a side: the smallest marker with one number bit


@dataclass(frozen=True, eq=False)
class HPCodePattern:
    """HP-code markers: the period (µm) and the dots a side (odd, at least 9)."""

    period_um: float
    size: int = 17
    layout: str = LAYOUT
    origin_um: tuple[float, float] = (0.0, 0.0)  # calflow's marker origin is its centre dot

    def __post_init__(self):
        if not (
            isinstance(self.period_um, (int, float)) and self.period_um > 0 and math.isfinite(self.period_um)
        ):
            raise ValueError(f"period_um: expected a positive number (µm), got {self.period_um!r}")
        if (
            isinstance(self.size, bool)
            or not isinstance(self.size, int)
            or self.size < MIN_SIZE
            or self.size % 2 == 0
        ):
            raise ValueError(
                f"size: expected an odd number of dots a side, at least {MIN_SIZE}, got {self.size!r}"
            )

    @property
    def dot_diameter_um(self) -> float:
        return 0.5 * self.period_um

    @property
    def half_periods(self) -> int:
        """The library's ``numberHalfPeriods``: 2·size − 1."""
        return 2 * self.size - 1

    @property
    def number_bits(self) -> int:
        return self.size - 8

    @property
    def fiducial_spacing(self) -> int:
        """Periods between the centres of the corner fiducial and each of the two others."""
        return self.size - 4

    @property
    def min_fov_um(self) -> tuple[float, float]:
        side = self.half_periods * self.period_um / 2
        return side, side

    def number_columns(self) -> np.ndarray:
        """Dot columns (0 … size − 1) of the number's bits 0, 1, …: bit n at size − 5 − n."""
        return self.size - 5 - np.arange(self.number_bits)

    def cells(self, u, v, number: int = 0) -> np.ndarray:
        """Whether the marker numbered ``number`` is bright (dot or fiducial) at the points
        (u, v), µm in its own frame (module docstring); False off the marker."""
        self._check_number(number)
        half = self.period_um / 2
        n = self.half_periods
        c = np.floor((np.asarray(u) + half / 2) / half).astype(np.int64) + self.size - 1
        r = np.floor((np.asarray(v) + half / 2) / half).astype(np.int64) + self.size - 1
        inside = (c >= 0) & (c < n) & (r >= 0) & (r < n)
        dots = (c % 2 == 0) & (r % 2 == 0)
        bits = (number >> np.arange(self.number_bits)) & 1
        missing = np.zeros(self.size, bool)
        missing[self.number_columns()] = bits.astype(bool)
        dots &= ~((r == 0) & missing[np.clip(c // 2, 0, self.size - 1)])
        far = n - FIDUCIAL
        out = dots
        for c0, r0 in ((0, 0), (far, 0), (0, far)):
            dc, dr = c - c0, r - r0
            box = (dc >= 0) & (dc < FIDUCIAL) & (dr >= 0) & (dr < FIDUCIAL)
            edge = np.minimum(np.minimum(dc, dr), np.minimum(FIDUCIAL - 1 - dc, FIDUCIAL - 1 - dr))
            out = np.where(box, (edge == 0) | (edge >= 2), out)
        return inside & out

    def _check_number(self, number) -> None:
        if (
            isinstance(number, bool)
            or not isinstance(number, (int, np.integer))
            or not 0 <= number < (1 << self.number_bits)
        ):
            raise ValueError(
                f"number: expected an integer from 0 to {(1 << self.number_bits) - 1} "
                f"({self.number_bits} bits), got {number!r}"
            )

    # -- the file ----------------------------------------------------------------------------
    def to_dict(self) -> dict:
        return {
            "format": FORMAT,
            "version": VERSION,
            "layout": LAYOUT,
            "units": "um",
            "period_um": self.period_um,
            "size": self.size,
            "dot_diameter_um": self.dot_diameter_um,
            "min_fov_um": list(self.min_fov_um),
        }

    def to_library_dict(self) -> dict:
        """The same markers as the Vernier library writes them (``HPCodePattern``)."""
        return {
            "HPCodePattern": {
                "description": f"{self.size} x {self.size} HP-code marker (calflow)",
                "unit": "micrometer",
                "period": float(self.period_um),
                "size": self.size,
            }
        }

    def save(self, path) -> Path:
        """Write the pattern file (JSON) atomically: a temporary name, then renamed."""
        from calflow.data.io import write_text

        return write_text(json.dumps(self.to_dict(), indent=1) + "\n", path)

    @classmethod
    def from_dict(cls, data, where: str = "pattern") -> HPCodePattern:
        """calflow's file (``layout: hpcode``) or the library's (``HPCodePattern`` or a square
        ``PeriodicPattern``); anything else raises one line naming ``where`` and the key."""

        def bad(key, expected, got=None):
            tail = "" if got is None else f", got {got!r}"
            return CalflowError(f"{where}: {key}: expected {expected}{tail}")

        if not isinstance(data, dict):
            raise bad("(top level)", "a JSON object")
        if "HPCodePattern" in data:
            body = data["HPCodePattern"]
            if not isinstance(body, dict):
                raise bad("HPCodePattern", "a JSON object")
            return _make(
                _number(body, "HPCodePattern.period", "period", bad),
                body.get("size"),
                "HPCodePattern.size",
                bad,
            )
        if "PeriodicPattern" in data:
            body = data["PeriodicPattern"]
            if not isinstance(body, dict):
                raise bad("PeriodicPattern", "a JSON object")
            period = _number(body, "PeriodicPattern.period", "period", bad)
            rows, cols = body.get("nRows"), body.get("nCols")
            if rows != cols:
                raise bad(
                    "PeriodicPattern.nCols",
                    f"the same as nRows ({rows!r}): HP-code markers are square",
                    cols,
                )
            return _make(period, rows, "PeriodicPattern.nRows", bad)
        if data.get("format") != FORMAT:
            raise bad("format", repr(FORMAT), data.get("format"))
        if data.get("version") != VERSION:
            raise bad("version", str(VERSION), data.get("version"))
        if data.get("layout") != LAYOUT:
            raise bad("layout", repr(LAYOUT), data.get("layout"))
        return _make(_number(data, "period_um", "period_um", bad), data.get("size"), "size", bad)


def _make(period: float, size, key: str, bad) -> HPCodePattern:
    if isinstance(size, bool) or not isinstance(size, int) or size < MIN_SIZE or size % 2 == 0:
        raise bad(key, f"an odd number of dots a side, at least {MIN_SIZE}", size)
    return HPCodePattern(period_um=float(period), size=size)


def _number(body: dict, name: str, key: str, bad) -> float:
    v = body.get(key)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not (v > 0 and math.isfinite(v)):
        raise bad(name, "a positive number (µm)", v)
    return float(v)


def read_hpcode(data, where: str = "pattern") -> HPCodePattern:
    """The layout's ``read`` hook (:mod:`calflow.instruments.pattern.layouts`)."""
    return HPCodePattern.from_dict(data, where)
