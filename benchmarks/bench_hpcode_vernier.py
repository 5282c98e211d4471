"""calflow's HP-code markers side by side with the Vernier library on a sequence of frames.

The folder holds the frames (``Image<N>.png``, any image file calflow reads) and the
library's poses of two markers in ``results.csv`` as its test program writes them
(``image;no;x;y;alpha;pixelSize;no;x;y;alpha;pixelSize;``: the marker numbered 0, then the one
numbered 1, each as ``HPCodePatternDetector::get2DPose`` gives it). The library's test data
``test/data/Image140`` is such a folder (GPL-3.0 data: it stays outside calflow's
repository; give its path). ``--fixed`` names the marker that does not move (the reference),
``--moving`` the other.

Figures, over the frames results.csv lists:

* the moving marker's displacement in the fixed marker's frame, from the first listed frame,
  calflow − library: rms and largest (µm), its least-squares share of the travel and what is
  left without it, and the same for its turn (mrad) — calflow's relative poses at one pixel
  size for the sequence (``--pixel-um``, or the one calflow pools over the frames:
  :func:`~calflow.instruments.pattern.hpcode.pool_pixel`, with its uncertainty and drift test),
  and under ``frame_scale`` at each frame's own; each frame's pixel size's scatter and how the
  two markers' go together;
* the frames where the moving marker's lobes enter another bin of the spectrum of the
  library's snapshot (``--library-snapshot``, 512 pixels for Image140), from calflow's
  lattice, and the library − calflow turn's factor on the angle from each lobe to its bin
  (the library's band-pass is centred on the bin);
* the turn and the travel as the fiducials' centres alone show them (no phase fit: a coarse
  witness that owes nothing to either decoder's fine part), against each decoder's — the
  travel as the least-squares factor from the decoder's to the fiducials' — and each
  decoder's largest turn step from one frame to the next;
* the fixed marker's scatter (standard deviation of x and y over the frames, µm), calflow's
  and the library's: the set-up's repeatability as each decoder sees it;
* the markers found and numbers read in every frame of the folder, and calflow's CPU time per
  frame (one core; CPU time holds under load, wall time does not).

``--smoke`` renders a short sequence with calflow's own renderer (two markers, the second
moving and turning) and writes their true poses as the library would print them, so the whole
script runs with no library.

    .venv/bin/python benchmarks/bench_hpcode_vernier.py /path/to/vernier/test/data/Image140 \\
        --period-um 15.5 --size 17 --json
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import platform
import re
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from calflow.instruments.pattern.frames import read_frames
from calflow.instruments.pattern.hpcode import HPCodePattern, decode_markers, pool_pixel, relative
from calflow.instruments.pattern.stream import joined_markers


def library_rows(path: Path) -> dict[int, dict[int, np.ndarray]]:
    """results.csv → {image number: {marker number: (x, y, alpha, pixelSize)}}; the file's
    ``no`` columns are not the markers' numbers (its writer prints 0 for both): the first
    group is marker 0's, the second marker 1's."""
    out = {}
    with open(path, newline="") as fh:
        for row in csv.reader(fh, delimiter=";"):
            if not row or not row[0].strip().isdigit():
                continue
            vals = [float(v) for v in row[1:11]]
            out[int(row[0])] = {0: np.array(vals[1:5]), 1: np.array(vals[6:10])}
    return out


def _rot(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s], [s, c]]) if np.ndim(a) == 0 else np.stack([[c, -s], [s, c]]).transpose(2, 0, 1)


def library_relative(rows: dict[int, dict[int, np.ndarray]], frames, fixed: int, moving: int):
    """The moving marker's centre in the fixed marker's frame and its turn, from the library's
    poses: its centre sits at R(alpha)·(x, y) in the camera, so the offset is
    R(alpha_m − alpha_f)·p_m − p_f (µm) and the turn alpha_m − alpha_f (radian)."""
    pos, turn = [], []
    for f in frames:
        pf, pm = rows[f][fixed], rows[f][moving]
        pos.append(_rot(pm[2] - pf[2]) @ pm[:2] - pf[:2])
        turn.append(pm[2] - pf[2])
    return np.array(pos), np.array(turn)


def calflow_relative(rel) -> tuple[np.ndarray, np.ndarray]:
    """calflow's relative pose (the fixed marker's centre in the moving one's frame, Θ the
    moving marker's turn) → the moving marker's centre in the fixed one's frame: −R(Θ)·(x, y)."""
    theta = np.radians(rel.theta_deg)
    q = np.stack([rel.x_um, rel.y_um], axis=1)
    return -np.einsum("nij,nj->ni", _rot(theta), q), theta


