"""Megarena frames through a known lens distortion, and the quantity a decoder estimates on them.

calflow's camera renders the frame (noise-free), which is then resampled through a decentred
radial distortion (megarena_estimand.radial_map, its centre drawn anywhere in the frame, so that
the distortion tilts the central half's mean lattice as a real lens's does) and exposed (shot and
read noise, the camera's bit depth). The truth written beside the frames is Eq. (1)–(2) of
megarena_estimand — the uniform least-squares plane of the lattice's own coordinates over the
library's central half — computed from the render's pose and the map, pixel by pixel, in the
Vernier library's convention (``file,x,y,alpha,pixelSize``): what calflow, the library and the
dots' witness are each checked against.

    .venv/bin/python benchmarks/make_distorted_megarena.py OUT_FOLDER --frames 12 --k 0.002
    DRIVER decode 9 12 1 OUT_FOLDER/d*.tiff > library.csv
    .venv/bin/python benchmarks/bench_megarena_witness.py --period-um 9 --depth 12 \\
        --truth OUT_FOLDER/truth.csv --library-csv library.csv --json OUT_FOLDER/d*.tiff

``--map-from REAL_IMAGE`` renders a real frame's view through that frame's own distortion
instead (megarena_realmap): the dots' polynomial map of the real frame, its non-affine part
clamped to the dots' bounding box, the real frame's shear and curvature carried by the map
q of megarena_realmap's Eq. (1); the pose, size and pixel size are calflow's decoding of the
real frame (``--pose`` overrides the pose). The truth is again Eq. (1) of the render through q.
``--dot-diameter-um``, ``--defocus-um``, ``--bit-depth`` and ``--jpeg-quality`` vary what the
camera makes of the dots.

    .venv/bin/python benchmarks/make_distorted_megarena.py OUT --map-from REAL.jpg --period-um 9 \
        --depth 12 --frames 6 --bit-depth 8
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import megarena_estimand as me  # noqa: E402
import megarena_realmap as mr  # noqa: E402
from megarena_dots import MARGIN  # noqa: E402

from calflow.instruments.pattern import Camera  # noqa: E402
from calflow.instruments.pattern.megarena import MegarenaPattern  # noqa: E402


def lattice_affine(cam: Camera, pattern: MegarenaPattern, x: float, y: float, theta: float) -> np.ndarray:
    """The undistorted render's lattice coordinates (u, v) as affine functions of the pixel
    (x, y): (2, 3) rows [value at pixel (0, 0), slope along x, slope along y], from the
    camera's own object points (exact: the undistorted map is affine)."""
    U, V = cam.object_points(x + pattern.origin_um[0], y + pattern.origin_um[1], theta)
    U, V = np.broadcast_arrays(U, V)
    h, w = U.shape
    py, px = np.mgrid[0:h:7, 0:w:7]
    A = np.stack([np.ones(px.size), px.ravel(), py.ravel()], 1)
    L = np.stack([U[py, px].ravel(), V[py, px].ravel()], 1) / pattern.period_um
    return np.linalg.lstsq(A, L, rcond=None)[0].T


def distorted_frame(
    cam: Camera, pattern: MegarenaPattern, pose, centre, k: float, rng, qmap=None, light=None
):
    """One frame through the map (k, centre), or through ``qmap`` (p ↦ q) when given, its
    expected levels passed through ``light`` when given, and its truth in the library's
    convention."""
    x, y, theta = pose
    if qmap is None:
        qmap = me.radial_map((cam.height, cam.width), centre, k)
    expected = me.distort(cam.expectation(pattern, x, y, theta), qmap)
    frame = cam.expose(light(expected) if light else expected, rng)
    plane = me.true_plane(lattice_affine(cam, pattern, x, y, theta), qmap, frame.shape)
    truth = me.library_pose(plane, pattern.period_um, ((0, 1), (1, 1)), 0.0)
    return frame, truth


