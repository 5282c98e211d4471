"""Figures of the nanopositioning reports (thesis Ch. 5): 1-DoF (Sec. 5.3) and 2-DoF (Sec. 5.4).

Time axes follow the thesis: hours since the start of validation ("Time 0 = end of
training = start of validation", Fig. 5.17–5.19, 5.23, 5.24); the training phase, when its
run is among the inputs, sits at negative times.
"""

from __future__ import annotations

import matplotlib
import numpy as np
import xarray as xr

from calflow.report.figures import (
    COLORS,
    Figure,
    Inputs,
    finish,
    finite,
    guarded,
    hours,
    legend_below,
    mode_label,
    new_figure,
)


def _axes(run: xr.Dataset) -> list[str]:
    return [a for a in ("x", "y") if f"cmd_{a}" in run and f"meas_{a}" in run]


def geometric_error(run: xr.Dataset | None, robot: str) -> Figure | None:
    """Measured − command against command, forward and backward (Fig. 5.1)."""
    if run is None or "cmd_x" not in run or "meas_x" not in run:
        return None
    axes = _axes(run)
    panels = [(a, a) for a in axes]
    if robot == "stage1d" and "meas_y" in run:
        panels.append(("x", "y"))  # the y reading while x moves (coupling)
    fig, ax = new_figure(len(panels), height=2.5)
    direction = run["direction"].values if "direction" in run else np.zeros(run.sizes["sample"])
    for a, (cmd, meas) in zip(ax[0], panels):
        c = run[f"cmd_{cmd}"].values
        dev = (
            run[f"meas_{meas}"].values - (c if cmd == meas else np.nanmean(run[f"meas_{meas}"].values))
        ) * 1e3
        groups = [(1, "forward"), (-1, "backward")] if np.any(direction != 0) else [(0, "all cycles")]
        for d, name in groups:
            sel = direction == d
            a.plot(
                c[sel],
                dev[sel],
                ".",
                ms=1.0,
                alpha=0.35,
                color=COLORS.get(name, COLORS["forward"]),
                rasterized=True,
            )
            xs = np.unique(c[sel])
            means = [np.nanmean(dev[sel][c[sel] == x]) for x in xs]
            a.plot(
                xs,
                means,
                "-",
                lw=1.1,
                color=COLORS.get(name, COLORS["forward"]),
                label=f"{name} (mean over cycles)",
            )
        a.set_xlabel(f"command {cmd}_T (µm)")
        if cmd == meas:
            a.set_ylabel(f"{meas}_m − {meas}_T (nm)")
            a.set_title(f"error along {meas}")
        else:
            a.set_ylabel(f"{meas}_m − mean {meas}_m (nm)")
            a.set_title(f"coupling: {meas} reading while {cmd} moves")
        a.legend(loc="best")
    return finish(
        fig,
        "fig-geometric",
        "training",
        "Geometric errors of the stage in the training run (runs/training.nc): every settled reading "
        "(dots, drifting with temperature over the run) and the mean over cycles per target and direction.",
        "Fig. 5.1",
    )


def _pose_centred(run: xr.Dataset, axis: str) -> np.ndarray:
    """Deviation (nm) minus its mean at the same pose and direction: the geometric part goes."""
    dev = (run[f"meas_{axis}"].values - run[f"cmd_{axis}"].values) * 1e3
    pose = run["pose"].values if "pose" in run else run[f"cmd_{axis}"].values
    direction = run["direction"].values if "direction" in run else np.zeros_like(pose)
    out = np.full_like(dev, np.nan)
    keys = pose.astype(float) * 10 + direction
    for k in np.unique(keys):
        sel = keys == k
        out[sel] = dev[sel] - np.nanmean(dev[sel])
    return out


