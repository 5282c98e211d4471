"""calflow's Megarena decoder side by side with the Vernier library, on the same frames.

The library (C++, GPL-3.0, github.com/vernierlib/vernier) is built on your machine, outside
calflow, with a small program of yours (the *driver*) that calflow runs as::

    DRIVER decode PERIOD_UM CODE_DEPTH REPEAT FILE...

and that prints a CSV with the header ``file,found,x,y,alpha,pixelSize,ms``: per image the
library's ``MegarenaPatternDetector(period, depth)`` pose as ``get2DPose()`` gives it and its
mean time per ``compute`` over REPEAT runs after one warm-up (docs/benchmarks.md says how the
figures below were taken). Instead of a driver, ``--library-csv`` takes that CSV as written
before. The images are the user's (a lab's frames, or the library's own examples, GPL-3.0
data that stays outside calflow's repository).

``--truth CSV`` (``file,x,y,alpha,pixelSize``, the library's convention: frames the library
rendered with ``renderOrthographicProjection`` at poses you chose) adds each decoder's error
from the truth; ``--noise SEED`` first blurs the frames (Gaussian, ``--blur-px``) and adds
shot and read noise (``--electrons`` full well, ``--read-e``), writes them as 16-bit PNG to a
temporary folder, and gives both decoders those.

Speed: calflow's CPU time per frame in this process (one core) over the frames as given (a
new pixel size per frame builds a new plan of the phase planes) — the median of three passes,
each building its plans afresh, the frames stacked beforehand (a pass right after the
library's run can carry the kernel's reclaim of its memory as system time) — and over the frames of the
first one's size repeated to ``--throughput-frames`` one after the other (one camera: one
plan), against the driver's time per frame on one core (``OMP_NUM_THREADS=1``) on those
files. Then ``calflow decode`` itself, a new process as a user runs it, on a TIFF stack of those
``--throughput-frames`` frames with ``--jobs 0`` (every core) and ``--jobs 1``: its CPU time
(the process and its workers, from the OS: trustworthy on a loaded machine) and its wall time,
frames per second with and without its start-up (the same command on one frame). Frames per
second are the machine's only when nothing else runs: the 1-minute load before and after is
printed beside them, and the stderr lines say which figures hold.

    .venv/bin/python benchmarks/bench_megarena_vernier.py --period-um 9 --depth 12 \\
        --driver /path/to/driver --fit-region 0.5 --json IMAGE...

``--plane-weights uniform`` (with ``--fit-region 0.5``) gives calflow the library's estimand,
``calflow decode --convention vernier``'s; the default, calflow's lobe-power weights.
"""

from __future__ import annotations

import argparse
import csv
import importlib
import io
import json
import math
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from calflow.instruments.pattern.frames import read_frames
from calflow.instruments.pattern.megarena import MegarenaPattern, decode

megarena_decode = importlib.import_module("calflow.instruments.pattern.megarena.decode")  # its plans
PASSES = 3  # calflow's timed passes over the frames as given


def library_poses(args, files) -> dict[str, dict]:
    if args.library_csv:
        text = Path(args.library_csv).read_text()
    else:
        env = {**os.environ, "OMP_NUM_THREADS": "1"}
        cmd = [args.driver, "decode", f"{args.period_um:g}", str(args.depth), str(args.repeat), *files]
        text = subprocess.run(cmd, check=True, capture_output=True, text=True, env=env).stdout
    rows = {}
    for row in csv.DictReader(io.StringIO(text)):
        rows[Path(row["file"]).name] = {
            "found": row["found"].strip() in ("1", "true", "True"),
            **{k: float(row[k]) for k in ("x", "y", "alpha", "pixelSize", "ms")},
        }
    return rows


def noisy_copies(files, args, folder: Path) -> list[str]:
    from PIL import Image
    from scipy.ndimage import gaussian_filter

    rng = np.random.default_rng(args.noise)
    out = []
    frames, _ = read_frames(files)
    for path, frame in zip(files, frames):
        a = frame.astype(float)
        a = (a - a.min()) / max(np.ptp(a), 1e-30)
        a = gaussian_filter(a, args.blur_px)
        electrons = (0.1 + 0.8 * a) * args.electrons
        electrons += rng.standard_normal(a.shape) * np.sqrt(electrons + args.read_e**2)
        dn = np.clip(np.rint(electrons / args.electrons * 65535), 0, 65535).astype(np.uint16)
        target = folder / (Path(path).stem + "_noisy.png")
        Image.fromarray(dn).save(target)
        out.append(str(target))
    return out