def _without_jump(dturn: np.ndarray, lturn: np.ndarray) -> float:
    """rms of calflow − library turn (mrad) once the library's largest step between two listed
    frames is taken out of its series (the frames after it shifted back by that step less the
    median step), to tell a jump from a drift."""
    steps = np.diff(lturn)
    k = int(np.argmax(np.abs(steps)))
    shift = np.zeros_like(lturn)
    shift[k + 1 :] = steps[k] - np.median(steps)
    fixed = dturn + shift
    return float(1e3 * np.sqrt(np.mean((fixed - fixed.mean()) ** 2)))


def smoke_folder(folder: Path) -> list[str]:
    """``--smoke``: five frames of two markers calflow renders and their truth in results.csv."""
    from PIL import Image

    from calflow.instruments.pattern import Camera
    from calflow.instruments.pattern.hpcode.render import render

    cam = Camera(width=480, height=360)
    pattern = HPCodePattern(4.0, 17)
    lines = ["image;no;x;y;alpha;pixelSize;no;x;y;alpha;pixelSize;"]
    for k in range(5):
        poses = [(0, 40.0, -10.0, 3.0), (1, -30.0 + 0.4 * k, 12.0 - 0.3 * k, -2.0 + 0.05 * k)]
        Image.fromarray(render(cam, pattern, poses, rng=k)).save(folder / f"Image{k}.png")
        cells = []
        for _, x, y, th in poses:
            t = math.radians(th)  # the library's pose of the same marker (docs/instruments.md)
            lx = -(x + 0.5 * cam.pixel_um * (math.cos(t) + math.sin(t)))
            ly = -(y + 0.5 * cam.pixel_um * (math.cos(t) - math.sin(t)))
            cells.append(f"0;{lx!r};{ly!r};{t!r};{cam.pixel_um!r}")
        lines.append(f"{k};{';'.join(cells)};")
    (folder / "results.csv").write_text("\n".join(lines) + "\n")
    return [str(folder), "--period-um", "4", "--size", "17"]


def bin_pull(m, number: int, period_um: float, snapshot: int) -> tuple[float, tuple]:
    """Where the marker's two lobes fall in the spectrum of a ``snapshot``-pixel square (the
    library's snapshot): the mean over the lobes of the angle from each lobe's frequency to the
    nearest integer bin's (radian), and those bins — a band-pass centred on the bin, not on the
    lobe, pulls the angle towards the bin's and jumps when the lobe crosses into the next."""
    k = int(np.nonzero(m.number == number)[0][0])
    pull, bins = [], []
    for axis in ("x", "y"):
        t = math.radians(m.columns[f"theta_{axis}_deg"][k])
        f = snapshot * m.columns[f"pixel_{axis}_um"][k] / period_um  # bins from the centre
        u, v = f * math.cos(t), f * math.sin(t)
        if v < 0 or (v == 0 and u < 0):  # the half plane the spectrum keeps
            u, v = -u, -v
        bu, bv = round(u), round(v)
        pull.append((math.atan2(bv, bu) - math.atan2(v, u) + math.pi) % (2 * math.pi) - math.pi)
        bins.append((bu, bv))
    return float(np.mean(pull)), tuple(bins)