def drift_vs_temperature(run: xr.Dataset | None) -> Figure | None:
    """Thermal drift of the training run against the mean thermocouple temperature (Fig. 5.2)."""
    if run is None or "temperature" not in run or "cmd_x" not in run:
        return None
    temperature = run["temperature"].values
    t_mean = np.nanmean(temperature, axis=1) if temperature.ndim == 2 else temperature
    axes = _axes(run)
    fig, ax = new_figure(len(axes), height=2.5, width=3.6 * len(axes))
    for a, axis in zip(ax[0], axes):
        drift = _pose_centred(run, axis)
        ok = np.isfinite(drift) & np.isfinite(t_mean)
        a.plot(t_mean[ok], drift[ok], ".", ms=1.2, alpha=0.5, color=COLORS["forward"], rasterized=True)
        if ok.sum() > 2 and np.ptp(t_mean[ok]) > 0:
            slope, icpt = np.polyfit(t_mean[ok], drift[ok], 1)
            xs = np.linspace(t_mean[ok].min(), t_mean[ok].max(), 2)
            a.plot(
                xs,
                slope * xs + icpt,
                "-",
                color=COLORS["backward"],
                label=f"linear fit: {slope / 1e3:.3f} µm/°C",
            )
            a.legend(loc="best")
        a.set_xlabel("mean thermocouple temperature (°C)")
        a.set_ylabel(f"drift along {axis} (nm)")
    return finish(
        fig,
        "fig-drift",
        "training",
        "Thermal drift in the training run: deviation from the target minus its mean at the same pose and "
        "direction (the geometric error), against the mean of the thermocouples.",
        "Fig. 5.2",
    )


def metrology(summary: dict) -> Figure | None:
    """Accuracy and repeatability per pose in the metrology room (Fig. 5.11, 5.12)."""
    intrinsic = summary.get("intrinsic")
    if not intrinsic or not intrinsic.get("per_pose"):
        return None
    rows = intrinsic["per_pose"]
    fig, ax = new_figure(2, height=2.5)
    for d, name in ((1, "forward"), (-1, "backward")):
        sel = [r for r in rows if r.get("direction") == d] or ([r for r in rows] if d == 1 else [])
        if not sel:
            continue
        x = finite([r["target_x_um"] for r in sel])
        ax[0, 0].plot(x, finite([r["ap_nm"] for r in sel]), "o-", color=COLORS[name], label=name)
        ax[0, 1].plot(x, finite([r["rp_nm"] for r in sel]), "o-", color=COLORS[name], label=name)
    for a, what in zip(ax[0], ("accuracy AP (nm)", "repeatability RP (nm)")):
        a.set_xlabel("target x_T (µm)")
        a.set_ylabel(what)
        a.set_ylim(bottom=0)
        a.legend(loc="best")
    ax[0, 0].set_title("(a) accuracy (Fig. 5.11)")
    ax[0, 1].set_title("(b) repeatability (Fig. 5.12)")
    spread = intrinsic.get("temperature_range_c")
    where = (
        f"in the metrology room (temperature range {spread:.3f} °C)"
        if spread is not None
        else "in the recorded test (no temperature readings)"
    )
    return finish(
        fig,
        "fig-metrology",
        "metrology",
        f"Accuracy and repeatability of the uncalibrated stage per pose {where}.",
        "Fig. 5.11, 5.12",
    )


def _modes(metrics: xr.Dataset) -> list[str]:
    return str(metrics["mode"].attrs.get("flag_meanings", "no_calibration adaptive_kmz single")).split()


def validation_poses(metrics: xr.Dataset | None) -> Figure | None:
    """AP of every validation pose of every test against time, one panel per mode (Fig. 5.17)."""
    if metrics is None or "ap" not in metrics or "mode" not in metrics:
        return None
    names = _modes(metrics)
    start = float(metrics.attrs.get("start_time_h", np.nanmin(metrics["time_h"].values)))
    t = metrics["time_h"].values - start
    mode = metrics["mode"].values
    present = [k for k in range(len(names)) if np.any(mode == k)]
    fig, ax = new_figure(1, len(present), height=1.55 * len(present) + 0.4, sharex=True)
    npose = metrics.sizes["pose"]
    colors = matplotlib.colormaps["viridis"](np.linspace(0, 0.9, npose))
    ap = metrics["ap"].transpose("test", "pose").values
    label = _pose_labels(metrics)
    for row, k in enumerate(present):
        a = ax[row, 0]
        sel = mode == k
        for j in range(npose):
            a.plot(t[sel], ap[sel, j], "-", lw=0.7, color=colors[j], label=label[j])
        a.set_ylabel("AP (nm)")
        a.set_title(mode_label(names[k]), loc="left")
        a.set_ylim(bottom=0)
    ax[-1, 0].set_xlabel("time since the start of validation (h)")
    ax[0, 0].legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=6, ncol=1 if npose <= 14 else 2)
    return finish(
        fig,
        "fig-poses-time",
        "validation",
        "Accuracy of every validation pose (colours, legend: target and direction) in every test, "
        "per test type (metrics/validation.nc). Time 0 = end of training = start of validation.",
        "Fig. 5.17",
    )