def smoke_frames(folder: Path) -> list[str]:
    """``--smoke``: two small frames calflow's camera renders, their truth, and that truth as the
    library's CSV (no library needed: the script's whole path runs, on frames of known pose)."""
    import tifffile

    from calflow.instruments.pattern import Camera

    cam = Camera(width=384, height=336, sensor_pixel_um=5.0, magnification=10.0)
    pattern = MegarenaPattern(4.0, 6)
    rows = []
    for k, (x, y, theta) in enumerate([(300.0, 420.0, 33.0), (250.0, 380.0, -12.0)]):
        name = folder / f"smoke_{k}.tif"
        tifffile.imwrite(name, cam.render(pattern, x, y, theta, rng=k))
        t, half = math.radians(theta), 0.5 * cam.pixel_um  # the library's pose (docs/instruments.md)
        px, py = x + (math.cos(t) + math.sin(t)) * half, y + (math.cos(t) - math.sin(t)) * half
        rows.append(f"{name.name},1,{-px!r},{-py!r},{t!r},{cam.pixel_um!r},0")
    truth = "file,found,x,y,alpha,pixelSize,ms\n" + "\n".join(rows) + "\n"
    (folder / "truth.csv").write_text(truth)
    return [
        *(str(folder / f"smoke_{k}.tif") for k in range(2)),
        "--period-um", "4", "--depth", "6", "--library-csv", str(folder / "truth.csv"),
        "--truth", str(folder / "truth.csv"), "--fit-region", "1", "--throughput-frames", "4",
    ]  # fmt: skip


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if "--smoke" in argv:
        argv.remove("--smoke")
        with tempfile.TemporaryDirectory() as tmp:
            return main(smoke_frames(Path(tmp)) + argv)
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("images", nargs="+", help="image files (PNG, JPEG, TIFF) of one Megarena target")
    p.add_argument("--period-um", type=float, required=True)
    p.add_argument("--depth", type=int, required=True)
    p.add_argument("--driver", help="the program running the Vernier library (module docstring)")
    p.add_argument("--library-csv", help="the driver's CSV, written before (instead of --driver)")
    p.add_argument("--truth", help="CSV file,x,y,alpha,pixelSize of the poses the frames were rendered at")
    p.add_argument("--fit-region", type=float, default=0.5, help="calflow's fit region (0.5: as the library)")
    p.add_argument(
        "--plane-weights",
        choices=("power", "uniform"),
        default="power",
        help="calflow's phase-plane weights (uniform with --fit-region 0.5: the library's estimand)",
    )
    p.add_argument("--noise", type=int, help="seed: blur and add noise to the frames first")
    p.add_argument("--blur-px", type=float, default=1.0)
    p.add_argument("--electrons", type=float, default=20000.0)
    p.add_argument("--read-e", type=float, default=15.0)
    p.add_argument("--repeat", type=int, default=3, help="library runs per image, timed")
    p.add_argument("--throughput-frames", type=int, default=200)
    p.add_argument("--json", action="store_true", help="print one JSON object last")
    args = p.parse_args(argv)
    if not (args.driver or args.library_csv):
        p.error("one of --driver or --library-csv is needed")
    pattern = MegarenaPattern(args.period_um, args.depth)
    with tempfile.TemporaryDirectory() as tmp:
        files = [str(Path(f)) for f in args.images]
        if args.noise is not None:
            files = noisy_copies(files, args, Path(tmp))
        lib = library_poses(args, files)
        frames = [read_frames([f])[0][0] for f in files]  # of any size
        decode(frames[0], pattern, workers=1)  # warm-up: imports, plans
        # one call per frame size, as calflow decode reads a recording (the plans are per size)
        groups: dict = {}
        for k, f in enumerate(frames):
            groups.setdefault(f.shape, []).append(k)
        stacks = {tuple(ks): np.stack([frames[k] for k in ks]) for ks in groups.values()}
        passes = []  # three passes, each building its plans afresh as the first: their median
        for _ in range(PASSES):
            megarena_decode._fitter.cache_clear()
            t0 = time.process_time()
            parts = {
                ks: decode(
                    st, pattern, workers=1, fit_region=args.fit_region, plane_weights=args.plane_weights
                )
                for ks, st in stacks.items()
            }
            passes.append(1000 * (time.process_time() - t0) / len(frames))
        cpu_ms = float(np.median(passes))
    res = {key: np.empty(len(frames), dtype=object) for key in ("status", "reason")}
    ours = {key: np.empty(len(frames)) for key in ("x", "y", "alpha", "pixelSize")}
    for ks, r in parts.items():
        pose = r.library_pose()
        for key in res:
            res[key][list(ks)] = getattr(r, key)
        for key in ours:
            ours[key][list(ks)] = pose[key]
    truth = {}
    if args.truth:
        for row in csv.DictReader(open(args.truth)):
            truth[Path(row["file"]).stem] = {k: float(row[k]) for k in ("x", "y", "alpha", "pixelSize")}
    rows = []
    for k, path in enumerate(files):
        name = Path(path).name
        L = lib.get(name, {"found": False})
        row = {"file": name, "calflow_status": str(res["status"][k]), "calflow_reason": str(res["reason"][k])}
        row["calflow"] = {key: float(ours[key][k]) for key in ours}
        row["library"] = L
        if res["status"][k] == "ok" and L["found"]:
            row["difference"] = {
                "x_nm": 1000 * (row["calflow"]["x"] - L["x"]),
                "y_nm": 1000 * (row["calflow"]["y"] - L["y"]),
                "alpha_urad": 1e6 * _wrap(row["calflow"]["alpha"] - L["alpha"]),
                "pixel_percent": 100 * (row["calflow"]["pixelSize"] / L["pixelSize"] - 1),
            }
        stem = Path(path).stem.removesuffix("_noisy")
        if stem in truth:
            T = truth[stem]
            for who, pose, found in (
                ("calflow", row["calflow"], res["status"][k] == "ok"),
                ("library", L, L["found"]),
            ):
                if found:
                    row[f"{who}_error"] = {
                        "x_nm": 1000 * (pose["x"] - T["x"]),
                        "y_nm": 1000 * (pose["y"] - T["y"]),
                        "alpha_urad": 1e6 * _wrap(pose["alpha"] - T["alpha"]),
                    }
        rows.append(row)
    # calflow decode on every core: the frames repeated
    first = np.stack([f for f in frames if f.shape == frames[0].shape])
    reps = max(1, math.ceil(args.throughput_frames / len(first)))
    many = np.concatenate([first] * reps)[: args.throughput_frames]
    # the same frames one after the other on one core, as a lab's camera gives them (one pixel
    # size: the phase planes' plan is built once), against the library's time on those files
    t0 = time.process_time()
    decode(many, pattern, workers=1, fit_region=args.fit_region, plane_weights=args.plane_weights)
    one_camera_ms = 1000 * (time.process_time() - t0) / len(many)
    same = [
        r["library"]["ms"]
        for r, f in zip(rows, frames)
        if f.shape == frames[0].shape and "ms" in r["library"]
    ]
    load_before = os.getloadavg()[0]
    cli = calflow_decode_cli(many, args)
    lib_ms = [r["library"]["ms"] for r in rows if "ms" in r["library"]]
    summary = {
        "frames": len(rows),
        "frame_shapes": sorted({tuple(f.shape) for f in frames}),
        "throughput_frame_shape": list(first.shape[1:]),
        "calflow_ok": int((res["status"] == "ok").sum()),
        "library_found": sum(bool(r["library"].get("found")) for r in rows),
        "max_abs_difference": _max_abs([r["difference"] for r in rows if "difference" in r]),
        "calflow_max_abs_error": _max_abs([r["calflow_error"] for r in rows if "calflow_error" in r]),
        "library_max_abs_error": _max_abs([r["library_error"] for r in rows if "library_error" in r]),
        "calflow_cpu_ms_per_frame": cpu_ms,
        "calflow_cpu_ms_per_frame_passes": passes,
        "library_ms_per_frame": float(np.mean(lib_ms)) if lib_ms else None,
        "speed_ratio": (float(np.mean(lib_ms)) / cpu_ms) if lib_ms else None,
        "calflow_cpu_ms_per_frame_one_camera": one_camera_ms,
        "speed_ratio_one_camera": (float(np.mean(same)) / one_camera_ms) if same else None,
        "calflow_decode": cli,
        "cores": _cores(),
        "load_1min": [load_before, os.getloadavg()[0]],
        "fit_region": args.fit_region,
        "plane_weights": args.plane_weights,
        "noise_seed": args.noise,
        "machine": f"{platform.machine()} {platform.processor() or ''} {platform.system()} Python {platform.python_version()}".strip(),
    }
    _speed_lines(summary)
    for r in rows:
        d = r.get("difference")
        tail = (
            f"dx {d['x_nm']:+8.1f} nm  dy {d['y_nm']:+8.1f} nm  dα {d['alpha_urad']:+8.1f} µrad  "
            f"dpix {d['pixel_percent']:+.4f} %"
            if d
            else f"calflow {r['calflow_status']} ({r['calflow_reason']}), library found={r['library'].get('found')}"
        )
        print(f"{r['file']}: {tail}", file=sys.stderr)
    print(
        json.dumps({"summary": summary, "frames": rows}, indent=1)
        if args.json
        else json.dumps(summary, indent=1)
    )
    return 0


