"""``calflow pattern make --layout megarena`` and the Megarena part of ``calflow decode``."""

from __future__ import annotations

import json
import math
import multiprocessing
import os
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from calflow.errors import CalflowError
from calflow.instruments.pattern.megarena.decode import MegarenaDecoded, decode
from calflow.instruments.pattern.megarena.pattern import TAPS, MegarenaPattern

MIN_CHUNK = 4  # frames a process decodes at least (fewer: not worth a process)


def smallest_depth(side_um: float, period_um: float) -> int:
    """The smallest code depth whose target (3·(2^d + d − 2) sites) spans ``side_um``."""
    for depth in TAPS:
        if (3 * ((1 << depth) + depth - 2) - 1) * period_um >= side_um:
            return depth
    raise CalflowError(
        f"--range: a 12-bit Megarena target of period {period_um:g} µm spans "
        f"{(3 * ((1 << 12) + 10) - 1) * period_um:g} µm; the range needs {side_um:g} µm"
    )


def make_megarena(args, range_um: tuple[float, float], names: dict) -> None:
    """The pattern file, the same target as the Vernier library's JSON, its GDSII and a PNG
    preview, of the region of interest: the range plus the field of view a frame needs, to
    ``names`` (kind → path: json, vernier.json, gds, png)."""
    from calflow.data.io import atomic_path
    from calflow.instruments.pattern.gds import write_png
    from calflow.instruments.pattern.megarena.gds import write_gds

    period = 9.0 if args.period_um is None else args.period_um
    if not period > 0:
        raise CalflowError(f"--period-um: expected a positive number (µm), got {period!r}")
    side = max(range_um)
    depth = args.depth
    if depth is None:
        # the range's largest side, plus the field of view the deepest code it needs asks
        depth = smallest_depth(side, period)
        while depth < 12 and (3 * ((1 << depth) + depth - 2) - 1) * period < side + 2 * _half_fov(
            depth, period
        ):
            depth += 1
    if depth not in TAPS:
        raise CalflowError(f"--depth: expected an integer from 4 to 12, got {depth!r}")
    fov = 3 * (depth + 4) * period
    half = _half_fov(depth, period)  # the origin: frame centres from (0, 0) decode
    region = (0.0, 0.0, range_um[0] + 2 * half, range_um[1] + 2 * half)
    size = (3 * ((1 << depth) + depth - 2) - 1) * period
    if max(region[2:]) > size + 1e-9:
        raise CalflowError(
            f"--range: a {depth}-bit Megarena target of period {period:g} µm spans {size:g} µm; "
            f"the range and a field of view of {fov:g} µm need {max(region[2:]):g} µm"
        )
    try:
        pattern = MegarenaPattern(
            period, depth, region_um=region, dot_diameter_um=args.dot_um, origin_um=(half, half)
        )
    except ValueError as exc:
        raise CalflowError(f"--period-um/--dot-um: {exc}") from None
    if pattern.dot_diameter_um >= period:
        raise CalflowError(
            f"--dot-um: expected less than the period {period:g} µm, got {pattern.dot_diameter_um:g}"
        )
    with (
        atomic_path(names["json"]) as j,
        atomic_path(names["vernier.json"]) as v,
        atomic_path(names["gds"]) as g,
        atomic_path(names["png"]) as p,
    ):
        pattern.save(j)
        v.write_text(json.dumps(pattern.to_library_dict(), indent=4, ensure_ascii=False) + "\n")
        write_gds(pattern, g)
        write_png(pattern, p)
    rows, cols = pattern.region_sites
    print(
        f"{names['json']}: {depth}-bit Megarena, {len(cols)} × {len(rows)} sites every {period:g} µm "
        f"(dots of {pattern.dot_diameter_um:g} µm), range {range_um[0]:g} × {range_um[1]:g} µm, field of view "
        f"needed {fov:g} µm; {names['vernier.json'].name}, {names['gds'].name}, {names['png'].name}"
    )


def _half_fov(depth: int, period: float) -> float:
    """Half the field of view a frame needs, rounded up to whole periods (µm)."""
    return math.ceil(3 * (depth + 4) / 2) * period


def decode_parallel(
    frames: np.ndarray, pattern: MegarenaPattern, jobs: int = 0, **options
) -> MegarenaDecoded:
    """:func:`decode` over ``jobs`` processes (0: every core this process may use), frames split
    into contiguous chunks; the same result as one process."""
    n = len(frames)
    if jobs <= 0:
        jobs = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    jobs = max(1, min(jobs, n // MIN_CHUNK))
    if jobs == 1:
        return decode(frames, pattern, **options)
    bounds = np.linspace(0, n, jobs + 1).astype(int)
    spans = list(zip(bounds[:-1].tolist(), bounds[1:].tolist()))
    if "fork" in multiprocessing.get_all_start_methods():
        # the workers inherit the frames: none is pickled (a few hundred MB for a few hundred frames)
        _SHARED.update(frames=frames, pattern=pattern, options=options)
        try:
            with ProcessPoolExecutor(
                max_workers=jobs, mp_context=multiprocessing.get_context("fork")
            ) as pool:
                parts = list(pool.map(_decode_span, spans))
        finally:
            _SHARED.clear()
    else:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            parts = list(
                pool.map(_decode_part, [(frames[a:b], pattern.to_dict(), options) for a, b in spans])
            )
    return MegarenaDecoded(
        **{
            key: np.concatenate([getattr(part, key) for part in parts])
            for key in (
                "x_um",
                "y_um",
                "theta_deg",
                "u_x_um",
                "u_y_um",
                "u_theta_deg",
                "status",
                "reason",
                "pixel_um",
                "u_pixel_um",
                "theta_x_deg",
                "pixel_x_um",
                "theta_y_deg",
                "pixel_y_um",
            )
        },
        shape=parts[0].shape,
        origin_um=parts[0].origin_um,
    )


_SHARED: dict = {}  # what forked workers inherit


def _decode_span(span) -> MegarenaDecoded:
    a, b = span
    return decode(_SHARED["frames"][a:b], _SHARED["pattern"], workers=1, **_SHARED["options"])


def _decode_part(job) -> MegarenaDecoded:
    frames, data, options = job
    return decode(frames, MegarenaPattern.from_dict(data), workers=1, **options)