def _pose_labels(metrics: xr.Dataset) -> list[str]:
    out = []
    for j in range(metrics.sizes["pose"]):
        xy = [f"{metrics[f'target_{a}'].values[j]:g}" for a in ("x", "y") if f"target_{a}" in metrics]
        d = int(metrics["direction"].values[j]) if "direction" in metrics else 0
        out.append(f"({', '.join(xy)}) µm" + {1: " →", -1: " ←"}.get(d, ""))
    return out


def _training_point(summary: dict, run: xr.Dataset | None) -> tuple[float, dict] | None:
    training, start = summary.get("training"), (summary.get("validation") or {}).get("start_h")
    if not training or run is None or start is None or "time" not in run:
        return None
    return float(np.nanmean(hours(run)) - start), training


def max_per_test(summary: dict, run: xr.Dataset | None = None) -> Figure | None:
    """Maximum AP and RP of every test against time (Fig. 5.18; Fig. 5.23 with the training phase)."""
    tests = summary.get("tests") or {}
    if not tests:
        return None
    two_dof = summary.get("robot") == "stage2d"
    fig, ax = new_figure(2, height=2.9)
    ref = (summary.get("reference") or {}).get("tests") or {}
    for name, block in tests.items():
        s = block["series"]
        color = COLORS.get(name)
        ax[0, 0].plot(
            finite(s["time_h"]), finite(s["max_ap_nm"]), "o-", ms=2.5, color=color, label=mode_label(name)
        )
        ax[0, 1].plot(
            finite(s["time_h"]), finite(s["max_rp_nm"]), "o-", ms=2.5, color=color, label=mode_label(name)
        )
        if name in ref:
            ax[0, 0].axhline(ref[name]["max_accuracy_nm"], color=color, ls="--", lw=0.7, alpha=0.6)
    point = _training_point(summary, run) if two_dof else None
    if point:
        t, training = point
        ax[0, 0].plot([t], [training["accuracy_nm"]], "s", color="k", label="training phase")
        ax[0, 1].plot([t], [training["repeatability_nm"]], "s", color="k", label="training phase")
    for a, what in zip(ax[0], ("max accuracy AP (nm)", "max repeatability RP (nm)")):
        a.set_xlabel("time since the start of validation (h)")
        a.set_ylabel(what)
        a.set_ylim(bottom=0)
    legend_below(fig, ax[0, 0], ncol=4)
    ax[0, 0].set_title("(a) accuracy; dashed: reference values" if ref else "(a) accuracy")
    ax[0, 1].set_title("(b) repeatability")
    return finish(
        fig,
        "fig-max",
        "validation",
        "Maximum accuracy and repeatability over the poses of every test"
        + (", training phase and validation" if two_dof else "")
        + (". Dashed lines: the reference's maxima for each test type" if ref else "")
        + ". Time 0 = end of training = start of validation.",
        "Fig. 5.23" if two_dof else "Fig. 5.18",
    )