def calflow_decode_cli(frames: np.ndarray, args) -> dict:
    """``calflow decode`` itself (a new process, as a user runs it) on a TIFF stack of these
    frames, on every core (``--jobs 0``) and on one: CPU seconds (the process and its workers,
    from the OS's accounting: trustworthy on a loaded machine) and wall seconds (frames per
    second: the machine's rate only when it is otherwise idle). The same command on the stack's
    first frame alone gives the start-up (interpreter, imports, pattern file), taken off for
    the rate after start-up."""
    import resource

    import tifffile

    def run(stack: Path, jobs: int) -> tuple[float, float]:
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        cmd = [str(Path(sys.executable).with_name("calflow")), "decode", str(stack), "--pattern"]
        cmd += [
            str(pattern_file),
            "--jobs",
            str(jobs),
            "--fit-region",
            f"{args.fit_region:g}",
            "--plane-weights",
            args.plane_weights,
            "--out",
            str(out),
        ]
        subprocess.run(cmd, check=True, capture_output=True)
        wall = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
        return wall, cpu

    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        pattern_file, out = folder / "megarena.json", folder / "poses.csv"
        pattern_file.write_text(
            json.dumps({"MegarenaPattern": {"period": args.period_um, "codeDepth": args.depth}})
        )
        tifffile.imwrite(folder / "one.tif", frames[:1], photometric="minisblack")
        tifffile.imwrite(folder / "stack.tif", frames, photometric="minisblack")
        n = len(frames)
        out_d = {"frames": n, "frame_shape": list(frames.shape[1:])}
        for jobs in (0, 1):
            start_wall, start_cpu = min(run(folder / "one.tif", jobs) for _ in range(2))
            wall, cpu = run(folder / "stack.tif", jobs)
            key = "all_cores" if jobs == 0 else "one_core"
            out_d[key] = {
                "wall_s": wall,
                "cpu_s": cpu,
                "cpu_ms_per_frame": 1000 * cpu / n,
                "frames_per_s": n / wall,
                "startup_wall_s": start_wall,
                "startup_cpu_s": start_cpu,
                "cpu_ms_per_frame_after_startup": 1000 * (cpu - start_cpu) / max(n - 1, 1),
                "frames_per_s_after_startup": (n - 1) / max(wall - start_wall, 1e-9),
            }
    return out_d


