"""``calflow pattern make`` and ``calflow decode``: the pattern's files, and a lab's frames → poses."""

from __future__ import annotations

import csv
import io
import math
import re
import sys
from pathlib import Path

from calflow.errors import CalflowError

FIELDS = ("x_um", "y_um", "theta_deg", "u_x_um", "u_y_um", "u_theta_deg")


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

    if args.layout == "megarena":
        from calflow.instruments.pattern.megarena.commands import make_megarena

        rng = _range(args.range)
        return make_megarena(args, rng, output_names(args, ("json", "vernier.json", "gds", "png")))
    if args.depth is not None:
        raise CalflowError("--depth: only for --layout megarena")
    from calflow.instruments.pattern.gds import write_gds, write_png
    from calflow.instruments.pattern.pattern import Pattern

    period = 4.0 if args.period_um is None else args.period_um
    dot = period / 2 if args.dot_um is None else args.dot_um
    pattern = Pattern.make(range_um=_range(args.range), period_um=period, dot_diameter_um=dot)
    names = output_names(args)
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


def output_names(args, kinds=("json", "gds", "png")) -> dict:
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise CalflowError(f"{out}: is a file; expected a folder for the pattern's files")
    out.mkdir(parents=True, exist_ok=True)
    return {k: out / f"{args.name}.{k}" for k in kinds}


def run_decode(args) -> int:
    from calflow.instruments.pattern.layouts import load_pattern

    if args.out and Path(args.out).suffix.lower() not in (".csv", ".nc"):
        raise CalflowError(f"--out {args.out}: expected a .csv or .nc file name")
    pattern = load_pattern(args.pattern)
    megarena = pattern.layout == "megarena"
    if pattern.layout == "hpcode":
        return _decode_markers(args, pattern)
    if getattr(args, "pixel_size", "frame") != "frame":
        raise CalflowError(
            f"--pixel-size {args.pixel_size}: only for HP-code markers (this pattern's layout is {pattern.layout!r})"
        )
    plane = {"fit_region": args.fit_region, "plane_weights": getattr(args, "plane_weights", None)}
    if not megarena and (any(v is not None for v in plane.values()) or args.convention != "calflow"):
        raise CalflowError(
            "--fit-region, --plane-weights and --convention vernier: only for Megarena patterns"
        )
    if args.convention == "vernier" and args.out and args.out.lower().endswith(".nc"):
        raise CalflowError("--convention vernier: the .nc output keeps calflow's convention; write a .csv")
    kwargs = {"pixel_um": args.pixel_um} if args.pixel_um is not None else {}
    # read and decoded chunk by chunk on every core: the stack is never held whole
    from calflow.instruments.pattern.stream import decode_stream

    if megarena:  # the convention's estimand, unless given: the library's region and weights
        library = args.convention == "vernier"
        kwargs["fit_region"] = (
            plane["fit_region"] if plane["fit_region"] is not None else (0.5 if library else 1.0)
        )
        kwargs["plane_weights"] = plane["plane_weights"] or ("uniform" if library else "power")
    result, origin = decode_stream(args.frames, pattern, args.jobs, **kwargs)
    if args.out and args.out.lower().endswith(".nc"):
        _write_nc(result, origin, args)
    else:
        text = _csv(result, origin, args.convention)
        if args.out:
            from calflow.data.io import write_text

            write_text(text, args.out)
        else:
            sys.stdout.write(text)
    bad = int((result.status != "ok").sum())
    if args.out:
        print(f"{args.out}: {len(result)} frames, {len(result) - bad} decoded, {bad} not", file=sys.stderr)
    return 0


def _decode_markers(args, pattern) -> int:
    """HP-code markers: one CSV row per marker found (:mod:`.hpcode.table`)."""
    from calflow.instruments.pattern.hpcode.table import markers_csv
    from calflow.instruments.pattern.stream import markers_stream

    if args.fit_region is not None or getattr(args, "plane_weights", None) is not None:
        raise CalflowError(
            "--fit-region, --plane-weights: only for Megarena patterns (a marker is fitted on itself)"
        )
    if args.out and args.out.lower().endswith(".nc"):
        raise CalflowError(f"--out {args.out}: HP-code markers are written one row per marker; write a .csv")
    pooled = getattr(args, "pixel_size", "frame") == "sequence"
    if pooled and args.pixel_um is not None:
        raise CalflowError(
            f"--pixel-size sequence: pools the frames' own pixel sizes, but --pixel-um {args.pixel_um:g} gives "
            "one; expected one or the other"
        )
    found, origin = markers_stream(args.frames, pattern, args.jobs, pixel_um=args.pixel_um)
    if pooled:  # the frames' lattices rescaled to the sequence's pixel size, not decoded again
        from calflow.instruments.pattern.hpcode import at_scale, pool_pixel

        try:
            scale = pool_pixel(found)
        except ValueError as exc:
            raise CalflowError(f"--pixel-size sequence: {exc}") from None
        found = at_scale(found, scale.pixel_um, scale.u_pixel_um)
        print(f"{scale.statement} (trend against the frames' order as given)", file=sys.stderr)
    text = markers_csv(found, origin, args.convention)
    if args.out:
        from calflow.data.io import write_text

        write_text(text, args.out)
        ok = int((found.status == "ok").sum())
        print(
            f"{args.out}: {len(origin)} frames, {ok} markers decoded, {len(found) - ok} rows not",
            file=sys.stderr,
        )
    else:
        sys.stdout.write(text)
    return 0


def _csv(result, origin, convention: str = "calflow") -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    if convention == "vernier":
        columns = result.library_pose()
        fields = ("x", "y", "alpha", "pixelSize")
    else:
        columns = {f: getattr(result, f) for f in FIELDS}
        fields = FIELDS
        if getattr(result, "pixel_um", None) is not None:
            columns.update(pixel_um=result.pixel_um, u_pixel_um=result.u_pixel_um)
            fields = (*FIELDS, "pixel_um", "u_pixel_um")
    w.writerow(["file", "page", *fields, "status", "reason"])
    for k, (path, page) in enumerate(origin):
        values = [columns[f][k] for f in fields]
        w.writerow(
            [
                path,
                page,
                *(
                    "" if math.isnan(v) else f"{v:.6f}" if abs(v) >= 1e-3 or v == 0 else f"{v:.6g}"
                    for v in values
                ),
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
    if getattr(result, "pixel_um", None) is not None:  # a layout that measures the pixel size
        data["pixel_size"] = (
            "frame",
            np.asarray(result.pixel_um, dtype=float),
            {"units": "um", "long_name": "pixel size in the object plane, measured from the frame"},
        )
        data["u_pixel_size"] = (
            "frame",
            np.asarray(result.u_pixel_um, dtype=float),
            {"units": "um", "long_name": "standard uncertainty of the measured pixel size (phase-plane fit)"},
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
