"""Recorded camera frames and their joints table: the input of a decoded run (docs/data.md).

A lab that filmed its pattern under the microscope hands calflow

* the frames: a folder of image files (``.png``, ``.tif``/``.tiff``) or one multi-page TIFF
  stack (read with tifffile, page by page), monochrome, each of the camera's size;
* a CSV table, one row per frame: ``frame`` (the file name in the folder, or the 0-based
  page of the stack), ``time`` (seconds since the recording's start, or ISO 8601 times),
  ``cmd_<joint>`` for every joint of the robot (µm, degree); optionally ``target_<axis>``,
  ``pose``, ``cycle``, ``direction``; every other column is a thermometer (degC).

Frames stay in their files: what a run keeps of them is the SHA-256 of each (of the image
file; of the page's pixel bytes for a stack, beside the stack file's own). Every problem
is one :class:`~calflow.errors.DataError` line naming the file, the row or frame, and what
was expected: a stack whose page count is not the table's row count, an unreadable or
truncated image, a frame of another size or type.
"""

from __future__ import annotations

import csv
import datetime as _dt
import hashlib
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calflow.errors import DataError

IMAGE_SUFFIXES = (".png", ".tif", ".tiff")  # what calflow.instruments.pattern.frames reads
STACK_SUFFIXES = (".tif", ".tiff")
INDEX_COLUMNS = ("pose", "cycle", "direction")
MISSING = ("", "nan", "NaN", "NA", "N/A")


@dataclass(frozen=True)
class FramesTable:
    """The joints table of a frame recording (module docstring); times in seconds since
    ``recording_start`` (ISO 8601, or None when the table's times are plain seconds)."""

    path: Path
    frame: tuple[str, ...]
    time_s: np.ndarray
    commands: dict[str, np.ndarray]
    targets: dict[str, np.ndarray]
    indices: dict[str, np.ndarray]
    temperatures: dict[str, np.ndarray]
    recording_start: str | None

    def __len__(self) -> int:
        return len(self.frame)


def _float(cell: str, where: str) -> float:
    if cell.strip() in MISSING:
        return math.nan
    try:
        return float(cell)
    except ValueError:
        raise DataError(f"{where}: expected a number, got {cell!r}") from None


def read_table(path: str | Path, joints: Sequence[str]) -> FramesTable:
    """The joints table at ``path`` for a robot with ``joints`` (module docstring)."""
    path = Path(path)
    try:
        with open(path, newline="", encoding="utf-8-sig") as f:
            rows = list(csv.reader(f))
    except (OSError, UnicodeDecodeError) as exc:
        raise DataError(f"{path}: joints table: not a readable CSV file ({exc})") from None
    if not rows or not any(c.strip() for c in rows[0]):
        raise DataError(
            f"{path}: joints table: expected a header row (frame, time, cmd_<joint>…), the file is empty"
        )
    header = [c.strip() for c in rows[0]]
    need = ["frame", "time", *(f"cmd_{j}" for j in joints)]
    for name in need:
        if name not in header:
            raise DataError(
                f"{path}: joints table: column {name!r} missing; expected columns {need} (docs/data.md)"
            )
    dup = sorted({h for h in header if header.count(h) > 1})
    if dup:
        raise DataError(f"{path}: joints table: column {dup[0]!r} appears twice")
    body = [r for r in rows[1:] if any(c.strip() for c in r)]
    if not body:
        raise DataError(f"{path}: joints table: expected one row per frame, got none")
    col = {h: k for k, h in enumerate(header)}
    for i, r in enumerate(body):
        if len(r) != len(header):
            raise DataError(f"{path}: row {i + 2}: expected {len(header)} cells (the header's), got {len(r)}")

    def numbers(name: str) -> np.ndarray:
        return np.array(
            [_float(r[col[name]], f"{path}: row {i + 2}, column {name!r}") for i, r in enumerate(body)]
        )

    frames = tuple(r[col["frame"]].strip() for r in body)
    for i, name in enumerate(frames):
        if not name:
            raise DataError(
                f"{path}: row {i + 2}, column 'frame': expected a file name or a page index, got ''"
            )
    time_s, start = _times([r[col["time"]].strip() for r in body], path)
    commands = {j: numbers(f"cmd_{j}") for j in joints}
    for j, v in commands.items():
        if not np.all(np.isfinite(v)):
            i = int(np.argmax(~np.isfinite(v)))
            raise DataError(
                f"{path}: row {i + 2}, column 'cmd_{j}': expected the joint command sent, got no number"
            )
    targets = {h[7:]: numbers(h) for h in header if h.startswith("target_")}
    indices = {}
    for name in INDEX_COLUMNS:
        if name in col:
            v = numbers(name)
            if not np.all(np.isfinite(v)) or np.any(v != np.round(v)):
                i = int(np.argmax(~np.isfinite(v) | (v != np.round(v))))
                raise DataError(f"{path}: row {i + 2}, column {name!r}: expected an integer")
            if name == "direction" and not np.all(np.isin(v, (-1, 0, 1))):
                i = int(np.argmax(~np.isin(v, (-1, 0, 1))))
                raise DataError(
                    f"{path}: row {i + 2}, column 'direction': expected -1, 0 or +1, got {v[i]:g}"
                )
            indices[name] = v.astype(int)
    known = set(need) | set(INDEX_COLUMNS) | {h for h in header if h.startswith(("target_", "cmd_"))}
    temperatures = {h: numbers(h) for h in header if h not in known}
    return FramesTable(path, frames, time_s, commands, targets, indices, temperatures, start)


