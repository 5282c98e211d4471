"""The measurement system of an XYΘ campaign that reads through images: summary and figures.

When the vision sensor is a camera over the coded pattern (the simulated rig's ``sensor:
images``, a ``gcs`` camera, a decoded frame recording), the run datasets carry each
reading's ``decode_status`` and ``u_meas_*``, and the campaign's instrument bench
(``metrics/instrument.nc``, :mod:`calflow.instruments.bench`) holds an example frame, its
spectrum, decoded − set over one period, a static series and the decoder's throughput.
:func:`summary_block` condenses them into the summary's ``sensor`` section; the figures
draw them in the report's "Measurement system" section. Nothing here reads a rig's truth.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import xarray as xr

if TYPE_CHECKING:  # the figures need matplotlib, which the summary's job need not import
    from calflow.report.figures import Figure


def _meanings(run: xr.Dataset) -> list[str]:
    return str(run["decode_status"].attrs.get("flag_meanings", "ok")).split()


def decode_counts(runs: list[xr.Dataset]) -> dict:
    """Per run (its plan, or plan and model): frames, decoded, failures by reason, and the pixel
    size pooled over a decoded frame recording with its trend test's words, when it was."""
    out = {}
    for run in runs:
        if "decode_status" not in run:
            continue
        status = np.asarray(run["decode_status"].values, dtype=int)
        names = _meanings(run)
        reasons: dict[str, int] = {}
        for code in np.unique(status[status != 0]):
            name = names[code] if 0 <= code < len(names) else str(code)
            reasons[name] = int(np.sum(status == code))
        key = str(run.attrs.get("plan", "run")) + (f"_{run.attrs['model']}" if run.attrs.get("model") else "")
        out[key] = {"frames": int(status.size), "decoded": int(np.sum(status == 0)), "failures": reasons}
        if run.attrs.get("pixel_size") == "sequence":  # a recording's pooled pixel size, in words
            out[key]["pixel_size"] = {
                "um": float(run.attrs["pixel_size_um"]),
                "u_um": float(run.attrs["u_pixel_size_um"]),
                "drifts": run.attrs.get("pixel_size_drifts") == "yes",
                "statement": str(run.attrs.get("pixel_size_statement", "")),
            }
    return out


def summary_block(runs: list[xr.Dataset], bench: xr.Dataset | None) -> dict | None:
    """The summary's ``sensor`` section, or None when no run reads through images."""
    counts = decode_counts(runs)
    if not counts and bench is None:
        return None
    out: dict = {"kind": "images", "decode": counts}
    u = [np.asarray(r[f"u_meas_{a}"].values, float) for r in runs for a in ("x",) if f"u_meas_{a}" in r]
    u = np.concatenate(u) if u else np.empty(0)
    if np.isfinite(u).any():
        out["u_meas_x_median_um"] = float(np.nanmedian(u))
    if bench is not None:
        static = {a: np.asarray(bench[f"static_{a}"].values, float) for a in ("x", "y", "theta")}
        sweep = {a: np.asarray(bench[f"sweep_err_{a}"].values, float) for a in ("x", "y", "theta")}
        out["bench"] = {
            "frame": [int(bench.attrs["frame_width"]), int(bench.attrs["frame_height"])],
            "pixel_um": float(bench.attrs["pixel_um"]),
            "repeatability_1sigma": {
                "x_um": _std(static["x"]),
                "y_um": _std(static["y"]),
                "theta_deg": _std(static["theta"]),
                "frames": int(np.isfinite(static["x"]).sum()),
            },
            "period_error": {
                "bias_x_um": _mean(sweep["x"]),
                "std_x_um": _std(sweep["x"]),
                "bias_y_um": _mean(sweep["y"]),
                "std_y_um": _std(sweep["y"]),
                "bias_theta_deg": _mean(sweep["theta"]),
                "std_theta_deg": _std(sweep["theta"]),
                "steps": int(sweep["x"].size),
            },
        }
    return out


def _std(v: np.ndarray) -> float | None:
    v = v[np.isfinite(v)]
    return float(np.std(v, ddof=1)) if v.size > 1 else None


def _mean(v: np.ndarray) -> float | None:
    v = v[np.isfinite(v)]
    return float(np.mean(v)) if v.size else None


