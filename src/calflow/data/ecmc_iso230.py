"""ISO 230-2 input files as the ecmc motion-control project writes them (``*ISO230.dat``).

A single-axis positioning test (ISO 230-2:2014, clause 3.2 and Annex A's standard test
cycle): ``POSITIONS`` target positions, each approached ``CYCLES`` times forward and
``CYCLES`` times backward, the reference instrument's reading recorded at each
approach. The file is text: ``#`` comment lines, blank lines, and ``KEY=value`` lines::

    # ISO 230-2 test of axis 1, laser interferometer
    UNIT=mm
    CYCLES=2
    POSITIONS=3
    TGT_DATA[1]=10.0
    REF_DATA_FWD[1,1]=10.00161
    REF_DATA_BWD[1,1]=10.00342
    ...

``TGT_DATA[i]`` is the target of position ``i``, ``REF_DATA_FWD[i,j]`` /
``REF_DATA_BWD[i,j]`` the reference reading of the forward / backward approach of
position ``i`` in cycle ``j`` (both 1-based), all in ``UNIT``. ``CYCLES`` and
``POSITIONS`` default to 5 and 8 and ``UNIT`` to ``mm`` as in ecmc; the keys ecmc's
extraction script writes for its own use (``DEC``, ``REF_PV``, ``TEST_PV``,
``TGT_SET_PV``) are accepted and ignored. Every other key, a repeated key, a missing
reading or a non-finite number is a one-line :class:`~calflow.errors.DataError` naming
the file, the line and what was expected.

:func:`to_run` turns a recording into a ``stage1d`` run dataset (µm): the standard test
cycle, forward through positions 1..P then backward P..1, one row per approach.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calflow.errors import DataError

UM_PER_UNIT = {"m": 1e6, "mm": 1e3, "um": 1.0, "µm": 1.0, "nm": 1e-3}  # lengths only: the stage1d axis
IGNORED_KEYS = ("DEC", "REF_PV", "TEST_PV", "TGT_SET_PV")  # ecmc's own bookkeeping
DEFAULTS = {"UNIT": "mm", "CYCLES": 5, "POSITIONS": 8}  # as ecmc's ISO 230-2 script assumes
_LINE = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*(?:\[\s*([^\]]*?)\s*\])?\s*=\s*(.*?)\s*$")


@dataclass(frozen=True)
class Iso230Recording:
    """One ISO 230-2 positioning test: ``targets`` (P,), ``forward`` and ``backward``
    (P, C) reference readings, all in ``unit``."""

    unit: str
    targets: np.ndarray
    forward: np.ndarray
    backward: np.ndarray

    @property
    def scale_um(self) -> float:
        """µm per ``unit``."""
        return UM_PER_UNIT[self.unit]


def _fail(where: str, line: int, message: str) -> DataError:
    return DataError(f"{where}: line {line}: {message}")


def _count(value: str, key: str, where: str, line: int) -> int:
    try:
        n = int(value)
    except ValueError:
        raise _fail(where, line, f"{key}: expected a whole number >= 1, got {value!r}") from None
    if n < 1 or n > 100_000:
        raise _fail(where, line, f"{key}: expected a whole number from 1 to 100000, got {value!r}")
    return n


def _real(value: str, key: str, where: str, line: int) -> float:
    try:
        x = float(value)
    except ValueError:
        raise _fail(where, line, f"{key}: expected a number, got {value!r}") from None
    if not math.isfinite(x):
        raise _fail(where, line, f"{key}: expected a finite number, got {value!r}")
    return x


def _indices(raw: str | None, n: int, key: str, where: str, line: int) -> tuple[int, ...]:
    shape = "[i]" if n == 1 else "[i,j]"
    parts = [] if raw is None else [p.strip() for p in raw.split(",")]
    if len(parts) != n or not all(p.isdigit() and p[0] != "0" for p in parts):
        raise _fail(where, line, f"{key}: expected 1-based indices {key}{shape}, got {key}[{raw or ''}]")
    return tuple(int(p) for p in parts)


def parse(text: str, where: str = "ISO 230-2 file") -> Iso230Recording:
    """Parse the text of an ecmc ``*ISO230.dat`` file; ``where`` names it in errors."""
    scalars: dict[str, tuple[str, int]] = {}
    cells: dict[tuple, tuple[float, int]] = {}  # (key, i[, j]) -> (value, line)
    for number, raw_line in enumerate(text.splitlines(), start=1):
        line = raw_line.strip()
        if not line or line.startswith("#"):
            continue
        m = _LINE.match(line)
        if not m:
            raise _fail(where, number, f"expected '# comment' or KEY=value, got {line[:60]!r}")
        key, index, value = m.group(1).upper(), m.group(2), m.group(3)
        if key in ("TGT_DATA", "REF_DATA_FWD", "REF_DATA_BWD"):
            idx = _indices(index, 1 if key == "TGT_DATA" else 2, key, where, number)
            name = f"{key}[{','.join(map(str, idx))}]"
            if (key, *idx) in cells:
                raise _fail(
                    where,
                    number,
                    f"{name} given again (first on line {cells[(key, *idx)][1]}); expected each reading once",
                )
            cells[(key, *idx)] = (_real(value, name, where, number), number)
        elif key in ("UNIT", "CYCLES", "POSITIONS", *IGNORED_KEYS) and index is None:
            if key in scalars:
                raise _fail(where, number, f"{key} given again (first on line {scalars[key][1]})")
            scalars[key] = (value, number)
        else:
            raise _fail(
                where,
                number,
                f"unknown key {m.group(1)!r}; expected UNIT, CYCLES, POSITIONS, "
                "TGT_DATA[i], REF_DATA_FWD[i,j] or REF_DATA_BWD[i,j]",
            )
    unit, unit_line = scalars.get("UNIT", (DEFAULTS["UNIT"], 0))
    if unit not in UM_PER_UNIT:
        raise _fail(
            where, unit_line, f"UNIT: expected a length unit, one of {list(UM_PER_UNIT)}, got {unit!r}"
        )
    sizes = {}
    for key in ("CYCLES", "POSITIONS"):
        value, line = scalars.get(key, (str(DEFAULTS[key]), 0))
        sizes[key] = _count(value, key, where, line)
    positions, cycles = sizes["POSITIONS"], sizes["CYCLES"]
    for (key, *idx), (_, line) in cells.items():
        limits = (positions,) if key == "TGT_DATA" else (positions, cycles)
        for v, hi, what in zip(idx, limits, ("POSITIONS", "CYCLES")):
            if v > hi:
                raise _fail(where, line, f"{key}[{','.join(map(str, idx))}]: index {v} is beyond {what}={hi}")
    end = len(text.splitlines())

    def table(key: str, shape: tuple[int, ...]) -> np.ndarray:
        given = {k[1:] for k in cells if k[0] == key}  # every index is in range: complete iff the count is
        if len(given) < math.prod(shape):
            one = next(i for i in (tuple(k + 1 for k in idx) for idx in np.ndindex(*shape)) if i not in given)
            what = "targets" if key == "TGT_DATA" else f"x CYCLES={cycles} readings per direction"
            raise DataError(
                f"{where}: line {end}: {key}[{','.join(map(str, one))}] missing; "
                f"expected POSITIONS={positions} {what}"
            )
        out = np.empty(shape)  # bounded by the file's own lines
        for idx in given:
            out[tuple(k - 1 for k in idx)] = cells[(key, *idx)][0]
        return out

    targets = table("TGT_DATA", (positions,))
    if positions > 1 and not (np.all(np.diff(targets) > 0) or np.all(np.diff(targets) < 0)):
        k = next(
            i for i in range(1, positions) if (targets[i] - targets[i - 1]) * (targets[1] - targets[0]) <= 0
        )
        raise _fail(
            where,
            cells[("TGT_DATA", k + 1)][1],
            f"TGT_DATA[{k + 1}]: expected targets strictly increasing or decreasing with i, "
            f"got {targets[k]!r} after {targets[k - 1]!r}",
        )
    return Iso230Recording(
        unit, targets, table("REF_DATA_FWD", (positions, cycles)), table("REF_DATA_BWD", (positions, cycles))
    )


def read(path: str | os.PathLike) -> Iso230Recording:
    """Read an ecmc ``*ISO230.dat`` file (one-line errors name the file and line)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise DataError(f"{path}: file not found") from None
    except UnicodeDecodeError as exc:
        raise DataError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except OSError as exc:
        raise DataError(f"{path}: cannot read ({exc.strerror or exc})") from None
    return parse(text, str(path))


