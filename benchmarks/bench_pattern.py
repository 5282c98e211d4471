#!/usr/bin/env python
"""The encoded-pattern sensor: throughput, accuracy against the Cramér–Rao bound, robustness.

Sections (``--sections``, default all three):

* ``throughput``: 1024 × 768 frames (the default camera over the thesis's 9.5 × 4.2 mm pattern)
  decoded per second — in one process decoding with one FFT thread (``per_core``), with two
  processes of one thread each (``two_processes``), and in one process with two FFT threads
  (``one_process_two_threads``); the frames are rendered beforehand and reused, and decoding
  includes every step (spectrum to code). ``per_core_cpu_fps`` divides by the decoding
  process's CPU time instead of the wall clock, which other work on a shared machine inflates
  less. ``memory_per_frame_mb``: the peak of Python's traced
  allocations (numpy's included) while a chunk of frames is decoded, over the chunk's frames;
  ``thesis_frames_s``: the thesis's 16 446 frames at the two-process rate.
* ``accuracy``: ``--accuracy-frames`` frames at the default optics and noise, the pose stepped
  over one period in x and y (Θ uniform in ±1°): decoded − true, its standard deviation and
  bias per axis, and the Cramér–Rao bound of the phase-plane estimate computed per frame from
  the noise-free frame and the camera's noise (docs/instruments.md derives it); Θ's standard
  deviation and bound in µrad.
* ``robustness``: ``--robust-frames`` frames at random poses over the whole range and the
  whole turn of Θ, each with dust (Poisson, mean 3 particles of 5–40 µm; ``--dust-mean``,
  ``--dust-max-um`` for harsher), missing and extra
  dots (each rate uniform in 0–5 %, a new defect draw per frame), defocus (0–3 µm) and uneven
  light (0–40 % peak to peak): the fraction decoded to the right place (within a quarter
  period), the frames flagged and why, and the silent jumps (decoded "ok" but a period or
  more off) — which must be zero. By default on a 3 × 3-binned camera (341 × 256 pixels of
  1.125 µm: the same field of view, a ninth of the pixels) so that 20 000 frames run in
  minutes on a shared machine; ``--binning 1`` for 1024 × 768.

``--json`` prints one JSON line. The machine and its load average are printed with the figures.

    .venv/bin/python benchmarks/bench_pattern.py --json
"""

from __future__ import annotations

import argparse
import collections
import dataclasses
import json
import math
import multiprocessing
import os
import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_montecarlo import machine  # noqa: E402

from calflow.instruments.pattern import Camera, Pattern, decode  # noqa: E402
from calflow.instruments.pattern.phase import CROP  # noqa: E402

PATTERN_RANGE = (9500.0, 4200.0)
_STATE: dict = {}


def _pattern() -> Pattern:
    if "pattern" not in _STATE:
        _STATE["pattern"] = Pattern.make(range_um=PATTERN_RANGE)
    return _STATE["pattern"]


# -- throughput ------------------------------------------------------------------------------
def _decode_chunk(frames: np.ndarray) -> int:
    return int(decode(frames, _pattern(), Camera(), workers=1).ok.sum())