def _times(cells: list[str], path: Path) -> tuple[np.ndarray, str | None]:
    """Seconds since the first time (ISO 8601 cells) or the cells as seconds."""
    try:
        return np.array([float(c) for c in cells]), None
    except ValueError:
        pass
    stamps = []
    for i, c in enumerate(cells):
        try:
            t = _dt.datetime.fromisoformat(c.replace("Z", "+00:00"))
        except ValueError:
            raise DataError(
                f"{path}: row {i + 2}, column 'time': expected seconds or an ISO 8601 time, got {c!r}"
            ) from None
        if t.tzinfo is None:
            raise DataError(
                f"{path}: row {i + 2}, column 'time': expected a time zone (e.g. +00:00), got {c!r}"
            )
        stamps.append(t)
    t0 = stamps[0]
    return np.array([(t - t0).total_seconds() for t in stamps]), t0.isoformat()


class FrameFiles:
    """The frames of a recording: a folder of image files or a TIFF stack, addressed by the
    table's ``frame`` column; checks the count, readability, type and size of each."""

    def __init__(self, source: str | Path, names: Sequence[str], shape: tuple[int, int] | None = None):
        self.source = Path(source)
        self.names = tuple(names)
        self.shape = shape
        self.stack = self.source.is_file()
        if self.stack:
            if self.source.suffix.lower() not in STACK_SUFFIXES:
                raise DataError(f"{self.source}: frames: expected a folder of images or a TIFF stack (.tif)")
            self.pages = _stack_pages(self.source)
            if self.pages != len(self.names):
                raise DataError(
                    f"{self.source}: TIFF stack of {self.pages} frames, the joints table has "
                    f"{len(self.names)} rows: expected one frame per row"
                )
            for i, name in enumerate(self.names):
                if not name.isdigit() or int(name) >= self.pages:
                    raise DataError(
                        f"{self.source}: frame {name!r} (table row {i + 2}): expected a page index 0-{self.pages - 1}"
                    )
        elif self.source.is_dir():
            for i, name in enumerate(self.names):
                p = self.source / name
                if Path(name).is_absolute() or ".." in Path(name).parts or not p.is_file():
                    raise DataError(
                        f"{self.source}: frame {name!r} (table row {i + 2}): expected an image file in the folder"
                    )
                if p.suffix.lower() not in IMAGE_SUFFIXES:
                    raise DataError(f"{p}: frame: expected an image file ({', '.join(IMAGE_SUFFIXES)})")
        else:
            raise DataError(f"{self.source}: frames: no such folder or TIFF stack")

    def __len__(self) -> int:
        return len(self.names)

    def where(self, i: int) -> str:
        return f"{self.source}: page {self.names[i]}" if self.stack else str(self.source / self.names[i])

    def chunks(self, size: int) -> Iterator[tuple[slice, np.ndarray, list[str]]]:
        """(rows, frames (n, height, width), SHA-256 of each) by chunks of ``size`` rows."""
        if self.stack:
            import tifffile

            with tifffile.TiffFile(self.source) as tif:
                for start in range(0, len(self), size):
                    rows = range(start, min(start + size, len(self)))
                    frames = [self._check(self._page(tif, i), i) for i in rows]
                    yield slice(rows.start, rows.stop), np.stack(frames), [_pixels_sha(f) for f in frames]
        else:
            for start in range(0, len(self), size):
                rows = range(start, min(start + size, len(self)))
                frames, shas = [], []
                for i in rows:
                    path = self.source / self.names[i]
                    frames.append(self._check(self._image(path), i))
                    shas.append(file_sha256(path))
                yield slice(rows.start, rows.stop), np.stack(frames), shas

    def _page(self, tif, i: int) -> np.ndarray:
        try:
            return tif.pages[int(self.names[i])].asarray()
        except Exception as exc:  # a truncated or corrupt page
            raise DataError(f"{self.where(i)}: not a readable image ({_reason(exc)})") from None

    def _image(self, path: Path) -> np.ndarray:
        """One image file: the instrument's reader (formats, colour, readability)."""
        from PIL import ImageFile

        from calflow.instruments.pattern.frames import read_frames

        lenient = ImageFile.LOAD_TRUNCATED_IMAGES  # WeasyPrint, once imported, sets it for everyone
        ImageFile.LOAD_TRUNCATED_IMAGES = False  # a truncated image is refused, not padded
        try:
            frames, _ = read_frames([path])
        finally:
            ImageFile.LOAD_TRUNCATED_IMAGES = lenient
        if len(frames) != 1:
            raise DataError(f"{path}: {len(frames)} frames in one file; expected one frame per table row")
        return frames[0]

    def _check(self, frame: np.ndarray, i: int) -> np.ndarray:
        if frame.ndim != 2 or frame.dtype.kind not in "uif":
            raise DataError(
                f"{self.where(i)}: expected a monochrome frame of integers or floats, got "
                f"{frame.dtype} of shape {frame.shape}"
            )
        if self.shape is not None and frame.shape != tuple(self.shape):
            h, w = self.shape
            raise DataError(
                f"{self.where(i)}: expected {w} × {h} pixels (the camera's width × height), got "
                f"{frame.shape[1]} × {frame.shape[0]}"
            )
        return frame