def format_text(rec: Iso230Recording, comments: tuple[str, ...] = ()) -> str:
    """The text of an ecmc ``*ISO230.dat`` file holding ``rec`` (the inverse of :func:`parse`)."""
    lines = [f"# {c}" for c in comments]
    p, c = rec.forward.shape
    lines += [f"UNIT={rec.unit}", f"CYCLES={c}", f"POSITIONS={p}"]
    lines += [f"TGT_DATA[{i + 1}]={float(rec.targets[i])!r}" for i in range(p)]
    for key, data in (("REF_DATA_FWD", rec.forward), ("REF_DATA_BWD", rec.backward)):
        lines += [f"{key}[{i + 1},{j + 1}]={float(data[i, j])!r}" for j in range(c) for i in range(p)]
    return "\n".join(lines) + "\n"


def write(rec: Iso230Recording, path: str | os.PathLike, comments: tuple[str, ...] = ()) -> Path:
    """Write ``rec`` as an ecmc ``*ISO230.dat`` file, atomically."""
    from calflow.data.io import write_text

    return write_text(format_text(rec, comments), path)


def standard_cycle(rec: Iso230Recording) -> dict[str, np.ndarray]:
    """Rows of the ISO 230-2 standard test cycle in µm: per cycle, forward through
    positions 1..P then backward P..1 (ISO 230-2:2014, Fig. 2, linear cycle).

    Returns ``target``, ``reading`` (µm), ``pose`` (0..2P-1 within a cycle: forward
    poses 0..P-1, backward poses P..2P-1), ``cycle`` (0-based) and ``direction`` (±1).
    Forward/backward are the directions of increasing/decreasing position index.
    """
    p, c = rec.forward.shape
    back = np.arange(p)[::-1]
    target = np.tile(np.concatenate([rec.targets, rec.targets[back]]), c) * rec.scale_um
    reading = np.concatenate([np.concatenate([rec.forward[:, j], rec.backward[back, j]]) for j in range(c)])
    return {
        "target": target,
        "reading": reading * rec.scale_um,
        "pose": np.tile(np.arange(2 * p), c),
        "cycle": np.repeat(np.arange(c), 2 * p),
        "direction": np.tile(np.concatenate([np.ones(p, int), -np.ones(p, int)]), c),
    }
