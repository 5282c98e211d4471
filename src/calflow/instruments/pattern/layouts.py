"""Pattern layouts: what each kind of encoded target contributes to the camera sensor.

A layout says what the sites of a target are and how its absolute code is read; the phase
part of the decoding (:mod:`.phase`) is shared by all. calflow registers its own ``cell2x2``
FEMTO-ST's ``megarena`` and its ``hpcode`` markers; a lab's own encoding plugs in as a :class:`Layout` registered
as an entry point of the group ``calflow.pattern_layouts`` in its ``pyproject.toml``::

    [project.entry-points."calflow.pattern_layouts"]
    mylayout = "mylab_calflow.layout:LAYOUT"

Its two hooks are functions (docs/instruments.md, "Pattern layouts"); this module is imported
only where a pattern file is read or frames are decoded:

* ``read(data: dict, where: str) -> pattern`` — a parsed pattern file (calflow's, with
  ``"layout": name``, or another program's, recognised by one of ``foreign_keys``) → a pattern
  object carrying ``layout``, ``period_um``, ``dot_diameter_um``, ``origin_um``,
  ``min_fov_um``, ``present(rows, cols)`` and ``save(path)`` (the renderer draws any such
  pattern); a bad file raises :class:`~calflow.errors.CalflowError` in one line naming
  ``where``, the key and what was expected;
* ``decode(frames, pattern, pixel_um=None, workers=None, details=False) -> Decoded`` — the
  contract of :func:`calflow.instruments.pattern.decode`: per frame x, y (µm), Θ (degree),
  their standard uncertainties, a status of :data:`~calflow.instruments.pattern.STATUSES`
  and a reason; NaN, never a neighbouring period, when it cannot tell.

The built-in layouts' code is imported here, so the workflow's code digests
(:mod:`calflow.provenance`) follow it; a lab's layout, loaded from its entry point, is not in
them: after changing it, rerun what decodes frames (``--forcerun decode_frames``).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from importlib.metadata import entry_points
from pathlib import Path
from typing import Any

from calflow.errors import CalflowError
from calflow.instruments.pattern.decode import decode as decode_cell2x2
from calflow.instruments.pattern.hpcode.decode import decode as decode_hpcode
from calflow.instruments.pattern.hpcode.pattern import read_hpcode
from calflow.instruments.pattern.megarena.decode import decode as decode_megarena
from calflow.instruments.pattern.megarena.pattern import read_megarena
from calflow.instruments.pattern.pattern import read_cell2x2

GROUP = "calflow.pattern_layouts"


@dataclass(frozen=True)
class Layout:
    """One layout: its name, a line saying what it is, its two hooks and the keys it reads."""

    name: str
    description: str
    read: Callable[[dict, str], Any]  # read(data, where) -> pattern
    decode: Callable[..., Any]  # decode(frames, pattern, pixel_um=None, ...) -> Decoded
    foreign_keys: tuple[str, ...] = ()  # top-level keys of other programs' pattern files


CELL2X2 = Layout(
    name="cell2x2",
    description="calflow's coded-dot grid: two m-sequences in the missing dots of 2 × 2 cells",
    read=read_cell2x2,
    decode=decode_cell2x2,
)

MEGARENA = Layout(
    name="megarena",
    description="FEMTO-ST's Megarena: one m-sequence keeps or drops whole rows and columns of a dot grid",
    read=read_megarena,
    decode=decode_megarena,
    foreign_keys=("MegarenaPattern",),
)

HPCODE = Layout(
    name="hpcode",
    description="FEMTO-ST's HP-code markers: numbered dot squares framed by three QR-like fiducials, several a frame",
    read=read_hpcode,
    decode=decode_hpcode,
    foreign_keys=("HPCodePattern", "PeriodicPattern"),
)


@lru_cache(maxsize=1)
def layouts() -> dict[str, Layout]:
    """Every installed layout by name; an entry point that is not a :class:`Layout`, or a
    second layout of one name or foreign key, is refused in one line."""
    found: dict[str, Layout] = {}
    keys: dict[str, str] = {}
    for ep in sorted(entry_points(group=GROUP), key=lambda e: e.name):
        layout = ep.load()
        if not isinstance(layout, Layout):
            raise CalflowError(f"entry point {GROUP}:{ep.name}: {ep.value} is not a calflow pattern Layout")
        if not (callable(layout.read) and callable(layout.decode)):
            raise CalflowError(
                f"entry point {GROUP}:{ep.name}: read and decode: expected functions, "
                f"got {type(layout.read).__name__} and {type(layout.decode).__name__}"
            )
        if layout.name in found:
            raise CalflowError(f"entry point {GROUP}:{ep.name}: a second layout named {layout.name!r}")
        for key in layout.foreign_keys:
            if key in keys:
                raise CalflowError(
                    f"entry point {GROUP}:{ep.name}: the key {key!r} is already read by layout {keys[key]!r}"
                )
            keys[key] = layout.name
        found[layout.name] = layout
    return found


def layout_of(name: str, where: str = "pattern") -> Layout:
    """The layout named ``name``, or one line saying which exist."""
    known = layouts()
    if name not in known:
        raise CalflowError(f"{where}: layout: expected one of {', '.join(sorted(known))}, got {name!r}")
    return known[name]


def read_pattern(data: Any, where: str = "pattern") -> Any:
    """A parsed pattern file → the pattern of its layout (``layout`` key, or another program's
    top-level key a layout reads; a file with neither is read as calflow's ``cell2x2``, unless
    it is made of objects only, as other programs' files are: then it is refused naming the
    keys calflow reads)."""
    if not isinstance(data, dict):
        raise CalflowError(f"{where}: (top level): expected a JSON object")
    if "layout" in data:
        return layout_of(data["layout"], where).read(data, where)
    for layout in layouts().values():
        for key in layout.foreign_keys:
            if key in data:
                return layout.read(data, where)
    if "format" in data or not data or not all(isinstance(v, dict) for v in data.values()):
        return layout_of("cell2x2", where).read(data, where)  # says which key is wrong
    known = sorted(k for lay in layouts().values() for k in lay.foreign_keys)
    raise CalflowError(
        f"{where}: (top level): expected a calflow pattern file (format, layout) or one of the keys "
        f"{', '.join(known)}, got keys {', '.join(sorted(map(str, data))) or '(none)'}"
    )


def load_pattern(path) -> Any:
    """Read a pattern file of any installed layout; a bad one raises one line naming it."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise CalflowError(f"{path}: no such pattern file") from None
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise CalflowError(f"{path}: not a calflow pattern file (expected JSON: {exc})") from None
    return read_pattern(data, str(path))


def decode_frames(frames, pattern, **options) -> Any:
    """Decode frames of ``pattern`` with its layout's decoder."""
    return layout_of(getattr(pattern, "layout", "cell2x2")).decode(frames, pattern, **options)