def example_frame(bench: xr.Dataset | None) -> Figure | None:
    """The example frame with the dot sites of its decoded pose and the code's empty sites,
    and its spectrum."""
    if bench is None or "example_frame" not in bench:
        return None
    from calflow.report.figures import finish, new_figure

    fig, ax = new_figure(2, height=2.9)
    frame = np.asarray(bench["example_frame"].values)
    h, w = frame.shape
    side = min(h, w, 96)  # a crop at the centre, where dots and marks can be told apart
    r0, c0 = (h - side) // 2, (w - side) // 2
    a = ax[0, 0]
    a.imshow(
        frame[r0 : r0 + side, c0 : c0 + side],
        cmap="gray",
        interpolation="nearest",
        extent=(c0 - 0.5, c0 + side - 0.5, r0 + side - 0.5, r0 - 0.5),
    )
    present = np.asarray(bench["site_present"].values, dtype=bool)
    i, j = np.asarray(bench["site_row"].values), np.asarray(bench["site_column"].values)
    near = (i >= r0) & (i < r0 + side) & (j >= c0) & (j < c0 + side)
    a.plot(j[present & near], i[present & near], "+", color="#1b9e77", ms=4, mew=0.6, label="grid: dot")
    a.plot(
        j[~present & near],
        i[~present & near],
        "o",
        mfc="none",
        color="#d95f02",
        ms=4,
        mew=0.7,
        label="code: no dot",
    )
    a.set_title(f"(a) frame centre ({side} × {side} px), decoded")
    a.set_xlabel("column (pixel)")
    a.set_ylabel("row (pixel)")
    a.legend(loc="upper right", fontsize=6, framealpha=0.9)
    b = ax[0, 1]
    s = np.asarray(bench["spectrum"].values)
    b.imshow(
        s, cmap="viridis", interpolation="nearest", vmin=float(np.percentile(s, 50)), vmax=float(s.max())
    )
    b.set_title("(b) whole frame's spectrum (log)")
    b.set_xticks([])
    b.set_yticks([])
    pose = f"({bench.attrs['pose_x_um']:.1f} µm, {bench.attrs['pose_y_um']:.1f} µm, {bench.attrs['pose_theta_deg']:.2f}°)"
    return finish(
        fig,
        "fig-instrument-frame",
        "instrument",
        f"A frame rendered by the camera model at {pose} in the pattern frame "
        f"({bench.attrs['frame_width']} × {bench.attrs['frame_height']} pixels of "
        f"{bench.attrs['pixel_um']:.3f} µm), its centre: crosses, the dot sites the decoded pose puts on "
        "it; circles, the sites the code leaves empty (the decoded code). (b) The whole frame's spectrum, "
        "centred: the grid's lobes the decoder band-passes.",
        "Sec. 3.5.1",
    )


def period_error(bench: xr.Dataset | None, speed: dict | None = None) -> Figure | None:
    """Decoded − set over one period, and the static series; the caption gives the decoder's
    throughput when the bench measured it (``speed``)."""
    if bench is None or "sweep_x" not in bench:
        return None
    from calflow.report.figures import finish, new_figure

    fig, ax = new_figure(2, height=2.5)
    a = ax[0, 0]
    x = np.asarray(bench["sweep_x"].values)
    x = x - x[0]
    for name, color in (("x", "#1b9e77"), ("y", "#7570b3")):
        a.plot(x, 1000 * np.asarray(bench[f"sweep_err_{name}"].values), ".-", color=color, lw=0.7, label=name)
    a.set_xlabel(f"set x over one period ({bench.attrs['period_um']:g} µm)")
    a.set_ylabel("decoded − set (nm)")
    a.set_title("(a) decoded − set over one period")
    a.legend(loc="best")
    b = ax[0, 1]
    for name, color in (("x", "#1b9e77"), ("y", "#7570b3")):
        v = np.asarray(bench[f"static_{name}"].values)
        b.plot(1000 * (v - np.nanmean(v)), ".", color=color, label=name)
    b.set_xlabel("frame of one static pose")
    b.set_ylabel("decoded − mean (nm)")
    b.set_title("(b) static series")
    b.legend(loc="best")
    return finish(
        fig,
        "fig-instrument-period",
        "instrument",
        "(a) Decoded − set camera point for frames rendered at set poses stepped over one period of "
        "the grid along x (the decoder's periodic error). (b) Frames of one pose with independent "
        "noise: the repeatability of a static frame series." + _speed(speed),
        "Sec. 3.5.1",
    )


def throughput(inputs) -> dict | None:
    """The decoder's throughput measured by the bench (its JSON among the report's files)."""
    import json
    from pathlib import Path

    path = next((Path(p) for p in inputs.unknown if p.endswith("instrument_throughput.json")), None)
    if path is None or not path.is_file():
        return None
    return json.loads(path.read_text())


def _speed(speed: dict | None) -> str:
    if not speed or not speed.get("frames_per_cpu_s"):
        return " The decoder's throughput was not measured."
    w, h = speed["frame"]
    return (
        f" Decoder throughput: {speed['frames_per_cpu_s']:.0f} frames of {w} × {h} pixels per CPU second "
        f"({speed['frames']} frames; {speed['note']}; it varies with the machine and its load)."
    )
