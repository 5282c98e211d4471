"""Where a Megarena decoder's pose in the library's convention departs from the dots' estimand:
calflow's own phase samples against the dots' lattice map, and the library's estimator changed
one thing at a time.

calflow's samples. The decoder's phase planes (:class:`~calflow.instruments.pattern.phase.PhaseFitter`)
are fitted to each lobe's band-passed field z on a coarse grid; in the library's convention
(``fit_region=0.5, plane_weights="uniform"``) each sample is weighted by its cell's share of the
central half, samples whose |z| is below ``NO_LOBE`` of the region's median are left out, and
the code's envelope regressors ∇ln|z| are fitted beside the plane. Here the samples are taken
from the same plan as ``decode`` (its ``PhaseFitter`` and its first, whole-frame fit), each
lobe's absolute phase in periods,

    Φ_j(r)/2π = arg z_j(r)/2π + b_j·r        (b_j the lobe's integer bin, cycles per pixel)

and the plane refitted from them is checked against the decoder's ``refit`` (to 1e-9 period).
Against the dots' map L_j (bench_megarena_witness: centroids, polynomial of cross-validated
degree) the residual field ρ_j(r) = Φ_j(r)/2π − L_j(r) − o (o = 0 for bright dots, ½ dark) says
where calflow's intercept leaves E (Eq. (1) of megarena_estimand):

    calflow − E = [plane of L over the samples − E] + [the regressors' share on L] + [fit of ρ]

(sampling, regressors, residual; linear, so exact). Then one thing at a time: no floor, a
floor of 0.3, the samples inside the region alike (no shares), no regressors, the lobe-power
weights. An independent demodulation of the frame by the map, e^{−2πi L_j}, Gaussian-windowed
over ~ calflow's band-pass (1.14 periods), at the same points, says whether calflow's samples are
the frame's own fundamental phase.

The library's estimator as its source reads (docs/benchmarks.md): the unwindowed frame's
spectrum, a Gaussian band-pass of σ = 3 bins about the lobe's integer peak bin, the phase's
ordinary least-squares plane over every pixel of the central half, at (w/2, h/2). Checked
against the library's own output (``--library-csv``; it reproduces it on the real images to the
printed digits), it is then changed one thing at a time: centred on the lobe's fitted frequency
instead of its peak bin; wider (``--sigma-bins``). With ``--truth`` (make_distorted_megarena.py's
frames: Eq. (1) of the render's lattice through a known lens) every variant is also set against
the truth. The images are the user's (GPL-3.0 data stays outside calflow).

    .venv/bin/python benchmarks/bench_megarena_residual.py --period-um 9 --depth 12 \\
        --library-csv library9.csv --json IMAGE...
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
from calflow.instruments.pattern.megarena.decode import _fitter
from calflow.instruments.pattern.megarena.period import fundamental
from calflow.instruments.pattern.megarena.uniform import ENVELOPE_DEGREE, NO_LOBE, uniform_planes
from calflow.instruments.pattern.phase import CROP, GAUSS

sys.path.insert(0, str(Path(__file__).resolve().parent))
import megarena_dots as md  # noqa: E402
import megarena_estimand as me  # noqa: E402
from megarena_dots import REGION  # noqa: E402


def phase_samples(frame: np.ndarray, depth: int, region: float = REGION) -> dict:
    """calflow's coarse phase samples of ``frame`` as ``decode`` fits them: points (n, 2) px,
    each lobe's absolute phase (2, n) periods, |z|² (2, n), the envelope regressors (2, 2, n),
    the region's shares (n,) and the decoder's own refit (phase at ((w−1)/2, (h−1)/2), freq)."""
    h, w = frame.shape
    plan = _fitter(h, w, -116, 1)
    spec = plan.spectrum(frame[None].astype(np.float32))
    f0 = fundamental(spec[0], plan.h, plan.w, depth)
    fitter = _fitter(h, w, round(math.log(f0) / math.log(1.02)), 1)
    planes = fitter.fit(spec)
    pts = fitter.coarse_points()
    z = planes.fields[0].astype(complex)
    bins = planes.bins[0]
    carrier = np.stack(
        [bins[j, 1] / fitter.w * pts[:, 0] + bins[j, 0] / fitter.h * pts[:, 1] for j in (0, 1)]
    )
    share = fitter.region_share(region)
    refit = uniform_planes(fitter, planes, 0, share)
    return {
        "pts": pts,
        "phase": np.angle(z) / (2 * np.pi) + carrier,
        "power": np.abs(z) ** 2,
        "grads": planes.gradients[0],
        "share": share,
        "flat": fitter.flat,
        "freq": planes.freq[0],
        "refit": refit,
        "centre": ((w - 1) / 2, (h - 1) / 2),
    }


def sample_plane(smp: dict, values: np.ndarray, lobe: int, how: dict, p0) -> np.ndarray:
    """One lobe's plane (value at ``p0``, slopes) of ``values`` (n,) over calflow's samples, by
    ``how``: ``floor`` (fraction of the median |z|, the no-lobe cut), ``shares`` (the region's
    shares, or the samples inside it alike), ``regressors`` (the envelope's), ``weights``
    ("uniform" or "power"), ``degree`` (of the surface the envelope's coefficient is fitted
    beside: 1, the plane alone), ``leave_out`` ((2, n) booleans: samples left out per lobe)."""
    pts, power = smp["pts"], smp["power"][lobe]
    if how.get("shares", True):
        region = smp["share"] * smp["flat"]
    else:
        h2, w2 = smp["centre"][1], smp["centre"][0]
        region = (np.abs(pts[:, 0] - w2) <= REGION * (w2 + 0.5)) & (
            np.abs(pts[:, 1] - h2) <= REGION * (h2 + 0.5)
        )
        region = region * smp["flat"]
    floor = how.get("floor", NO_LOBE) ** 2 * float(np.median(power[region > 0]))
    wgt = region * (power > floor)
    if "leave_out" in how:
        wgt = wgt * ~how["leave_out"][lobe]
    if how.get("weights", "uniform") == "power":
        wgt = wgt * power
    A = np.stack([np.ones(len(pts)), pts[:, 0] - p0[0], pts[:, 1] - p0[1]], 1)
    u = wgt > 0
    if how.get("regressors", True):  # ĉ beside a surface of ``degree``, then the plane without it
        G = smp["grads"][lobe].T
        scale = max(smp["centre"]) + 0.5
        X, Y = (pts[:, 0] - p0[0]) / scale, (pts[:, 1] - p0[1]) / scale
        d = how.get("degree", ENVELOPE_DEGREE)
        D = np.column_stack([X**a * Y ** (n - a) for n in range(d + 1) for a in range(n, -1, -1)] + [G])
        Dw = D[u] * wgt[u, None]
        values = values - G @ np.linalg.solve(D[u].T @ Dw, Dw.T @ values[u])[-G.shape[1] :]
    Aw = A[u] * wgt[u, None]
    return np.linalg.solve(A[u].T @ Aw, Aw.T @ values[u])


def local_demodulation(frame, m: me.LatticeMap, offset: float, pts, sigma_px: float) -> np.ndarray:
    """Φ_j/2π − L_j at ``pts`` from the frame itself: the frame less its smooth background (a
    Gaussian of two periods), demodulated by e^{−2πi(L_j + offset)} and Gaussian-windowed
    (σ ``sigma_px``). (2, n) periods; independent of calflow's spectrum, band-pass and fit."""
    from scipy.ndimage import gaussian_filter

    h, w = frame.shape
    y, x = np.mgrid[0:h, 0:w]
    L = m(x, y) + offset
    img = frame - gaussian_filter(frame, 2 * sigma_px / 1.14)
    ix = np.clip(np.rint(pts[:, 0]).astype(int), 0, w - 1)
    iy = np.clip(np.rint(pts[:, 1]).astype(int), 0, h - 1)
    out = np.empty((2, len(pts)))
    for j in (0, 1):
        d = img * np.exp(-2j * np.pi * L[..., j])
        zz = gaussian_filter(d.real, sigma_px) + 1j * gaussian_filter(d.imag, sigma_px)
        out[j] = np.angle(zz[iy, ix]) / (2 * np.pi)
    return out


def _quadrants(pts, values, wgt, centre) -> list[float]:
    out = []
    for sy in (-1, 1):
        for sx in (-1, 1):
            q = (np.sign(pts[:, 0] - centre[0]) == sx) & (np.sign(pts[:, 1] - centre[1]) == sy) & (wgt > 0)
            out.append(float(np.sum(wgt[q] * values[q]) / max(np.sum(wgt[q]), 1e-300)))
    return out


def analyse(
    frame: np.ndarray, period_um: float, depth: int, reference: dict | None, sigmas, boot: int
) -> dict:
    """Every figure of the module docstring for one frame (poses in the library's convention)."""
    pattern = MegarenaPattern(period_um, depth)
    r = decode(frame, pattern, fit_region=REGION, plane_weights="uniform")
    if r.status[0] != "ok":
        return {"calflow_status": str(r.status[0])}
    ours = {k: float(v[0]) for k, v in r.library_pose().items()}
    ref = reference or ours
    s, t, c, period_px, bright = md.dots(frame, depth, region=me.CROP + md.MARGIN)
    st = np.stack([s, t], 1)
    degree, _ = me.cv_degree(c, st, frame.shape)
    e = me.estimand(c, st, frame.shape, degree, boot=boot)
    m, offset = e["map"], (0.0 if bright else 0.5)
    E = e["plane"] + np.array([offset, 0.0, 0.0])
    axes = me.match_axes(E, ref["alpha"])
    h, w = frame.shape
    p0 = me.library_region(h, w)[2]

    def pose(plane):
        q = me.library_pose(plane, period_um, axes, 0.0)
        q["x"], q["y"] = me.near(q["x"], ref["x"], period_um), me.near(q["y"], ref["y"], period_um)
        return q

    Ep = pose(E)
    out = {
        "dots": int(len(c)),
        "degree": degree,
        "axes": [list(a) for a in axes],
        "u": me.differences(
            {k: Ep[k] + float(np.std([pose(b + [offset, 0, 0])[k] for b in e["boot"]], ddof=1)) for k in Ep},
            Ep,
        )
        if boot > 1
        else None,
        "calflow_minus": me.differences(ours, Ep),
    }
    smp = phase_samples(frame, depth)
    L = m(smp["pts"][:, 0], smp["pts"][:, 1]).T + offset  # (2, n)
    rho = (smp["phase"] - L + 0.5) % 1.0 - 0.5
    phase = L + rho  # calflow's phase on the branch of the map's
    base = {"floor": NO_LOBE, "shares": True, "regressors": True, "weights": "uniform"}

    def fitted(how, values=phase):
        return np.stack([sample_plane(smp, values[j], j, how, p0) for j in (0, 1)])

    mine = fitted(base)
    # the check: this plane is the decoder's refit, at the decoder's centre
    rc = smp["centre"]
    at_rc = mine[:, 0] + mine[:, 1] * (rc[0] - p0[0]) + mine[:, 2] * (rc[1] - p0[1])
    refit_phase, refit_freq, _ = smp["refit"]
    check = float(np.max(np.abs((at_rc - refit_phase / (2 * np.pi) + 0.5) % 1.0 - 0.5)))
    check = max(check, float(np.max(np.abs(mine[:, 1:] - refit_freq))))
    out["refit_check_periods"] = check
    out["samples_plane_minus"] = me.differences(pose(mine), Ep)
    out["decomposition"] = {
        "sampling": me.differences(pose(fitted(dict(base, regressors=False), L)), Ep),
        "regressors_on_map": me.differences(
            pose(fitted(base, L)), pose(fitted(dict(base, regressors=False), L))
        ),
        "residual": me.differences(pose(E + fitted(base, rho)), Ep),
    }
    out["one_at_a_time"] = {
        name: me.differences(pose(fitted(dict(base, **change))), Ep)
        for name, change in (
            ("no_floor", {"floor": 0.0}),
            ("floor_0.3", {"floor": 0.3}),
            ("no_shares", {"shares": False}),
            ("no_regressors", {"regressors": False}),
            ("envelope_beside_the_plane", {"degree": 1}),
            ("power_weights", {"weights": "power", "degree": 1}),
        )
    }
    region = smp["share"] * smp["flat"]
    # spots (dust, defects): samples whose residual from the map, less its own plane and
    # envelope, is beyond k robust standard deviations — the map's, so a diagnosis only
    spots = np.zeros((2, len(region)))
    for j in (0, 1):
        u = region > 0
        A = np.stack([np.ones(u.sum()), *(smp["pts"][u] - p0).T, *smp["grads"][j][:, u]], 1)
        spots[j, u] = rho[j][u] - A @ np.linalg.lstsq(A, rho[j][u], rcond=None)[0]
        spots[j] /= 1.4826 * np.median(np.abs(spots[j, u]))
    for k in (8, 5):
        out["one_at_a_time"][f"spots_beyond_{k}_mad"] = me.differences(
            pose(fitted(dict(base, leave_out=np.abs(spots) > k))), Ep
        )
        out[f"spots_beyond_{k}_mad"] = [int(np.sum((region > 0) & (np.abs(spots[j]) > k))) for j in (0, 1)]
    floor = NO_LOBE**2 * np.array([np.median(smp["power"][j][region > 0]) for j in (0, 1)])
    out["floor_left_out"] = [int(np.sum((region > 0) & (smp["power"][j] <= floor[j]))) for j in (0, 1)]
    out["samples_in_region"] = int(np.sum(region > 0))
    # the residual field, per lobe, in nm along the lobe (period × periods)
    nm = 1000 * period_um
    sigma_px = GAUSS / (2 * math.pi * CROP) * period_px
    demod = local_demodulation(frame.astype(float), m, offset, smp["pts"], sigma_px)
    field = []
    for j in (0, 1):
        u = region > 0
        A = np.stack([np.ones(u.sum()), smp["grads"][j][0][u], smp["grads"][j][1][u]], 1)
        env = A[:, 1:] @ np.linalg.lstsq(A, rho[j][u], rcond=None)[0][1:]
        wq = region[u]
        block = np.rint(smp["pts"][u, 0]).astype(int) % 8
        field.append(
            {
                "mean_nm": nm * float(np.sum(wq * rho[j][u]) / wq.sum()),
                "mean_less_envelope_nm": nm * float(np.sum(wq * (rho[j][u] - env)) / wq.sum()),
                "rms_less_envelope_nm": nm * float(np.sqrt(np.sum(wq * (rho[j][u] - env) ** 2) / wq.sum())),
                "quadrants_less_envelope_nm": [
                    nm * v for v in _quadrants(smp["pts"][u], rho[j][u] - env, wq, (w / 2, h / 2))
                ],
                "by_column_mod_8_nm": [
                    nm * float(np.mean((rho[j][u] - env)[block == b])) if np.any(block == b) else None
                    for b in range(8)
                ],
                "demodulation_mean_nm": nm * float(np.sum(wq * demod[j][u]) / wq.sum()),
                "calflow_minus_demodulation_rms_nm": nm
                * float(np.sqrt(np.mean((rho[j][u] - demod[j][u]) ** 2))),
            }
        )
    out["residual_field"] = field
    # the library's estimator, one thing at a time
    est = {}
    cal_sigma = CROP * float(np.mean(np.hypot(*smp["freq"].T))) / GAUSS  # calflow's, cycles per pixel
    for sig in sigmas:
        for centre in ("integer", "fitted"):
            bins = (sig, sig) if sig != "calflow" else (cal_sigma * w, cal_sigma * h)
            est[f"{sig}:{centre}"] = pose(
                me.band_pass_plane(frame.astype(float), smp["freq"], bins, centre, E)
            )
    out["band_pass"] = {k: me.differences(q, Ep) for k, q in est.items()}
    # the estimand from the centroids on the frame as it is (its background's slope left in them)
    s0, t0, c0, *_ = md.dots(frame, depth, region=me.CROP + md.MARGIN, flatten=False)
    st0 = np.stack([s0, t0], 1)
    E0 = me.estimand(c0, st0, frame.shape, me.cv_degree(c0, st0, frame.shape)[0], boot=0)["plane"]
    E0 = pose(E0 + np.array([offset, 0.0, 0.0]))
    out["unflattened_minus"] = me.differences(E0, Ep)
    out["_poses"] = {
        "E": Ep,
        "E unflattened": E0,
        "calflow": ours,
        **{f"band_pass {k}": q for k, q in est.items()},
    }
    return out


def with_background(frame: np.ndarray, source: np.ndarray, scale: float = 1.0) -> np.ndarray:
    """``frame`` (float) plus ``source``'s smooth background less its mean, in units of each
    one's contrast (1st to 99th percentile) times ``scale``; bright dots assumed in both. The
    frames must have one shape."""
    source = source.astype(float)
    frame = frame.astype(float)
    if source.shape != frame.shape:
        raise ValueError(f"--background-of: expected a {frame.shape} image, got {source.shape}")
    plan = _fitter(*source.shape, -116, 1)
    f0 = fundamental(plan.spectrum(source[None].astype(np.float32))[0], plan.h, plan.w, 6)
    bg = md.background(source, 1.0 / f0 if f0 else 10.0)
    contrast = lambda a: float(np.percentile(a, 99) - np.percentile(a, 1))  # noqa: E731
    return frame + scale * (bg - bg.mean()) * contrast(frame) / contrast(source)


def smoke(folder: Path) -> list[str]:
    """``--smoke``: two small frames of calflow's camera, their truth in the library's convention."""
    import subprocess

    here = Path(__file__).resolve().parent
    size = ["--size", "384x320", "--period-um", "4", "--depth", "6", "--pixel-um", "0.5", "--k", "0.01"]
    cmd = [sys.executable, str(here / "make_distorted_megarena.py"), str(folder), "--frames", "2", *size]
    subprocess.run(cmd, check=True, capture_output=True)
    files = sorted(str(p) for p in folder.glob("d*.tiff"))
    return [*files, "--period-um", "4", "--depth", "6", "--truth", str(folder / "truth.csv"), "--boot", "0"]


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
    p.add_argument("--library-csv", help="the Vernier driver's CSV (file,found,x,y,alpha,pixelSize,ms)")
    p.add_argument(
        "--truth", help="CSV file,x,y,alpha,pixelSize: the frames' estimand (library's convention)"
    )
    p.add_argument(
        "--sigma-bins",
        default="3,6,calflow",
        help="band-pass widths for the library's estimator, bins (comma-separated; calflow: calflow's own)",
    )
    p.add_argument("--boot", type=int, default=100, help="bootstrap replicates of the dots' estimand")
    p.add_argument(
        "--background-of",
        help="an image whose smooth background (bench_megarena_witness.background) is added to every frame, "
        "scaled to the frame's contrast: a real frame's illumination under frames of known truth",
    )
    p.add_argument("--background-scale", type=float, default=1.0)
    p.add_argument("--json", action="store_true")
    args = p.parse_args(argv)
    sigmas = [v if v == "calflow" else float(v) for v in args.sigma_bins.split(",")]
    read = lambda path: {Path(r["file"]).name: r for r in csv.DictReader(open(path))} if path else {}  # noqa: E731
    truth, library = read(args.truth), read(args.library_csv)
    rows = []
    for path in args.images:
        name = Path(path).name
        frame = read_frames([path])[0][0]
        if args.background_of:
            frame = with_background(frame, read_frames([args.background_of])[0][0], args.background_scale)
        lib = library.get(name)
        lib_pose = None
        if lib and lib["found"].strip() in ("1", "true", "True"):
            lib_pose = {k: float(lib[k]) for k in ("x", "y", "alpha", "pixelSize")}
        row = {"file": name, **analyse(frame, args.period_um, args.depth, lib_pose, sigmas, args.boot)}
        poses = row.pop("_poses", {})
        if poses and lib_pose:
            row["library_minus"] = me.differences(lib_pose, poses["E"])
            row["minus_library"] = {k: me.differences(q, lib_pose) for k, q in poses.items() if k != "E"}
        if poses and name in truth:
            T = {k: float(truth[name][k]) for k in ("x", "y", "alpha", "pixelSize")}
            row["minus_truth"] = {}
            for k, q in [*poses.items(), *([("library", lib_pose)] if lib_pose else [])]:
                Tq = dict(
                    T, x=me.near(T["x"], q["x"], args.period_um), y=me.near(T["y"], q["y"], args.period_um)
                )
                row["minus_truth"][k] = me.differences(q, Tq)
        rows.append(row)
        print(f"{name}: dots {row.get('dots')}, degree {row.get('degree')}", file=sys.stderr)
        for key in ("calflow_minus", "samples_plane_minus", "library_minus"):
            if key in row:
                print(f"  {key}: " + ", ".join(f"{k} {v:+.4g}" for k, v in row[key].items()), file=sys.stderr)
        for group in ("decomposition", "one_at_a_time", "band_pass", "minus_library", "minus_truth"):
            for key, d in row.get(group, {}).items():
                print(
                    f"  {group} {key}: " + ", ".join(f"{k} {v:+.4g}" for k, v in d.items()), file=sys.stderr
                )
    print(json.dumps({"region": REGION, "frames": rows}, indent=1 if args.json else None))
    return 0


if __name__ == "__main__":
    sys.exit(main())
