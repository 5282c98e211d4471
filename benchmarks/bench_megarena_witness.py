"""A witness of a Megarena frame's pose that owes nothing to either decoder's phase fit: the
dots' own centroids, and the lattice they trace.

Each dot the lattice predicts (calflow's coarse lattice only numbers the dots and seeds the
search) is located by a Gaussian-weighted centroid, iterated until the window is centred on the
dot itself (so the prediction does not pull it), on the frame less its smooth background
(``background``: a grey opening that cuts the dots off, smoothed): a background sloping across a
dot's window — the illumination's fall-off — pulls a centroid uphill where the lobes' band-passed
phase does not see it (on the library's 12-bit example, 15 nm; ``unflattened`` in the JSON is
the estimand from the centroids as they were). Two witnesses follow.

One affine lattice over the central half (``witness``): c_k = o + s_k·u + t_k·v by least
squares, (s_k, t_k) the dot's lattice indices; the residuals' rms says how well one lattice
fits the frame (a few thousandths of a pixel on a render), the same fit on each quarter how
much the lattice's direction varies across it.

The decoders' estimand (``estimand_pose``, megarena_estimand): on a distorted frame the pose
both decoders give is a mean lattice over the library's central half, Eq. (1) there; the dots
estimate it through a polynomial map of the lattice (degree by cross-validation) and its
uniform plane over that region, with a bootstrap uncertainty; beside it the same plane through
the library's band-pass, through calflow's, with calflow's lobe-power weights, and shifted by
the dots' asymmetry (where the lobes' phase puts a dot against its centroid): what each
decoder's own choices make of the same frame. ``--calflow-weights uniform`` adds calflow's own
pose with equal weights over the central half (``decode(…, plane_weights="uniform")``, the
library's estimand).

``--truth CSV`` checks the witness on frames of known pose: ``file,alpha`` (radians) for the
affine witness; ``file,x,y,alpha,pixelSize`` in the library's convention for the estimand (the
library's renders, or make_distorted_megarena.py's frames through a known distortion, whose
truth is Eq. (1) itself). ``--library-csv`` (the driver's CSV, bench_megarena_vernier.py) adds
the library's pose. The images are the user's (GPL-3.0 data stays outside calflow).

    .venv/bin/python benchmarks/bench_megarena_witness.py --period-um 9 --depth 12 \\
        --library-csv library.csv --calflow-weights uniform --json IMAGE...
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
import tempfile
from pathlib import Path

import numpy as np

from calflow.instruments.pattern.frames import read_frames
from calflow.instruments.pattern.megarena import MegarenaPattern, decode
from calflow.instruments.pattern.phase import CROP, GAUSS

sys.path.insert(0, str(Path(__file__).resolve().parent))
import megarena_estimand as me  # noqa: E402
from megarena_dots import MARGIN, REGION, background, dots, lattice  # noqa: E402


def _wrap(a):
    return (np.asarray(a) + math.pi) % (2 * math.pi) - math.pi


def witness(frame: np.ndarray, depth: int) -> dict:
    """The dots' lattice over the central half: per lattice vector (u along s, v along t) its
    direction (rad, atan2 in pixel coordinates) and uncertainty, the fit's rms (pixels), the
    number of dots, and the directions fitted on each quarter of the region."""
    h, w = frame.shape
    rc = np.array([(w - 1) / 2, (h - 1) / 2])
    s, t, c, period, _ = dots(frame, depth)
    A = np.stack([np.ones_like(s), s, t], 1)

    def fit(m):
        coef, *_ = np.linalg.lstsq(A[m], c[m], rcond=None)
        return coef

    coef = fit(np.ones(len(c), bool))
    res = c - A @ coef
    var = (res**2).sum(axis=0) / max(len(c) - 3, 1)
    cov = np.linalg.inv(A.T @ A)
    out = {"dots": int(len(c)), "rms_px": float(np.sqrt(var.mean())), "period_px": period}
    for k, name in ((1, "u"), (2, "v")):
        vec = coef[k]
        a = math.atan2(vec[1], vec[0])
        normal = np.array([-math.sin(a), math.cos(a)])
        out[name] = (a, math.sqrt(float((normal**2 * var).sum() * cov[k, k] / (vec @ vec))))
        quarters = []
        for sx in (-1, 1):
            for sy in (-1, 1):
                m = (np.sign(c[:, 0] - rc[0]) == sx) & (np.sign(c[:, 1] - rc[1]) == sy)
                q = fit(m)[k] if m.sum() > 10 else np.array([np.nan, np.nan])
                quarters.append(math.atan2(q[1], q[0]))
        out[name + "_quarters"] = quarters
    return out


def x_axis(w: dict, theta_x: float) -> tuple[float, float, list[float]]:
    """The witness's direction of the pattern's x axis: the lattice vector (either sign, either
    handedness of the pixel axes) whose direction is nearest calflow's — calflow only names the
    axis; the angle is the dots'. Returns (angle, uncertainty, quarters), radians."""
    best = min(
        (abs(float(_wrap(sign * w[n][0] + turn - theta_x))), n, sign, turn)
        for n in ("u", "v")
        for sign in (1, -1)
        for turn in (0.0, math.pi)
    )
    _, n, sign, turn = best
    return (
        float(_wrap(sign * w[n][0] + turn)),
        w[n][1],
        [float(_wrap(sign * q + turn)) for q in w[n + "_quarters"]],
    )


