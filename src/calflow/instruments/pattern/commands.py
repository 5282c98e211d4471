"""``calflow pattern make`` and ``calflow decode``: the pattern's files, and a lab's frames → poses."""

from __future__ import annotations

import argparse
import csv
import io
import math
import re
import sys
from pathlib import Path

from calflow.errors import CalflowError

FIELDS = ("x_um", "y_um", "theta_deg", "u_x_um", "u_y_um", "u_theta_deg")


def pattern_arguments(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="pattern_command", required=True)
    m = sub.add_parser("make", help="write a pattern file, its GDSII for lithography and a PNG preview")
    m.add_argument("--range", required=True, metavar="XxY", help="measuring range in µm, e.g. 9500x4200")
    m.add_argument("--period-um", type=float, default=4.0, help="dot pitch (µm, default 4)")
    m.add_argument("--dot-um", type=float, default=2.0, help="dot diameter (µm, default 2)")
    m.add_argument("--out", required=True, help="folder for pattern.json, pattern.gds, pattern.png")
    m.add_argument("--name", default="pattern", help="file stem (default: pattern)")


def decode_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("frames", nargs="+", help="image files: TIFF (one frame or a stack) or PNG, monochrome")
    p.add_argument("--pattern", required=True, help="the pattern file (calflow pattern make)")
    p.add_argument(
        "--pixel-um", type=float, help="pixel size in the object plane, µm (default: the default camera's)"
    )
    p.add_argument("--out", help="poses.csv or poses.nc (default: print CSV)")


def _range(text: str) -> tuple[float, float]:
    m = re.fullmatch(r"\s*([0-9.eE+-]+)\s*[xX×]\s*([0-9.eE+-]+)\s*", text)
    try:
        values = (float(m.group(1)), float(m.group(2))) if m else None
    except ValueError:
        values = None
    if not values or not all(v > 0 and math.isfinite(v) for v in values):
        raise CalflowError(
            f"--range: expected two positive lengths in µm as XxY (e.g. 9500x4200), got {text!r}"
        )
    return values


def run_pattern(args) -> None:
    from calflow.data.io import atomic_path
    from calflow.instruments.pattern.gds import write_gds, write_png
    from calflow.instruments.pattern.pattern import Pattern

    pattern = Pattern.make(range_um=_range(args.range), period_um=args.period_um, dot_diameter_um=args.dot_um)
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise CalflowError(f"{out}: is a file; expected a folder for the pattern's files")
    out.mkdir(parents=True, exist_ok=True)
    names = {k: out / f"{args.name}.{k}" for k in ("json", "gds", "png")}
    with atomic_path(names["json"]) as j, atomic_path(names["gds"]) as g, atomic_path(names["png"]) as p:
        pattern.save(j)
        write_gds(pattern, g)
        write_png(pattern, p)
    rx, ry = pattern.range_um
    fx, fy = pattern.min_fov_um
    print(
        f"{names['json']}: {pattern.shape[1]} × {pattern.shape[0]} dots of {pattern.dot_diameter_um:g} µm "
        f"every {pattern.period_um:g} µm, range {rx:g} × {ry:g} µm, field of view needed {fx:g} × {fy:g} µm; "
        f"{names['gds'].name}, {names['png'].name}"
    )


def run_decode(args) -> int:
    from calflow.instruments.pattern.decode import decode
    from calflow.instruments.pattern.frames import read_frames
    from calflow.instruments.pattern.pattern import Pattern

    if args.out and Path(args.out).suffix.lower() not in (".csv", ".nc"):
        raise CalflowError(f"--out {args.out}: expected a .csv or .nc file name")
    pattern = Pattern.load(args.pattern)
    frames, origin = read_frames(args.frames)
    kwargs = {"pixel_um": args.pixel_um} if args.pixel_um is not None else {}
    result = decode(frames, pattern, **kwargs)
    if args.out and args.out.lower().endswith(".nc"):
        _write_nc(result, origin, args)
    else:
        text = _csv(result, origin)
        if args.out:
            from calflow.data.io import write_text

            write_text(text, args.out)
        else:
            sys.stdout.write(text)
    bad = int((result.status != "ok").sum())
    if args.out:
        print(f"{args.out}: {len(result)} frames, {len(result) - bad} decoded, {bad} not", file=sys.stderr)
    return 0


def _csv(result, origin) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["file", "page", *FIELDS, "status", "reason"])
    for k, (path, page) in enumerate(origin):
        values = [getattr(result, f)[k] for f in FIELDS]
        w.writerow(
            [
                path,
                page,
                *("" if math.isnan(v) else f"{v:.6f}" for v in values),
                result.status[k],
                result.reason[k],
            ]
        )
    return buf.getvalue()


def _write_nc(result, origin, args) -> None:
    import numpy as np
    import xarray as xr

    from calflow import __version__
    from calflow.data.io import write_dataset

    units = {"x_um": "um", "y_um": "um", "theta_deg": "degree"}
    names = {"x_um": "x", "y_um": "y", "theta_deg": "theta"}
    data = {}
    for f in ("x_um", "y_um", "theta_deg"):
        data[f"meas_{names[f]}"] = (
            "frame",
            getattr(result, f),
            {"units": units[f], "long_name": f"decoded {names[f]} of the frame centre in the pattern frame"},
        )
        data[f"u_meas_{names[f]}"] = (
            "frame",
            getattr(result, "u_" + f),
            {
                "units": units[f],
                "long_name": f"standard uncertainty of the decoded {names[f]} (phase-plane fit)",
            },
        )
    data["decode_status"] = ("frame", np.asarray(result.status, dtype=str), {"long_name": "decoder status"})
    data["decode_reason"] = ("frame", np.asarray(result.reason, dtype=str), {"long_name": "why, when not ok"})
    data["file"] = ("frame", np.asarray([o[0] for o in origin], dtype=str), {"long_name": "image file"})
    data["page"] = (
        "frame",
        np.asarray([o[1] for o in origin], dtype=np.int32),
        {"long_name": "frame in the file", "units": "1"},
    )
    ds = xr.Dataset(
        data,
        coords={
            "frame": (
                "frame",
                np.arange(len(origin), dtype=np.int32),
                {"long_name": "frame index", "units": "1"},
            )
        },
        attrs={
            "Conventions": "CF-1.11",
            "calflow_kind": "decoded_frames",
            "calflow_version": __version__,
            "title": "poses decoded from frames of an encoded pattern",
            "pattern": str(args.pattern),
            "history": f"calflow {__version__}: decode",
        },
    )
    write_dataset(ds, args.out)