def real_view(path: str, pattern: MegarenaPattern, degree, region: float, clamp: bool = False):
    """The real frame's lattice (megarena_realmap) and calflow's decoding of it: its pose
    (calflow's convention), size (w, h) and pixel size; and the frame itself."""
    from calflow.instruments.pattern.frames import read_frames
    from calflow.instruments.pattern.megarena import decode

    frame = read_frames([path])[0][0]
    r = decode(frame, pattern)
    if r.status[0] != "ok":
        raise SystemExit(f"{path}: calflow does not decode it ({r.reason[0]}): no view to render")
    pose = (float(r.x_um[0]), float(r.y_um[0]), float(r.theta_x_deg[0]))
    real = mr.real_lattice(frame, pattern.depth, degree, region)
    if region < 1 and not clamp:
        real.outer = mr.real_lattice(frame, pattern.depth, None, 1.0)
    return real, pose, (frame.shape[1], frame.shape[0]), float(r.pixel_um[0]), frame


def write_frame(frame: np.ndarray, out: Path, n: int, quality: int | None) -> str:
    """The frame as d{n}.tiff, or d{n}.jpg at JPEG ``quality`` (PIL), through a temporary name."""
    name = f"d{n:02d}." + ("jpg" if quality else "tiff")
    tmp = out / (name + ".part")
    if quality:
        from PIL import Image

        Image.fromarray(frame).save(tmp, format="JPEG", quality=quality)
    else:
        import tifffile

        tifffile.imwrite(tmp, frame)
    tmp.replace(out / name)
    return name