#: the estimand again from centroids of a narrower and a wider window (σ in periods; 0.2 the witness's)
WINDOWS = {"centroid_narrow": 0.12, "centroid_wide": 0.3}


def estimand_pose(frame: np.ndarray, period_um: float, depth: int, reference: dict, boot: int = 200) -> dict:
    """Eq. (1)–(2) of megarena_estimand from the dots: the pose in the library's convention
    (positions moved by whole periods to lie nearest ``reference``, a decoder's library-convention
    pose, whose ``alpha`` also names the x axis), with the bootstrap's standard deviations, the
    same with the next degree of map, and — to say where a decoder's own weighting takes it — the
    plane through the library's band-pass (Gaussian of 3 bins), through calflow's (its ``GAUSS``
    and ``CROP``) and with calflow's lobe-power weights over its coarse samples."""
    s, t, c, period_px, bright = dots(frame, depth, region=me.CROP + MARGIN)
    st = np.stack([s, t], 1)
    degree, errors = me.cv_degree(c, st, frame.shape)
    e = me.estimand(c, st, frame.shape, degree, boot=boot)
    axes = me.match_axes(e["plane"], reference["alpha"])
    offset = 0.0 if bright else 0.5

    def pose(plane):
        q = me.library_pose(plane, period_um, axes, offset)
        q["x"], q["y"] = (
            me.near(q["x"], reference["x"], period_um),
            me.near(q["y"], reference["y"], period_um),
        )
        return q

    def window(sigma):  # the same map's degree on centroids of another Gaussian window
        s, t, c, *_ = dots(frame, depth, region=me.CROP + MARGIN, sigma_periods=sigma)
        return me.estimand(c, np.stack([s, t], 1), frame.shape, degree, boot=0)["plane"]

    best = pose(e["plane"])
    reps = [pose(b) for b in e["boot"]]
    h, w = frame.shape
    lib_sigma = (w / (2 * math.pi * 3), h / (2 * math.pi * 3))
    cal_sigma = (GAUSS / (2 * math.pi * CROP / period_px),) * 2
    *_, pts, power = lattice(frame.astype(float), depth, fields=True)
    m = e["map"]
    img = frame.astype(float) if bright else frame.max() - frame.astype(float)
    delta = me.dot_phase_offset(img - background(img, period_px), m, c, st, period_px)
    shifted = e["plane"].copy()
    shifted[:, 0] -= delta  # the lobes' phase lattice: the centroids' less the dots' asymmetry
    # the same dots' centroids on the frame as it is, its background's slope left in them
    s0, t0, c0, *_ = dots(frame, depth, region=me.CROP + MARGIN, flatten=False)
    st0 = np.stack([s0, t0], 1)
    unflattened = me.estimand(c0, st0, frame.shape, me.cv_degree(c0, st0, frame.shape)[0], boot=0)["plane"]
    return {
        "dots": int(len(c)),
        "bright": bright,
        "degree": degree,
        "cv_rms_px": {d: v * period_px for d, v in errors.items()},
        "rms_px": e["rms"] * period_px,
        "pose": best,
        "u": {k: float(np.std([r[k] for r in reps], ddof=1)) for k in best},
        "next_degree": pose(me.estimand(c, st, frame.shape, degree + 1, boot=0)["plane"]),
        "library_bandpass": pose(me.smoothed_plane(m, frame.shape, lib_sigma)),
        "calflow_bandpass": pose(me.smoothed_plane(m, frame.shape, cal_sigma)),
        "calflow_weights": pose(me.weighted_plane(m, pts, power, frame.shape)),
        "dot_offset_periods": [float(d) for d in delta],
        "dot_asymmetry": pose(shifted),
        "unflattened": pose(unflattened),
        "dot_asymmetry_field": pose(
            e["plane"]
            - me.dot_phase_plane(img - background(img, period_px), m, c, st, period_px, frame.shape)
        ),
        **{name: pose(window(sigma)) for name, sigma in WINDOWS.items()},
    }