def figures(decoded, numbers, listed, lib, args, pixel_um) -> dict:
    """The comparison's figures over the listed frames, the relative poses at ``pixel_um`` (one
    pixel size for the sequence) or, when None, at each frame's own lattices."""
    fixed, rels, witness = [], [], []
    for m in decoded:
        fixed.append(m.of(args.fixed))
        rels.append(relative(m, args.moving, args.fixed, args.period_um, pixel_um))
        by_number = {int(n): k for k, n in enumerate(m.number)}
        i, j = by_number.get(args.moving), by_number.get(args.fixed)
        if i is None or j is None:
            witness.append((np.nan, np.full(2, np.nan)))
        else:  # the fiducials' turn, and the centres' offset in the fixed marker's axes (µm)
            t = math.radians(m.theta_fiducials_deg[j])
            off = [
                m.centre_fiducials_x_px[i] - m.centre_fiducials_x_px[j],
                m.centre_fiducials_y_px[i] - m.centre_fiducials_y_px[j],
            ]
            scale = pixel_um or 0.5 * (m.pixel_um[i] + m.pixel_um[j])
            turn = math.radians(m.theta_fiducials_deg[i] - m.theta_fiducials_deg[j])
            witness.append((turn, _rot(-t) @ np.array(off) * scale))

    def stack(parts):
        from calflow.instruments.pattern.decode import Decoded

        keys = ("x_um", "y_um", "theta_deg", "u_x_um", "u_y_um", "u_theta_deg", "status", "reason")
        return Decoded(**{k: np.concatenate([getattr(d, k) for d in parts]) for k in keys})

    fx, rel = stack(fixed), stack(rels)
    ok = [i for i in listed if rel.status[i] == "ok"]
    pos, turn = calflow_relative(rel)
    lpos, lturn = library_relative(lib, [numbers[i] for i in ok], args.fixed, args.moving)
    d = (pos[ok] - pos[ok][0]) - (lpos - lpos[0])
    dist = np.hypot(d[:, 0], d[:, 1])
    dturn = (turn[ok] - turn[ok][0]) - (lturn - lturn[0])
    fid = np.array([w[0] for w in witness])[ok]
    fid = fid - fid[0]
    fid_pos = np.array([w[1] for w in witness])[ok]
    fid_pos = fid_pos - fid_pos[0]

    def scale(p):  # the fiducials' travel as a fraction of a decoder's: least squares with an
        # offset, the fiducials' noise on the side it does not bias
        p, f = p - p.mean(axis=0), fid_pos - fid_pos.mean(axis=0)
        return float(np.sum(p * f) / np.sum(p * p))

    def along(p):  # the residual's least-squares factor on the library's travel, and what is
        # left once it is taken out (rms, µm): a scale difference, or noise
        t = lpos - lpos[0]
        k = float(np.sum(p * t) / np.sum(t * t))
        return k, float(np.sqrt(np.mean(np.sum((p - k * t) ** 2, axis=1))))

    lib_fixed = np.array([lib[numbers[i]][args.fixed][:2] for i in ok])
    # each marker's centre dot in the frame, pixels from (w/2, h/2): calflow's, and the library's
    # pose turned back into the frame at its own pixel size, R(alpha)·(x, y) / pixelSize
    h, w = decoded[ok[0]].shape
    centre_gap = 0.0
    for i in ok:
        m = decoded[i]
        for n in (args.fixed, args.moving):
            k = int(np.nonzero(m.number == n)[0][0])
            x, y, alpha, size = lib[numbers[i]][n]
            there = _rot(alpha) @ np.array([x, y]) / size
            here = np.array([m.centre_x_px[k] - w / 2, m.centre_y_px[k] - h / 2])
            centre_gap = max(centre_gap, float(np.hypot(*(here - there))))
    lib_pixel = np.array([[lib[numbers[i]][n][3] for n in (args.fixed, args.moving)] for i in ok])
    # the library's turn against where the markers' lobes fall in its snapshot's spectrum
    pulls = [
        [bin_pull(decoded[i], n, args.period_um, args.library_snapshot) for n in (args.moving, args.fixed)]
        for i in ok
    ]
    pull = np.array([m[0] - f[0] for m, f in pulls])
    moved = [numbers[ok[k + 1]] for k in range(len(ok) - 1) if pulls[k + 1][0][1] != pulls[k][0][1]]
    excess = (lturn - lturn[0]) - (turn[ok] - turn[ok][0])
    fit = np.polyfit(pull, excess, 1)
    factor, rest = along(d)
    return {
        "frames_compared": len(ok),
        "frames_not_decoded": [numbers[i] for i in listed if rel.status[i] != "ok"],
        "displacement_diff_rms_um": float(np.sqrt(np.mean(dist**2))),
        "displacement_diff_max_um": float(dist.max()),
        "displacement_diff_over_travel": factor,
        "displacement_diff_rms_um_without_scale": rest,
        "turn_diff_rms_mrad": float(1e3 * np.sqrt(np.mean(dturn**2))),
        "turn_diff_max_mrad": float(1e3 * np.abs(dturn).max()),
        # the largest change of the turn from one listed frame to the next, and where: a decoder
        # that jumps where the other does not is the one to doubt
        "turn_step_max_mrad_calflow": float(1e3 * np.abs(np.diff(turn[ok])).max()),
        "turn_step_max_mrad_library": float(1e3 * np.abs(np.diff(lturn)).max()),
        "turn_step_max_at_library": int(numbers[ok[int(np.argmax(np.abs(np.diff(lturn)))) + 1]]),
        "turn_diff_rms_mrad_without_library_jump": _without_jump(dturn, lturn),
        # the turn the fiducials' centres alone show (no phase fit; noisier): calflow − it and
        # library − it, rms about their means, and the library's drift from it
        "turn_vs_fiducials_rms_mrad_calflow": float(1e3 * np.std((turn[ok] - turn[ok][0]) - fid)),
        "turn_vs_fiducials_rms_mrad_library": float(1e3 * np.std((lturn - lturn[0]) - fid)),
        # each of calflow's two lobes alone against its turn (rms from frame to frame, mrad)
        "turn_lobes_vs_turn_rms_mrad_calflow": [
            float(1e3 * np.sqrt(np.mean(((lobe - lobe[0]) - (turn[ok] - turn[ok][0])) ** 2)))
            for lobe in (
                np.radians(
                    [
                        decoded[i].columns[f"theta_{a}_deg"][decoded[i].number == args.moving][0]
                        - decoded[i].columns[f"theta_{a}_deg"][decoded[i].number == args.fixed][0]
                        for i in ok
                    ]
                )
                for a in ("x", "y")
            )
        ],
        # calflow's lattice predicts the library's turn: the frames where the moving marker's
        # lobes enter another bin of the library's snapshot spectrum, the library − calflow
        # turn's factor on the bins' pull (moving − fixed), and what is left of it once the
        # pull is taken out (rms, mrad)
        "library_bin_changes_at": moved,
        "library_turn_excess_on_bin_pull": float(fit[0]),
        "library_turn_excess_rms_mrad_without_pull": float(1e3 * np.std(excess - np.polyval(fit, pull))),
        # the fiducials' travel (centres alone, at the same scale) over each decoder's
        "fiducials_travel_over": {"calflow": scale(pos[ok]), "library": scale(lpos)},
        "fiducials_travel_um": [float(v) for v in fid_pos[-1]],
        "turn_total_mrad": {
            "calflow": float(1e3 * (turn[ok][-1] - turn[ok][0])),
            "library": float(1e3 * (lturn[-1] - lturn[0])),
            "fiducials": float(1e3 * fid[-1]),
        },
        "relative_offset_mean_um": [float(v) for v in (pos[ok] - lpos).mean(axis=0)],
        "fixed_scatter_um_calflow": [float(np.std(fx.x_um[ok], ddof=1)), float(np.std(fx.y_um[ok], ddof=1))],
        "fixed_scatter_um_library": [float(v) for v in np.std(lib_fixed, axis=0, ddof=1)],
        "centres_px_calflow_vs_library_max": centre_gap,
        "library_pixel_um_markers": [float(v) for v in lib_pixel.mean(axis=0)],
        "library_pixel_um_scatter_rel": [
            float(v) for v in np.std(lib_pixel, axis=0, ddof=1) / lib_pixel.mean(axis=0)
        ],
        "fixed_u_um_calflow": [float(np.median(fx.u_x_um[ok])), float(np.median(fx.u_y_um[ok]))],
        "moving_travel_um": [float(v) for v in pos[ok][-1] - pos[ok][0]],
    }


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if "--smoke" in argv:
        argv.remove("--smoke")
        with tempfile.TemporaryDirectory() as tmp:
            return main(smoke_folder(Path(tmp)) + argv)
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("folder", help="frames Image<N>.png and the library's results.csv")
    p.add_argument("--period-um", type=float, required=True, help="the markers' period (µm)")
    p.add_argument(
        "--size", type=int, required=True, help="dots a side (the library's half periods + 1, halved)"
    )
    p.add_argument("--fixed", type=int, default=0, help="the fixed marker's number")
    p.add_argument("--moving", type=int, default=1, help="the moving marker's number")
    p.add_argument(
        "--pixel-um",
        type=float,
        help="the optics' pixel size (µm), the relative poses' scale; default: the one calflow pools "
        "over the frames (pool_pixel, as calflow decode --pixel-size sequence)",
    )
    p.add_argument(
        "--library-snapshot",
        type=int,
        default=512,
        help="the library's snapshot size (pixels) its results were made with (512 for Image140)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object last")
    args = p.parse_args(argv)
    folder = Path(args.folder)
    pattern = HPCodePattern(args.period_um, args.size)
    files = sorted(
        (f for f in folder.iterdir() if re.fullmatch(r"[A-Za-z_]*\d+\.(png|jpe?g|tiff?)", f.name, re.I)),
        key=lambda f: int(re.search(r"\d+", f.name).group()),
    )
    if not files:
        print(f"{folder}: no frames Image<N>.png", file=sys.stderr)
        return 1
    lib = library_rows(folder / "results.csv")
    numbers = [int(re.search(r"\d+", f.name).group()) for f in files]
    decoded, cpu = [], 0.0
    for f in files:
        frame = read_frames([f])[0]
        start = time.process_time()
        decoded.append(decode_markers(frame, pattern))
        cpu += time.process_time() - start
    listed = [i for i, n in enumerate(numbers) if n in lib]
    # one pixel size for the whole sequence: given (the optics'), or pooled by calflow's own
    # path over every frame of the folder from the two markers (calflow decode --pixel-size
    # sequence, a frames recording's pixel_size: sequence)
    pairs = np.array(
        [
            (m.pixel_um[m.number == args.fixed][0], m.pixel_um[m.number == args.moving][0])
            for m in (decoded[i] for i in listed)
            if {args.fixed, args.moving} <= set(m.number[m.status == "ok"].tolist())
        ]
    )
    pool = pool_pixel(joined_markers(decoded), [args.fixed, args.moving])
    sequence_pixel = args.pixel_um or pool.pixel_um
    summary = {
        "frames": len(files),
        "frames_listed": len(listed),
        "markers_per_frame": sorted({int((m.status == "ok").sum()) for m in decoded}),
        "numbers_read": sorted({int(n) for m in decoded for n in m.number[m.status == "ok"]}),
        "sequence_pixel_um": sequence_pixel,
        "sequence_pixel_given": args.pixel_um is not None,
        "pooled_pixel_um": pool.pixel_um,
        "pooled_u_pixel_um": pool.u_pixel_um,
        "pooled_frames": pool.n_frames,
        "pooled_rejected": list(pool.rejected),
        "pooled_n_eff": pool.n_eff,
        "pooled_drift_um": pool.drift_um,
        "pooled_u_drift_um": pool.u_drift_um,
        "pooled_drift_p": pool.drift_p,
        "pooled_statement": pool.statement,
        # each frame's own pixel size: its scatter over the sequence (relative), each marker's,
        # and how the two markers' estimates go together (one optics: a change of magnification
        # would move both alike)
        "frame_pixel_um_scatter_rel": [float(v) for v in np.std(pairs, axis=0, ddof=1) / pairs.mean(axis=0)],
        "frame_pixel_um_markers": [float(v) for v in pairs.mean(axis=0)],
        "frame_pixel_correlation": float(np.corrcoef(pairs.T)[0, 1]),
        "frame_pixel_u_rel": [
            float(np.median([m.u_pixel_um[m.number == n][0] / m.pixel_um[m.number == n][0] for m in decoded]))
            for n in (args.fixed, args.moving)
        ],
    }
    # headline: the relative poses at one pixel size for the sequence; then at each frame's own
    summary.update(figures(decoded, numbers, listed, lib, args, sequence_pixel))
    summary["frame_scale"] = figures(decoded, numbers, listed, lib, args, None)
    summary["cpu_s_per_frame"] = cpu / len(files)
    summary["load_1min"] = os.getloadavg()[0]
    summary["machine"] = f"{platform.machine()} {platform.system()} Python {platform.python_version()}"
    for k, v in summary.items():
        print(f"{k}: {v}")
    if summary["frames_compared"] < summary["frames_listed"]:
        print(f"frames listed but not decoded by calflow: {summary['frames_not_decoded']}")
    if args.json:
        print(json.dumps(summary, indent=1))
    return 0 if summary["frames_compared"] >= 2 else 1


if __name__ == "__main__":
    sys.exit(main())