def smoke(out: Path) -> int:
    """``--smoke OUT``: two small frames through a known radial map, then the first one's view
    re-rendered through the map its dots give (``--map-from``): the re-render's truth must be
    the original's — the machinery checked on a case whose answer is known."""
    import csv

    small = ["--period-um", "9", "--depth", "8", "--size", "512x512"]
    main([str(out), "--frames", "2", "--k", "0.003", "--seed", "3", *small])
    main([str(out / "mapped"), "--map-from", str(out / "d00.tiff"), "--frames", "1", "--seed", "4", *small])
    a, b = (next(csv.DictReader(open(f / "truth.csv"))) for f in (out, out / "mapped"))
    dx, dy = (1000 * abs(float(a[k]) - float(b[k])) for k in ("x", "y"))
    da = 1e6 * abs(float(a["alpha"]) - float(b["alpha"]))
    print(
        f"--map-from of a known radial map: truth moved by {dx:.2f} / {dy:.2f} nm, {da:.1f} µrad",
        file=sys.stderr,
    )
    return 0 if max(dx, dy) < 5 and da < 50 else 1


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if "--smoke" in argv:
        argv.remove("--smoke")
        return smoke(Path(argv[0]))
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("out", help="folder for the frames (d00.tiff, …) and truth.csv")
    p.add_argument("--frames", type=int, default=12)
    p.add_argument("--k", type=float, default=0.002, help="radial distortion at the half diagonal (relative)")
    p.add_argument("--period-um", type=float, default=9.0)
    p.add_argument("--depth", type=int, default=12)
    p.add_argument("--seed", type=int, default=5)
    p.add_argument("--size", default="1024x768", help="frame width x height, pixels")
    p.add_argument("--pixel-um", type=float, default=0.625, help="pixel size in the object plane")
    p.add_argument(
        "--pose",
        help="x,y,theta (µm, µm, degree; calflow's convention) for every frame, e.g. a real frame's "
        "decoded pose: noise draws of that view, the code in view as in the real frame",
    )
    p.add_argument(
        "--translations",
        action="store_true",
        help="one lens and one angle for every frame (the first frame's), the pattern only translated: a stage moving under a fixed camera",
    )
    p.add_argument(
        "--map-from",
        metavar="IMAGE",
        help="render IMAGE's view (calflow's decoded pose, its size and pixel size) through IMAGE's own "
        "lattice distortion, its dots' polynomial map (--k, --size, --pixel-um ignored)",
    )
    p.add_argument("--degree", type=int, help="the map's degree (default: cross-validated)")
    p.add_argument(
        "--map-region",
        type=float,
        default=me.CROP + MARGIN,
        help="the central fraction of IMAGE's sides whose dots fit the map (default: the witness's, so that "
        "the truth is the witness's estimand of IMAGE; 1: the whole frame)",
    )
    p.add_argument(
        "--clamp-outside",
        action="store_true",
        help="beyond the map's dots, continue its affine part with its non-affine part clamped "
        "(default: follow the whole frame's map, cross-validated degree, from the box's edge)",
    )
    p.add_argument(
        "--light-from-real",
        action="store_true",
        help="with --map-from: the real frame's background and dot-top fields (megarena_realmap.relight) "
        "instead of the camera's illumination",
    )
    p.add_argument("--bit-depth", type=int, default=12)
    p.add_argument("--dot-diameter-um", type=float, help="the dots' diameter (default: half the period)")
    p.add_argument("--defocus-um", type=float, default=0.0, help="the pattern's distance from focus (blur)")
    p.add_argument("--jpeg-quality", type=int, help="write JPEG at this quality (PIL; --bit-depth 8 only)")
    args = p.parse_args(argv)
    if args.jpeg_quality and args.bit_depth != 8:
        p.error("--jpeg-quality: expected --bit-depth 8 (JPEG frames are 8-bit)")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    pattern = MegarenaPattern(args.period_um, args.depth, dot_diameter_um=args.dot_diameter_um)
    rng = np.random.default_rng(args.seed)
    width, height = (int(v) for v in args.size.lower().split("x"))
    pixel_um, real = args.pixel_um, None
    if args.map_from:
        real, view, (width, height), pixel_um, levels = real_view(
            args.map_from, pattern, args.degree, args.map_region, args.clamp_outside
        )
        args.pose = args.pose or ",".join(repr(v) for v in view)
        print(
            f"{args.map_from}: {len(real.xy)} dots, degree {real.map.degree}, one lattice {real.rms_affine_px:.3f} px, "
            f"the map {real.rms_px:.3f} px, shear {mr.shear_deg(real.affine):+.3f}°, pose {args.pose}",
            file=sys.stderr,
        )
    cam = Camera(
        width=width,
        height=height,
        sensor_pixel_um=3.75,
        magnification=3.75 / pixel_um,
        bit_depth=args.bit_depth,
        defocus_um=args.defocus_um,
        illumination_nonuniformity=0.0 if args.light_from_real else 0.1,
    )
    light = None
    if args.light_from_real:
        if real is None:
            p.error("--light-from-real: expected --map-from IMAGE")
        scale = cam.max_level / (np.iinfo(levels.dtype).max if levels.dtype.kind in "ui" else 1.0)
        light = lambda e: mr.relight(e, levels, real.period_px, scale)  # noqa: E731
    side = pattern.size_um[0]
    rows = ["file,x,y,alpha,pixelSize,k,cx,cy,map_from,degree"]
    theta, centre = rng.uniform(-180, 180), (rng.uniform(0, cam.width - 1), rng.uniform(0, cam.height - 1))
    for n in range(args.frames):
        pose = (rng.uniform(0.2, 0.8) * side, rng.uniform(0.2, 0.8) * side, theta)
        if args.pose:
            pose = tuple(float(v) for v in args.pose.split(","))
        elif not args.translations:
            pose = (*pose[:2], rng.uniform(-180, 180))
            centre = (rng.uniform(0, cam.width - 1), rng.uniform(0, cam.height - 1))
        qmap = None
        if real is not None:
            qmap, R, k = mr.real_warp(real, lattice_affine(cam, pattern, *pose))
        frame, t = distorted_frame(cam, pattern, pose, centre, args.k, rng, qmap, light)
        name = write_frame(frame, out, n, args.jpeg_quality)
        source = (Path(args.map_from).name, real.map.degree) if real else ("", "")
        rows.append(
            f"{name},{float(t['x'])!r},{float(t['y'])!r},{float(t['alpha'])!r},{float(t['pixelSize'])!r},"
            + (f"0,,,{source[0]},{source[1]}" if real else f"{args.k!r},{centre[0]!r},{centre[1]!r},,")
        )
    (out / "truth.csv.part").write_text("\n".join(rows) + "\n")
    (out / "truth.csv.part").replace(out / "truth.csv")
    print(f"{args.frames} frames and truth.csv in {out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