def smoke(folder: Path) -> list[str]:
    """``--smoke``: two frames calflow's camera renders at known angles, and that truth."""
    import tifffile

    from calflow.instruments.pattern import Camera

    cam = Camera(width=384, height=336, sensor_pixel_um=5.0, magnification=10.0)
    rows = []
    for k, (x, y, theta) in enumerate([(300.0, 420.0, 33.0), (250.0, 380.0, -12.0)]):
        tifffile.imwrite(folder / f"smoke_{k}.tif", cam.render(MegarenaPattern(4.0, 6), x, y, theta, rng=k))
        rows.append(f"smoke_{k}.tif,{math.radians(theta)!r}")
    (folder / "truth.csv").write_text("file,alpha\n" + "\n".join(rows) + "\n")
    files = [str(folder / f"smoke_{k}.tif") for k in range(2)]
    return [*files, "--period-um", "4", "--depth", "6", "--truth", str(folder / "truth.csv")]


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if "--smoke" in argv:
        argv.remove("--smoke")
        with tempfile.TemporaryDirectory() as tmp:
            return main(smoke(Path(tmp)) + argv)
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("images", nargs="+")
    p.add_argument("--period-um", type=float, required=True)
    p.add_argument("--depth", type=int, required=True)
    p.add_argument("--truth", help="CSV file,alpha (radians): the angles the frames were rendered at")
    p.add_argument("--library-csv", help="the Vernier driver's CSV (file,found,x,y,alpha,pixelSize,ms)")
    p.add_argument(
        "--calflow-weights",
        action="append",
        default=[],
        choices=("uniform",),
        help="also calflow's pose with these plane weights over the central half (uniform: the library's estimand)",
    )
    p.add_argument("--boot", type=int, default=200, help="bootstrap replicates of the dots' estimand")
    p.add_argument("--json", action="store_true")
    args = p.parse_args(argv)
    pattern = MegarenaPattern(args.period_um, args.depth)
    read = lambda path: {Path(r["file"]).name: r for r in csv.DictReader(open(path))} if path else {}  # noqa: E731
    truth, library = read(args.truth), read(args.library_csv)
    rows = []
    for path in args.images:
        frame = read_frames([path])[0][0]
        r = decode(frame, pattern, fit_region=REGION)
        name = Path(path).name
        row = {"file": name, "calflow_status": str(r.status[0])}
        if r.status[0] == "ok":
            ours = math.radians(float(r.theta_x_deg[0]))
            w = witness(frame, pattern.depth)
            angle, u, quarters = x_axis(w, ours)
            row |= {
                "dots": w["dots"],
                "rms_px": w["rms_px"],
                "witness_alpha": angle,
                "u_witness_urad": 1e6 * u,
            }
            row["quarters_minus_witness_urad"] = [1e6 * float(_wrap(q - angle)) for q in quarters]
            row["calflow_minus_witness_urad"] = 1e6 * float(_wrap(ours - angle))
            lib = library.get(name)
            if lib and lib["found"].strip() in ("1", "true", "True"):
                row["library_minus_witness_urad"] = 1e6 * float(_wrap(float(lib["alpha"]) - angle))
            ours_lib = {k: float(v[0]) for k, v in r.library_pose().items()}
            ref = ours_lib
            lib_pose = None
            if lib and lib["found"].strip() in ("1", "true", "True"):
                lib_pose = {k: float(lib[k]) for k in ("x", "y", "alpha", "pixelSize")}
                ref = lib_pose
            est = estimand_pose(frame, args.period_um, pattern.depth, ref, boot=args.boot)
            E = est["pose"]
            row["estimand"] = {
                **{
                    k: est[k]
                    for k in ("dots", "bright", "degree", "cv_rms_px", "rms_px", "dot_offset_periods")
                },
                "u": {
                    "x_nm": 1000 * est["u"]["x"],
                    "y_nm": 1000 * est["u"]["y"],
                    "alpha_urad": 1e6 * est["u"]["alpha"],
                    "pixel_percent": 100 * est["u"]["pixelSize"] / E["pixelSize"],
                },
                "calflow_minus": me.differences(ours_lib, E),
                **({"library_minus": me.differences(lib_pose, E)} if lib_pose else {}),
                **{
                    k + "_minus": me.differences(est[k], E)
                    for k in (
                        "next_degree",
                        "library_bandpass",
                        "calflow_bandpass",
                        "calflow_weights",
                        "dot_asymmetry",
                        "unflattened",
                        "dot_asymmetry_field",
                        *WINDOWS,
                    )
                },
            }
            reweighted = {}
            for mode in args.calflow_weights:
                q = decode(frame, pattern, fit_region=REGION, plane_weights=mode)
                if q.status[0] == "ok":
                    reweighted[mode] = {k: float(v[0]) for k, v in q.library_pose().items()}
                    row["estimand"][f"calflow_{mode}_minus"] = me.differences(reweighted[mode], E)
            if name in truth and "x" in truth[name]:
                T = {k: float(truth[name][k]) for k in ("x", "y", "alpha", "pixelSize")}
                T["x"], T["y"] = (
                    me.near(T["x"], E["x"], args.period_um),
                    me.near(T["y"], E["y"], args.period_um),
                )
                row["estimand"]["minus_truth"] = me.differences(E, T)
                row["estimand"]["u_over_error"] = {
                    k: abs(row["estimand"]["minus_truth"][k]) / max(row["estimand"]["u"][k], 1e-300)
                    for k in ("x_nm", "y_nm", "alpha_urad")
                }
                others = [(f"calflow_{mode}", q) for mode, q in reweighted.items()]
                for who, q in (("calflow", ours_lib), ("library", lib_pose), *others):
                    if q:
                        Tq = dict(
                            T,
                            x=me.near(T["x"], q["x"], args.period_um),
                            y=me.near(T["y"], q["y"], args.period_um),
                        )
                        row["estimand"][f"{who}_minus_truth"] = me.differences(q, Tq)
            if name in truth:
                row["witness_minus_truth_urad"] = 1e6 * float(_wrap(angle - float(truth[name]["alpha"])))
                row["calflow_minus_truth_urad"] = 1e6 * float(_wrap(ours - float(truth[name]["alpha"])))
        rows.append(row)
        brief = {k: v for k, v in row.items() if k not in ("file", "estimand", "quarters_minus_witness_urad")}
        print(
            f"{name}: "
            + ", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in brief.items()),
            file=sys.stderr,
        )
        for key, d in row.get("estimand", {}).items():
            if isinstance(d, dict) and "x_nm" in d:
                print(f"  {key}: " + ", ".join(f"{k} {v:+.4g}" for k, v in d.items()), file=sys.stderr)
    result = {"region": REGION, "frames": rows}
    if truth:
        result["summary"] = me.summary(rows)
        for who, d in result["summary"].items():
            print(
                f"{who}: " + ", ".join(f"{k} {v['mean']:+.4g} ± {v['sd']:.2g}" for k, v in d.items()),
                file=sys.stderr,
            )
    print(json.dumps(result, indent=1 if args.json else None))
    return 0


if __name__ == "__main__":
    sys.exit(main())
