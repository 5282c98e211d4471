"""Camera frames from files: TIFF (one frame or a stack, tifffile), PNG and JPEG (Pillow).

Frames must be monochrome (one channel), 8- or 16-bit integers or floats, all of one size; a
file that cannot be read, is truncated, holds colour or a frame of another size is refused in
one line naming it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from calflow.errors import DataError

TIFF = (".tif", ".tiff")
PNG = (".png",)
JPEG = (".jpg", ".jpeg")


def read_frames(paths) -> tuple[np.ndarray, list[tuple[str, int]]]:
    """The frames of these files as one array (n, h, w) and, per frame, (file, page)."""
    frames: list[np.ndarray] = []
    origin: list[tuple[str, int]] = []
    shape = None
    for path in map(Path, paths):
        for page, frame in enumerate(_read(path)):
            if shape is None:
                shape = frame.shape
            elif frame.shape != shape:
                raise DataError(
                    f"{path}: frame {page} is {frame.shape[1]} × {frame.shape[0]} pixels; "
                    f"expected {shape[1]} × {shape[0]} like the frames before it"
                )
            frames.append(frame)
            origin.append((str(path), page))
    if not frames:
        raise DataError("no frames: expected at least one image file")
    return np.stack(frames), origin


def _read(path: Path) -> list[np.ndarray]:
    if not path.is_file():
        raise DataError(f"{path}: no such image file")
    suffix = path.suffix.lower()
    if suffix in TIFF:
        arr = _tiff(path)
    elif suffix in PNG + JPEG:
        arr = _png(path, "JPEG" if suffix in JPEG else "PNG")
    else:
        raise DataError(
            f"{path}: unknown image type {suffix or '(none)'!r}; expected .tif, .tiff, .png, .jpg or .jpeg"
        )
    if arr.dtype.kind not in "uif" or arr.dtype.kind == "b":
        raise DataError(f"{path}: pixels of type {arr.dtype}; expected integers or floats")
    if arr.ndim == 2:
        return [arr]
    if arr.ndim == 3 and suffix in TIFF and arr.shape[-1] not in (3, 4):
        return list(arr)
    raise DataError(f"{path}: image of shape {arr.shape}; expected a monochrome frame (one channel)")


def _tiff(path: Path) -> np.ndarray:
    import tifffile

    try:
        with _tifffile_errors() as errors, tifffile.TiffFile(path) as tif:
            _check_whole(path, tif, errors)
            series = tif.series[0]
            if series.axes[-1:] == "S" or (
                series.shape and series.shape[-1] in (3, 4) and "S" in series.axes
            ):
                raise DataError(f"{path}: a colour TIFF (axes {series.axes}); expected monochrome frames")
            frames = series.asarray()
            _check_whole(path, tif, errors)
            return frames
    except DataError:
        raise
    except Exception as exc:  # tifffile raises TiffFileError, ValueError, OSError … on bad files
        raise DataError(f"{path}: not a readable TIFF ({type(exc).__name__}: {exc})") from None


def tiff_pages(path: str | Path) -> int:
    """The number of pages of a TIFF file, every one of them whole.

    :class:`DataError` when the file is not a TIFF, or is truncated or corrupt: its chain of
    pages points past what could be read, a page's data lies beyond the end of the file, or
    tifffile reported an error while reading it.
    """
    import tifffile

    path = Path(path)
    try:
        with _tifffile_errors() as errors, tifffile.TiffFile(path) as tif:
            pages = len(tif.pages)
            _check_whole(path, tif, errors)
    except DataError:
        raise
    except Exception as exc:  # tifffile raises its own and OS errors: the file is not a TIFF
        raise DataError(f"{path}: not a readable TIFF ({type(exc).__name__}: {exc})") from None
    return pages


def _check_whole(path: Path, tif, errors: list[str]) -> None:
    """Refuse a truncated or corrupt TIFF, not relying on tifffile's log alone (the chain of
    pages is followed here too: a last page that points to another one is a cut file)."""
    size = path.stat().st_size
    pages = list(tif.pages)
    why = errors[0] if errors else ""
    if not why:
        for page in pages:
            offsets = getattr(page, "dataoffsets", ()) or ()
            counts = getattr(page, "databytecounts", ()) or ()
            if max((o + n for o, n in zip(offsets, counts)), default=0) > size:
                why = "a page's data lies beyond the end of the file"
                break
    if not why and pages and _next_ifd(tif, pages[-1].offset, size) != 0:
        why = f"page {len(pages)} points to a next page that cannot be read"
    if why:
        raise DataError(f"{path}: not a readable TIFF, truncated or corrupt ({why[:160]})")


def _next_ifd(tif, offset: int, size: int) -> int:
    """The offset of the page after the one whose IFD starts at ``offset`` (0: none)."""
    import struct

    header = tif.tiff  # byte order and sizes of classic or BigTIFF
    fh = tif.filehandle
    fh.seek(offset)
    raw = fh.read(header.tagnosize)
    if len(raw) < header.tagnosize:
        return -1
    (count,) = struct.unpack(header.tagnoformat, raw)
    fh.seek(offset + header.tagnosize + count * header.tagsize)
    raw = fh.read(header.offsetsize)
    if len(raw) < header.offsetsize:
        return -1
    (nxt,) = struct.unpack(header.offsetformat, raw)
    return nxt


class _tifffile_errors:
    """Within: tifffile's errors collected here, its warnings silenced (printed, either would
    be a second line), whatever level other code set on its logger; restored after. The
    structural checks of :func:`_check_whole` do not depend on this log."""

    def __enter__(self) -> list[str]:
        import logging

        messages: list[str] = []

        class Collect(logging.Handler):
            def emit(self, record):
                if record.levelno >= logging.ERROR:
                    messages.append(record.getMessage())

        self.log = logging.getLogger("tifffile")
        self.saved = (self.log.level, self.log.propagate)
        self.handler = Collect(logging.WARNING)
        self.log.addHandler(self.handler)
        self.log.setLevel(logging.WARNING)
        self.log.propagate = False
        return messages

    def __exit__(self, *exc) -> None:
        level, propagate = self.saved
        self.log.removeHandler(self.handler)
        self.log.setLevel(level)
        self.log.propagate = propagate


def _png(path: Path, kind: str = "PNG") -> np.ndarray:
    from PIL import Image, ImageFile, UnidentifiedImageError

    lenient = ImageFile.LOAD_TRUNCATED_IMAGES  # WeasyPrint, once imported, sets it process-wide
    try:
        with Image.open(path) as img:
            ImageFile.LOAD_TRUNCATED_IMAGES = False  # a truncated image is refused, not padded
            try:
                img.load()
            finally:
                ImageFile.LOAD_TRUNCATED_IMAGES = lenient
            if img.mode not in ("L", "I;16", "I;16B", "I;16L", "I", "F"):
                raise DataError(f"{path}: a {img.mode} image; expected a monochrome frame (mode L or I;16)")
            return np.asarray(img)
    except DataError:
        raise
    except (UnidentifiedImageError, Image.DecompressionBombError, OSError, SyntaxError, ValueError) as exc:
        raise DataError(f"{path}: not a readable {kind} ({exc})") from None


def write_frames_tiff(frames: np.ndarray, path) -> Path:
    """Write frames (h, w) or (n, h, w) as a TIFF stack, atomically."""
    import tifffile

    from calflow.data.io import atomic_path

    with atomic_path(path) as tmp:
        tifffile.imwrite(tmp, np.asarray(frames), photometric="minisblack")
    return Path(path)
