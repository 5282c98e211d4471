"""The measurement system on the bench: what a camera over a coded pattern does with frames.

A campaign whose sensor is a camera (the simulated XYΘ rig's ``sensor: images``) shows, in
its report, the instrument that made its readings, from frames rendered by the camera
model at poses the bench chooses (the bench's own inputs, not a rig's truth):

* an example frame, the grid of dot sites the decoded pose puts on it and which of them the
  code leaves empty (the decoded code), and the frame's spectrum (the two lobes of the grid
  the decoder band-passes, thesis Sec. 3.5.1);
* decoded − set pose of frames stepped over one period of the grid along x (the decoder's
  periodic error, which averaging frames at one pose does not remove);
* the repeatability of a static series: frames of one pose with independent noise;
* the decoding throughput of this machine (CPU time of :func:`decode`, frames per second).

The result is a ``metrics`` dataset (``plan = "instrument"``) the report reads, the same to
the byte for the same inputs, and the throughput apart (a measurement of the machine that
ran it, which no two runs share).
"""

from __future__ import annotations

import math
import time

import numpy as np
import xarray as xr

from calflow.instruments.readings import READINGS, decode_readings, render_poses


def _decode(frames, pattern, camera) -> dict[str, np.ndarray]:
    r = decode_readings(frames, pattern, camera)
    return {k: np.array([x[k] for x in r]) for k in READINGS}


def sites_in_frame(pattern, camera, x_um: float, y_um: float, theta_deg: float):
    """Pixel positions (row, column) of the pattern's dot sites inside a frame whose centre
    is at (``x_um``, ``y_um``) in the pattern frame at angle ``theta_deg`` (Eq. 4.26
    readings, :mod:`calflow.instruments.readings`), and whether each carries a dot."""
    (_, _, theta_r) = render_poses(x_um, y_um, theta_deg)[0]
    h, w = camera.height, camera.width
    px, p = camera.pixel_um, pattern.period_um
    half = 0.5 * math.hypot(w, h) * px + p
    ox, oy = pattern.origin_um
    cols = np.arange(math.floor((x_um - half + ox) / p), math.ceil((x_um + half + ox) / p) + 1)
    rows = np.arange(math.floor((y_um - half + oy) / p), math.ceil((y_um + half + oy) / p) + 1)
    R, C = np.meshgrid(rows, cols, indexing="ij")
    dx, dy = C * p - ox - x_um, R * p - oy - y_um  # site − frame centre, pattern frame (µm)
    t = math.radians(theta_r)  # pattern point = centre + R(−Θ_r)·c, so c = R(Θ_r)·(point − centre)
    cx, cy = math.cos(t) * dx - math.sin(t) * dy, math.sin(t) * dx + math.cos(t) * dy
    j, i = cx / px + (w - 1) / 2, cy / px + (h - 1) / 2
    inside = (i >= 0) & (i <= h - 1) & (j >= 0) & (j <= w - 1)
    return i[inside], j[inside], pattern.present(R[inside], C[inside])


def spectrum(frame: np.ndarray, pattern, camera) -> np.ndarray:
    """log10 of the magnitude of the frame's 2-D spectrum (mean removed), centred, cropped to
    1.6 times the grid's frequency on each axis (its first lobes and their neighbours)."""
    from scipy import fft

    f = fft.fftshift(np.abs(fft.fft2(frame.astype(float) - frame.mean())))
    h, w = frame.shape
    k = pattern.period_um / camera.pixel_um  # the grid's period in pixels
    ch, cw = min(h // 2, math.ceil(1.6 * h / k)), min(w // 2, math.ceil(1.6 * w / k))
    crop = f[h // 2 - ch : h // 2 + ch, w // 2 - cw : w // 2 + cw]
    return np.log10(crop + 1e-9).astype(np.float32)


def bench(pattern, camera, pose, steps: int = 12, static: int = 12, seed: int = 0) -> tuple[xr.Dataset, dict]:
    """The bench's dataset (module docstring) around ``pose`` = (x µm, y µm, Θ degree), a
    camera point and angle in the pattern frame (Eq. 4.26), and the decoder's throughput
    (``frames``, ``cpu_s``, ``frames_per_cpu_s``); ``steps`` frames over one period,
    ``static`` frames of one pose; noise drawn from ``seed``."""
    rng = np.random.default_rng(seed)
    x0, y0, t0 = (float(v) for v in pose)
    p = pattern.period_um
    sweep = np.column_stack([x0 + p * np.arange(steps) / steps, np.full(steps, y0), np.full(steps, t0)])
    held = np.tile([x0, y0, t0], (static, 1))
    poses = np.vstack([sweep, held])
    frames = camera.render_batch(pattern, render_poses(*poses.T), rng)
    cpu = time.process_time()
    r = _decode(frames, pattern, camera)
    cpu = time.process_time() - cpu
    example = frames[steps]
    i, j, present = sites_in_frame(
        pattern, camera, r["meas_x"][steps], r["meas_y"][steps], r["meas_theta"][steps]
    )
    s = slice(0, steps)
    q = slice(steps, steps + static)
    um, deg = {"units": "um"}, {"units": "degree"}
    ds = xr.Dataset(
        {
            "example_frame": (("row", "column"), example, {"units": "1", "long_name": "example frame (DN)"}),
            "site_row": (
                "site",
                i.astype(np.float32),
                {"units": "1", "long_name": "row of a dot site (pixel)"},
            ),
            "site_column": (
                "site",
                j.astype(np.float32),
                {"units": "1", "long_name": "column of a dot site (pixel)"},
            ),
            "site_present": (
                "site",
                present.astype("int8"),
                {
                    "units": "1",
                    "long_name": "dot present (1) or left out by the code (0), at the decoded pose",
                },
            ),
            "spectrum": (
                ("k_row", "k_column"),
                spectrum(example, pattern, camera),
                {"units": "1", "long_name": "log10 magnitude of the example frame's spectrum"},
            ),
            "sweep_x": ("step", sweep[:, 0], {**um, "long_name": "set camera point x over one period"}),
            **{
                f"sweep_err_{a}": (
                    "step",
                    r[f"meas_{a}"][s] - sweep[:, k],
                    {**(deg if a == "theta" else um), "long_name": f"decoded − set {a}"},
                )
                for k, a in enumerate(("x", "y", "theta"))
            },
            **{
                f"static_{a}": (
                    "frame",
                    r[f"meas_{a}"][q],
                    {**(deg if a == "theta" else um), "long_name": f"decoded {a}, one static pose"},
                )
                for a in ("x", "y", "theta")
            },
            "static_u_x": (
                "frame",
                r["u_meas_x"][q],
                {**um, "long_name": "decoder's standard uncertainty of x"},
            ),
            "decode_status": (
                "frame_all",
                r["decode_status"].astype("int8"),
                {"units": "1", "long_name": "decode status"},
            ),
        }
    )
    ds.attrs.update(
        plan="instrument",
        pose_x_um=x0,
        pose_y_um=y0,
        pose_theta_deg=t0,
        period_um=p,
        frame_width=int(camera.width),
        frame_height=int(camera.height),
        pixel_um=float(camera.pixel_um),
        min_fov_x_um=float(pattern.min_fov_um[0]),
        min_fov_y_um=float(pattern.min_fov_um[1]),
    )
    throughput = {
        "frames": int(len(frames)),
        "frame": [int(camera.width), int(camera.height)],
        "cpu_s": float(cpu),
        "frames_per_cpu_s": float(len(frames) / cpu) if cpu > 0 else None,
        "note": "CPU time of the decoder in the bench's process, on the machine that ran it",
    }
    return ds, throughput