def _cores() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def _speed_lines(s: dict) -> None:
    """The speed figures in words on stderr: CPU time (trustworthy under load) apart from the
    rates (wall time: the machine's only when nothing else runs)."""
    c = s["calflow_decode"]
    load = s["load_1min"]
    say = lambda text: print(text, file=sys.stderr)  # noqa: E731
    passes = ", ".join(f"{v:.1f}" for v in s["calflow_cpu_ms_per_frame_passes"])
    say(
        f"CPU per frame, one core (trustworthy under load): calflow {s['calflow_cpu_ms_per_frame']:.1f} ms "
        f"(the median of passes {passes})"
    )
    if s["library_ms_per_frame"]:
        say(f"  the library {s['library_ms_per_frame']:.1f} ms: {s['speed_ratio']:.1f}x")
    if s["speed_ratio_one_camera"]:
        say(
            f"  one camera ({c['frames']} frames of one size in a row): calflow "
            f"{s['calflow_cpu_ms_per_frame_one_camera']:.1f} ms, {s['speed_ratio_one_camera']:.1f}x"
        )
    for key, what in (("all_cores", f"--jobs 0 ({s['cores']} cores)"), ("one_core", "--jobs 1")):
        r = c[key]
        say(
            f"calflow decode {what}, {c['frames']} frames: CPU {r['cpu_ms_per_frame']:.1f} ms a frame "
            f"({r['cpu_ms_per_frame_after_startup']:.1f} after start-up); wall {r['wall_s']:.2f} s, "
            f"{r['frames_per_s']:.0f} frames/s ({r['frames_per_s_after_startup']:.0f} after a start-up of "
            f"{r['startup_wall_s']:.2f} s)"
        )
    say(
        f"1-minute load {load[0]:.1f} before, {load[1]:.1f} after on {s['cores']} cores: "
        + (
            "rates are the machine's"
            if max(load) < 0.5
            else "rates (wall time) are NOT the machine's; CPU times are"
        )
    )


def _wrap(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi


def _max_abs(items: list[dict]) -> dict | None:
    if not items:
        return None
    return {k: max(abs(i[k]) for i in items) for k in items[0]}


if __name__ == "__main__":
    sys.exit(main())