def throughput(n_frames: int, repeats: int) -> dict:
    pattern, cam = _pattern(), Camera()
    rng = np.random.default_rng(0)
    distinct = 32
    poses = np.c_[
        rng.uniform(0, 9500, distinct), rng.uniform(0, 4200, distinct), rng.uniform(-180, 180, distinct)
    ]
    base = cam.render_batch(pattern, poses, rng=1)
    frames = base[np.arange(n_frames) % distinct]
    decode(frames[:8], pattern, cam, workers=1)  # warm: imports, FFT plans, tables

    def best(fn):
        return min(_timed(fn) for _ in range(repeats))

    one = best(lambda: decode(frames, pattern, cam, workers=1))
    cpu = min(_cpu_timed(lambda: decode(frames, pattern, cam, workers=1)) for _ in range(repeats))
    threads = best(lambda: decode(frames, pattern, cam, workers=2))
    halves = [frames[: n_frames // 2], frames[n_frames // 2 :]]
    with multiprocessing.get_context("fork").Pool(2) as pool:
        pool.map(_decode_chunk, [f[:8] for f in halves])  # warm both workers
        two = best(lambda: pool.map(_decode_chunk, halves))
    tracemalloc.start()
    decode(frames[:8], pattern, cam, workers=1)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    rate2 = n_frames / two
    return {
        "frames": n_frames,
        "frame_shape": [cam.height, cam.width],
        "per_core_fps": round(n_frames / one, 1),
        "per_core_cpu_fps": round(n_frames / cpu, 1),
        "two_processes_fps": round(rate2, 1),
        "one_process_two_threads_fps": round(n_frames / threads, 1),
        "memory_per_frame_mb": round(peak / 8 / 2**20, 2),
        "thesis_frames_s": round(16446 / rate2, 1),
    }


def _cpu_timed(fn) -> float:
    t = time.process_time()
    fn()
    return time.process_time() - t


def _timed(fn) -> float:
    t = time.perf_counter()
    fn()
    return time.perf_counter() - t


# -- accuracy --------------------------------------------------------------------------------
def crb(cam: Camera, pattern: Pattern, pose) -> tuple[float, float, float]:
    """Cramér–Rao bounds (x µm, y µm, Θ rad) of the phase-plane estimate at a pose: the Fisher
    information the two fundamental lobes of the noise-free frame carry, under the camera's
    shot, read and quantisation noise (docs/instruments.md, "Cramér–Rao bound")."""
    expect = cam.expectation(pattern, *pose).astype(np.float64)
    gain = cam.full_well_e / cam.max_level
    var = expect / gain + (cam.read_noise_e / gain) ** 2 + 1 / 12  # DN² per pixel
    h, w = expect.shape
    spec = np.fft.fft2(expect - expect.mean())
    fi = np.fft.fftfreq(h)[:, None]
    fj = np.fft.fftfreq(w)[None, :]
    t = math.radians(pose[2])
    f0 = cam.pixel_um / pattern.period_um
    X = (np.arange(w) - (w - 1) / 2)[None, :] * cam.pixel_um
    Y = (np.arange(h) - (h - 1) / 2)[:, None] * cam.pixel_um
    info = []
    dtheta = np.zeros((h, w))
    for direction, du_dtheta in (
        ((math.cos(t), math.sin(t)), (-math.sin(t) * X + math.cos(t) * Y) / pattern.period_um),
        ((-math.sin(t), math.cos(t)), (-math.cos(t) * X - math.sin(t) * Y) / pattern.period_um),
    ):
        kx, ky = direction[0] * f0, direction[1] * f0
        lobe = np.hypot(fj - kx, fi - ky) < CROP * f0
        z = np.fft.ifft2(np.where(lobe, spec, 0)) * 2  # the lobe's analytic signal a·e^{iΦ}
        dphi = -z.imag  # ∂I/∂φ of the fundamental
        info.append(np.sum(dphi**2 / var))
        dtheta += dphi * 2 * np.pi * du_dtheta
    jx, jy = info
    return (
        pattern.period_um / (2 * np.pi) / math.sqrt(jx),
        pattern.period_um / (2 * np.pi) / math.sqrt(jy),
        1 / math.sqrt(np.sum(dtheta**2 / var)),
    )


def accuracy(n_frames: int) -> dict:
    pattern, cam = _pattern(), Camera()
    rng = np.random.default_rng(2)
    p = pattern.period_um
    steps = (np.arange(n_frames) + 0.5) / n_frames
    poses = np.c_[4000 + p * steps, 2000 + p * rng.permutation(steps), rng.uniform(-1, 1, n_frames)]
    d = decode(cam.render_batch(pattern, poses, rng=3), pattern, cam, workers=1)
    ok = d.ok
    ex = (d.x_um - poses[:, 0])[ok] * 1e3
    ey = (d.y_um - poses[:, 1])[ok] * 1e3
    et = np.radians((d.theta_deg - poses[:, 2] + 180) % 360 - 180)[ok] * 1e6
    bounds = np.array([crb(cam, pattern, poses[k]) for k in np.flatnonzero(ok)[:: max(1, ok.sum() // 10)]])
    cx, cy, ct = np.sqrt(np.mean(bounds**2, axis=0)) * [1e3, 1e3, 1e6]
    return {
        "frames": n_frames,
        "decoded": int(ok.sum()),
        "x_sigma_nm": round(float(ex.std(ddof=1)), 4),
        "x_bias_nm": round(float(ex.mean()), 4),
        "x_crb_nm": round(float(cx), 4),
        "x_sigma_over_crb": round(float(ex.std(ddof=1) / cx), 2),
        "y_sigma_nm": round(float(ey.std(ddof=1)), 4),
        "y_bias_nm": round(float(ey.mean()), 4),
        "y_crb_nm": round(float(cy), 4),
        "y_sigma_over_crb": round(float(ey.std(ddof=1) / cy), 2),
        "theta_sigma_urad": round(float(et.std(ddof=1)), 3),
        "theta_bias_urad": round(float(et.mean()), 3),
        "theta_crb_urad": round(float(ct), 3),
        "reported_u_x_nm": round(float(np.mean(d.u_x_um[ok]) * 1e3), 4),
        "reported_u_theta_urad": round(float(np.radians(np.mean(d.u_theta_deg[ok])) * 1e6), 3),
    }


# -- robustness ------------------------------------------------------------------------------
def _robust_chunk(args) -> list:
    seed, count, binning, dust_mean, dust_max = args
    pattern = _pattern()
    base = Camera(width=1024 // binning, height=768 // binning, sensor_pixel_um=3.75 * binning)
    rng = np.random.default_rng(seed)
    frames, poses = [], []
    for _ in range(count):
        cam = dataclasses.replace(
            base,
            dust_count=dust_mean,
            dust_size_um=float(rng.uniform(5, dust_max)),
            missing_dot_rate=float(rng.uniform(0, 0.05)),
            extra_dot_rate=float(rng.uniform(0, 0.05)),
            defect_seed=int(rng.integers(2**31)),
            defocus_um=round(float(rng.uniform(0, 3)), 1),  # in 0.1 µm steps: blur tables reused
            illumination_nonuniformity=round(float(rng.uniform(0, 0.4)), 2),
        )
        pose = (rng.uniform(0, 9500), rng.uniform(0, 4200), rng.uniform(-180, 180))
        frames.append(cam.render(pattern, *pose, rng=rng))
        poses.append(pose)
    poses = np.array(poses)
    d = decode(np.stack(frames), pattern, base, workers=1)  # the decoder sees only the frames
    err = np.where(d.ok, np.maximum(np.abs(d.x_um - poses[:, 0]), np.abs(d.y_um - poses[:, 1])), np.nan)
    return [(str(s), float(e)) for s, e in zip(d.status, err)]


def robustness(
    n_frames: int,
    binning: int,
    processes: int,
    seed: int = 1000,
    dust_mean: float = 3.0,
    dust_max: float = 40.0,
) -> dict:
    p = _pattern().period_um
    chunk = 50
    jobs = [
        (seed + i, min(chunk, n_frames - i * chunk), binning, dust_mean, dust_max)
        for i in range(math.ceil(n_frames / chunk))
    ]
    t = time.perf_counter()
    with multiprocessing.get_context("fork").Pool(processes) as pool:
        results = []
        for part in pool.imap_unordered(_robust_chunk, jobs):
            results += part
            bad = sum(s == "ok" and not e < p / 4 for s, e in part)
            flagged = sum(s != "ok" for s, _ in part)
            print(
                f"robustness: {len(results)} frames, +{flagged} flagged, +{bad} jumps",
                file=sys.stderr,
                flush=True,
            )
    wall = time.perf_counter() - t
    status = collections.Counter(s for s, _ in results)
    errors = np.array([e for s, e in results if s == "ok"])
    right = int(np.sum(errors < p / 4))
    return {
        "frames": len(results),
        "frame_shape": [768 // binning, 1024 // binning],
        "pixel_um": 0.375 * binning,
        "right": right,
        "right_fraction": round(right / len(results), 6),
        "flagged": {k: v for k, v in sorted(status.items()) if k != "ok"},
        "silent_jumps": int(np.sum(errors >= p / 4)),
        "max_error_ok_nm": round(float(errors.max() * 1e3), 3) if len(errors) else None,
        "p99_error_ok_nm": round(float(np.percentile(errors, 99) * 1e3), 3) if len(errors) else None,
        "wall_s": round(wall, 1),
        "processes": processes,
        "seed": seed,
        "dust_mean": dust_mean,
        "dust_max_um": dust_max,
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sections", default="throughput,accuracy,robustness")
    ap.add_argument("--frames", type=int, default=200, help="frames decoded in the throughput section")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--accuracy-frames", type=int, default=200)
    ap.add_argument("--robust-frames", type=int, default=20000)
    ap.add_argument("--binning", type=int, default=3, help="robustness frames binned n × n (1: 1024 × 768)")
    ap.add_argument("--processes", type=int, default=2)
    ap.add_argument("--seed", type=int, default=1000, help="first seed of the robustness frames' chunks")
    ap.add_argument("--dust-mean", type=float, default=3.0, help="mean dust particles per robustness frame")
    ap.add_argument("--dust-max-um", type=float, default=40.0, help="largest dust shadow (µm)")
    ap.add_argument(
        "--smoke",
        action="store_true",
        help="small sizes for CI: 5 frames, 1 repeat, 5 accuracy frames, 20 robustness frames, 1 process",
    )
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    if args.smoke:
        args.frames, args.repeats, args.accuracy_frames, args.robust_frames, args.processes = 5, 1, 5, 20, 1
    sections = args.sections.split(",")
    out = {"machine": machine(), "load_before": list(os.getloadavg())}
    _pattern()
    if "throughput" in sections:
        out["throughput"] = throughput(args.frames, args.repeats)
    if "accuracy" in sections:
        out["accuracy"] = accuracy(args.accuracy_frames)
    if "robustness" in sections:
        out["robustness"] = robustness(
            args.robust_frames, args.binning, args.processes, args.seed, args.dust_mean, args.dust_max_um
        )
    out["load_after"] = list(os.getloadavg())
    if args.json:
        print(json.dumps(out))
    else:
        for key, value in out.items():
            print(f"{key}: {value}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