def load_pattern(path: str | Path):
    """The pattern file at ``path``, of any installed layout
    (:func:`calflow.instruments.pattern.layouts.load_pattern`); :class:`DataError` in one line
    naming it when it cannot be read or is not one."""
    from calflow.errors import CalflowError
    from calflow.instruments.pattern.layouts import load_pattern as load

    try:
        return load(path)
    except (OSError, ValueError, CalflowError) as exc:
        text = str(exc)
        raise DataError(text if text.startswith(str(path)) else f"{path}: pattern file: {text}") from None


def _stack_pages(path: Path) -> int:
    """The page count of a TIFF stack; :class:`DataError` when it is not readable, or is
    truncated or corrupt (the instrument's reader checks the chain of pages and their data)."""
    from calflow.instruments.pattern.frames import tiff_pages

    try:
        return tiff_pages(path)
    except DataError as exc:
        text = str(exc).removeprefix(f"{path}: ").replace("not a readable TIFF", "not a readable TIFF stack")
        raise DataError(f"{path}: frames: {text}") from None


def _pixels_sha(frame: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(frame).tobytes()).hexdigest()


def _reason(exc: Exception) -> str:
    text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    return text[:160]


def file_sha256(path: str | Path) -> str:
    """SHA-256 of a file (a stack's own digest beside its pages')."""
    with open(path, "rb") as f:
        return hashlib.file_digest(f, "sha256").hexdigest()
