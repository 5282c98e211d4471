"""Frames decoded as they are read, on every core: ``calflow decode`` over a recording too
large to hold.

The files' frames are listed from their headers (a TIFF stack's pages, each checked whole;
one frame per PNG or JPEG), cut into chunks of :data:`CHUNK` frames, and a pool of processes
each reads its chunk from the files and decodes it (one core a process, the phase planes'
plans kept between a process's chunks): the parent holds the poses, never the frames, so the
memory is the pool's chunks whatever the recording's length. The result is the one
:func:`~calflow.instruments.pattern.layouts.decode_frames` gives on the whole stack, and for
HP-code markers (:func:`markers_stream`) the table
:func:`~calflow.instruments.pattern.hpcode.decode_markers` gives.
"""

from __future__ import annotations

import dataclasses
import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from calflow.errors import DataError
from calflow.instruments.pattern.frames import JPEG, PNG, TIFF, _read, tiff_pages

CHUNK = 16  # frames a process reads and decodes at once


def frame_index(paths) -> list[tuple[str, int]]:
    """(file, page) of every frame of these files, from their headers; a missing, unknown or
    truncated file is refused in one line."""
    index: list[tuple[str, int]] = []
    for path in map(Path, paths):
        if not path.is_file():
            raise DataError(f"{path}: no such image file")
        suffix = path.suffix.lower()
        if suffix in TIFF:
            index += [(str(path), page) for page in range(tiff_pages(path))]
        elif suffix in PNG + JPEG:
            index.append((str(path), 0))
        else:
            raise DataError(
                f"{path}: unknown image type {suffix or '(none)'!r}; expected .tif, .tiff, .png, .jpg or .jpeg"
            )
    if not index:
        raise DataError("no frames: expected at least one image file")
    return index


def read_chunk(units: list[tuple[str, int]], shape: tuple[int, int] | None = None) -> np.ndarray:
    """The frames (n, h, w) at ``units`` ((file, page) each), all of ``shape`` when given."""
    import tifffile

    frames = []
    tif, tif_path = None, None  # a TIFF stack is opened once per chunk, not once per frame
    try:
        for path, page in units:
            p = Path(path)
            if p.suffix.lower() in TIFF:
                try:
                    if tif_path != p:
                        if tif is not None:
                            tif.close()
                            tif = None
                        tif = tifffile.TiffFile(p)
                        tif_path = p
                    frame = tif.pages[page].asarray()
                except Exception as exc:  # tifffile's and the OS's errors alike
                    raise DataError(
                        f"{p}: frame {page}: not readable ({type(exc).__name__}: {exc})"
                    ) from None
            else:
                frame = _read(p)[0]
            frames.append(_checked(frame, p, page, shape))
    finally:
        if tif is not None:
            tif.close()
    return np.stack(frames)


def _checked(frame: np.ndarray, p: Path, page: int, shape) -> np.ndarray:
    """The frame, or :class:`DataError` when it is not one monochrome frame of ``shape``."""
    if p.suffix.lower() in TIFF:
        if frame.ndim != 2:
            raise DataError(f"{p}: frame {page} of shape {frame.shape}; expected a monochrome frame")
        if frame.dtype.kind not in "uif":
            raise DataError(f"{p}: pixels of type {frame.dtype}; expected integers or floats")
    if shape is not None and frame.shape != tuple(shape):
        raise DataError(
            f"{p}: frame {page} is {frame.shape[1]} × {frame.shape[0]} pixels; "
            f"expected {shape[1]} × {shape[0]} like the frames before it"
        )
    return frame


def decode_stream(paths, pattern, jobs: int = 0, chunk: int = CHUNK, **options):
    """Decode every frame of ``paths`` (module docstring) with the pattern's layout, over ``jobs``
    processes (0: every core this process may use). Returns (result, [(file, page)…])."""
    parts, index = _stream(paths, pattern, jobs, chunk, _decode_chunk, options)
    return _joined(parts), index


def markers_stream(paths, pattern, jobs: int = 0, chunk: int = CHUNK, pixel_um: float | None = None):
    """Every HP-code marker of every frame of ``paths``, streamed as :func:`decode_stream`
    streams poses. Returns (:class:`~calflow.instruments.pattern.hpcode.decode.Markers` of the
    whole recording, [(file, page)…])."""
    parts, index = _stream(paths, pattern, jobs, chunk, _markers_chunk, {"pixel_um": pixel_um})
    return joined_markers(parts), index


def _stream(paths, pattern, jobs: int, chunk: int, work, options):
    """``work`` over the recording's chunks, in order, on ``jobs`` processes: (results, index)."""
    index = frame_index(paths)
    shape = read_chunk(index[:1]).shape[1:]
    chunks = [index[i : i + chunk] for i in range(0, len(index), chunk)]
    if jobs <= 0:
        jobs = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    jobs = max(1, min(jobs, len(chunks)))
    jobs_args = [(units, shape, pattern, options) for units in chunks]
    _imported(pattern)  # before the pool forks: the workers inherit the modules, not import them
    if jobs == 1:
        return [work(a) for a in jobs_args], index
    methods = multiprocessing.get_all_start_methods()
    context = multiprocessing.get_context("fork" if "fork" in methods else None)
    with ProcessPoolExecutor(max_workers=jobs, mp_context=context) as pool:
        return list(pool.map(work, jobs_args)), index


def _imported(pattern) -> None:
    """Import what decoding frames of ``pattern`` needs (its layout's decoder, scipy's FFT and
    ndimage): a few tenths of a second each process would otherwise spend."""
    import scipy.fft  # noqa: F401
    import scipy.ndimage  # noqa: F401

    from calflow.instruments.pattern.layouts import layout_of

    layout_of(getattr(pattern, "layout", "cell2x2"))


def _decode_chunk(job):
    from calflow.instruments.pattern.layouts import decode_frames

    units, shape, pattern, options = job
    return decode_frames(read_chunk(units, shape), pattern, workers=1, **options)


def _markers_chunk(job):
    from calflow.instruments.pattern.hpcode import decode_markers

    units, shape, pattern, options = job
    return decode_markers(read_chunk(units, shape), pattern, options["pixel_um"])


def joined_markers(parts):
    """One table of the chunks' markers: each chunk's frame indices shifted by its start."""
    from calflow.instruments.pattern.hpcode.decode import Markers

    starts = np.cumsum([0] + [p.n_frames for p in parts[:-1]])
    return Markers(
        frame=np.concatenate([p.frame + start for p, start in zip(parts, starts)]),
        number=np.concatenate([p.number for p in parts]),
        columns={k: np.concatenate([p.columns[k] for p in parts]) for k in parts[0].columns},
        status=np.concatenate([p.status for p in parts]),
        reason=np.concatenate([p.reason for p in parts]),
        n_frames=int(sum(p.n_frames for p in parts)),
        shape=parts[0].shape,
    )


def _joined(parts):
    """One result of the chunks' results: every per-frame array concatenated, the rest the
    first chunk's."""
    first = parts[0]
    if len(parts) == 1:
        return first
    values = {}
    for f in dataclasses.fields(first):
        v = getattr(first, f.name)
        if isinstance(v, np.ndarray) and v.shape[:1] == (len(first),):
            values[f.name] = np.concatenate([getattr(p, f.name) for p in parts])
        elif f.name == "details" and v is not None:
            values[f.name] = [d for p in parts for d in p.details]
        else:
            values[f.name] = v
    return type(first)(**values)