def temperature(summary: dict, run: xr.Dataset | None = None) -> Figure | None:
    """Mean thermocouple temperature of every test (and of the training run) against time (Fig. 5.19, 5.24)."""
    tests = summary.get("tests") or {}
    if not tests:
        return None
    two_dof = summary.get("robot") == "stage2d"
    validation = summary.get("validation") or {}
    fig, ax = new_figure(1, height=2.9)
    a = ax[0, 0]
    start = validation.get("start_h")
    if run is not None and "temperature" in run and start is not None:
        temp = run["temperature"].values
        t_mean = np.nanmean(temp, axis=1) if temp.ndim == 2 else temp
        a.plot(hours(run) - start, t_mean, "-", lw=0.7, color="k", label="training run")
    for name, block in tests.items():
        s = block["series"]
        a.errorbar(
            finite(s["time_h"]),
            finite(s["temperature_c"]),
            yerr=finite(s["temperature_range_c"]) / 2,
            fmt="o",
            ms=2.5,
            lw=0.7,
            color=COLORS.get(name),
            label=f"tests: {mode_label(name)}",
        )
    rng = validation.get("training_temperature_range_c")
    if rng and None not in rng:
        a.axhspan(rng[0], rng[1], color=COLORS["shade"], zorder=0, label="training temperature range")
    a.set_xlabel("time since the start of validation (h)")
    a.set_ylabel("temperature (°C)")
    legend_below(fig, a, ncol=3 if len(tests) <= 2 else 2)
    return finish(
        fig,
        "fig-temperature",
        "temperature",
        "Room temperature at the stage: the mean of the thermocouples per test (markers; bars: range within the test)"
        + (" and along the training run" if run is not None else "")
        + ".",
        "Fig. 5.24" if two_dof else "Fig. 5.19",
    )


def accuracy_vs_temperature(summary: dict) -> Figure | None:
    """Maximum AP and RP of every test against its mean temperature, training range shaded (Fig. 5.20)."""
    tests = summary.get("tests") or {}
    if not tests:
        return None
    fig, ax = new_figure(2, height=2.8)
    rng = (summary.get("validation") or {}).get("training_temperature_range_c")
    for name, block in tests.items():
        s = block["series"]
        inside = np.array([bool(v) for v in s.get("in_training_range", [True] * len(s["time_h"]))])
        for a, key in zip(ax[0], ("max_ap_nm", "max_rp_nm")):
            x, y = finite(s["temperature_c"]), finite(s[key])
            a.plot(x[inside], y[inside], "o", ms=3, color=COLORS.get(name), label=mode_label(name))
            a.plot(x[~inside], y[~inside], "o", ms=3, mfc="none", color=COLORS.get(name))
    for a, what in zip(ax[0], ("max accuracy AP (nm)", "max repeatability RP (nm)")):
        if rng and None not in rng:
            a.axvspan(rng[0], rng[1], color=COLORS["shade"], zorder=0)
        a.set_xlabel("mean temperature of the test (°C)")
        a.set_ylabel(what)
        a.set_ylim(bottom=0)
    legend_below(fig, ax[0, 0], ncol=len(tests))
    return finish(
        fig,
        "fig-acc-temp",
        "temperature",
        "Maximum accuracy and repeatability of every test against its mean temperature; the shaded band is "
        "the temperature range of the training run (open markers: tests outside it).",
        "Fig. 5.20",
    )


def build(summary: dict, inputs: Inputs) -> tuple[list[Figure], list[str]]:
    """The report's figures in order, and notes on figures that could not be drawn."""
    notes = []
    unsupported = summary.get("unsupported") or {}  # said in the report's own words; no note twice
    run = inputs.runs.get("training")
    if run is None and "training" not in unsupported:
        notes.append(
            "The training run (runs/training.nc) is not among the report inputs: Fig. 5.1, 5.2 analogs "
            "and the training temperature are omitted."
        )
    val = (inputs.metrics.get("validation") or {}).get("")
    if val is None and "validation" not in unsupported:
        notes.append(
            "The validation metrics (metrics/validation.nc) are not among the report inputs: "
            "Fig. 5.17 analog omitted."
        )
    robot = summary.get("robot", "stage1d")
    draw = guarded(notes)
    figures = [
        draw(geometric_error, run, robot),
        draw(drift_vs_temperature, run),
        draw(metrology, summary),
        draw(validation_poses, val),
        draw(max_per_test, summary, run),
        draw(temperature, summary, run),
        draw(accuracy_vs_temperature, summary),
    ]
    return [f for f in figures if f is not None], notes


def figures(c, args) -> tuple[list, list[str]]:
    """The family's step hook ``figures(c, args)`` (:mod:`calflow.family_contract`): the
    report's figures of ``args.summary`` and notes on omitted ones, from ``args.inputs``."""
    return build(args.summary, args.inputs)
