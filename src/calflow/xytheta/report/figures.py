"""Figures of the XYΘ micro-robot report (thesis Ch. 4).

Each function takes the summary and/or the opened result files and returns a
:class:`~calflow.report.figures.Figure`, or None when its data are not among the inputs.
:func:`build` returns them in report order; the template places them by ``section``.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from calflow.report.figures import COLORS, Figure, Inputs, finish, finite, guarded, legend_below, new_figure

MODEL_ORDER = ("I", "II", "III", "IV", "V")
COMPENSATIONS = ("none", "linear", "cubic")


def _directions(ax, da: xr.DataArray, position: str, ylabel: str, title: str) -> None:
    for d, name in ((1, "forward"), (-1, "backward")):
        if d in da["direction"].values:
            ax.plot(da[position].values, da.sel(direction=d).values, color=COLORS[name], lw=0.7, label=name)
    ax.set_xlabel(f"commanded {position.split('_')[0].upper()} position (µm)")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.legend(loc="best")


def error_tables(luts: xr.Dataset) -> Figure | None:
    """Errors along the moving axis, forward and backward (Fig. 4.8)."""
    if luts is None or "err_xx" not in luts or "err_yy" not in luts:
        return None
    fig, ax = new_figure(2, height=2.5)
    _directions(ax[0, 0], luts["err_xx"], "x_position", "x_T − x_m (µm)", "(a) X stage moving: error along x")
    _directions(ax[0, 1], luts["err_yy"], "y_position", "y_T − y_m (µm)", "(b) Y stage moving: error along y")
    periods = [f"{luts[k].item():.1f} µm" for k in ("period_xx", "period_yy") if k in luts]
    return finish(
        fig,
        "fig-errors",
        "characterisation",
        "Position-dependent errors of the XY stages from the characterisation sweeps (error tables "
        "err_xx, err_yy of luts/position.nc), forward and backward; dominant periods "
        f"{' and '.join(periods) or 'n/a'} (lead-screw pitch 400 µm).",
        "Fig. 4.8",
    )


def coupling_tables(luts: xr.Dataset) -> Figure | None:
    """Coupling errors in the other axis, linear trend removed (Fig. 4.9)."""
    if luts is None or "err_xy" not in luts or "err_yx" not in luts:
        return None
    fig, ax = new_figure(2, height=2.5)
    _directions(
        ax[0, 0], luts["err_xy"], "x_position", "0 − y_m, detrended (µm)", "(a) X stage moving: coupling in y"
    )
    _directions(
        ax[0, 1], luts["err_yx"], "y_position", "0 − x_m, detrended (µm)", "(b) Y stage moving: coupling in x"
    )
    return finish(
        fig,
        "fig-coupling",
        "characterisation",
        "Coupling errors of the XY stages (err_xy, err_yx of luts/position.nc), forward and backward, "
        "after removing their linear trends (stage misalignment and perpendicularity).",
        "Fig. 4.9",
    )


def repeatability(luts: xr.Dataset) -> Figure | None:
    """Repeatability of the errors at every measuring point, per direction (Fig. 4.7)."""
    if luts is None or "rep_xx" not in luts or "rep_yy" not in luts:
        return None
    fig, ax = new_figure(2, 2, height=3.6, sharey=True)
    for col, (var, position, axis) in enumerate(
        (("rep_xx", "x_position", "x"), ("rep_yy", "y_position", "y"))
    ):
        da = luts[var]
        for row, (d, name) in enumerate(((1, "forward"), (-1, "backward"))):
            a = ax[row, col]
            if d in da["direction"].values:
                a.plot(da[position].values, da.sel(direction=d).values, "-", lw=0.45, color=COLORS[name])
            a.set_ylim(bottom=0)
            a.set_title(f"({'abcd'[2 * row + col]}) {axis.upper()} stage moving {name}s", loc="left")
            a.set_ylabel(f"repeatability of {axis} error (µm)" if col == 0 else "")
            a.set_xlabel(f"commanded {axis.upper()} position (µm)" if row == 1 else "")
    definition = luts.attrs.get("repeatability_definition", "range over cycles")
    return finish(
        fig,
        "fig-repeatability",
        "characterisation",
        f"Repeatability of the errors along X and Y at every measuring point, forward and backward: "
        f"{definition}.",
        "Fig. 4.7",
    )


def _compensation(
    summary: dict, inputs: Inputs, plan: str, key: str, title: str, thesis: str
) -> Figure | None:
    tests = inputs.metrics.get(plan) or {}
    rows = {c: (tests[c]["target"].values, tests[c]["ap"].values) for c in COMPENSATIONS if c in tests}
    if not rows:  # fall back on the summary's per-target table
        block = (summary.get("xy_tests") or {}).get(plan) or {}
        rows = {
            c: (
                np.array([t["target"] for t in block[c]["per_target"]]),
                finite([t["ap_um"] for t in block[c]["per_target"]]),
            )
            for c in COMPENSATIONS
            if c in block
        }
    if not rows:
        return None
    fig, ax = new_figure(1, height=2.7)
    a = ax[0, 0]
    many = max(len(t) for t, _ in rows.values()) > 30
    for c, (target, ap) in rows.items():
        a.plot(target, ap, marker="" if many else "o", lw=0.8, color=COLORS[c], label=f"compensation: {c}")
    a.set_yscale("log")
    a.set_xlabel("target index along the trajectory" if many else "target index (Table 4.3)")
    a.set_ylabel("accuracy AP (µm, log scale)")
    legend_below(fig, a, ncol=3)
    ref = (summary.get("reference", {}).get("lut_compensation_um") or {}).get(plan)
    note = f" The reference reports {ref[0]:g} µm → {ref[1]:g} µm." if ref else ""
    return finish(
        fig,
        key,
        "xy",
        f"{title}: ISO 9283 accuracy per target without compensation and with "
        f"lookup-table compensation (linear and cubic interpolation).{note}",
        thesis,
    )


def square(summary: dict, inputs: Inputs) -> Figure | None:
    return _compensation(summary, inputs, "square", "fig-square", "Square trajectory", "Fig. 4.13")


def random_points(summary: dict, inputs: Inputs) -> Figure | None:
    return _compensation(summary, inputs, "random_points", "fig-random", "Random points", "Fig. 4.15")


def identification_poses(run: xr.Dataset | None) -> Figure | None:
    """Joint coordinates of the identification poses (Fig. 4.22)."""
    if run is None or "cmd_x" not in run:
        return None
    fig, ax = new_figure(3, height=2.2)
    pose = np.arange(run.sizes["sample"])
    for a, (var, label, unit) in zip(
        ax[0], (("cmd_x", "X", "µm"), ("cmd_y", "Y", "µm"), ("cmd_theta", "Θ", "°"))
    ):
        if var in run:
            a.plot(pose, run[var].values, ".", ms=1.2, color=COLORS["forward"], rasterized=True)
        a.set_xlabel("pose index")
        a.set_ylabel(f"joint {label} ({unit})")
    return finish(
        fig,
        "fig-poses",
        "identification",
        f"Joint coordinates of the {pose.size} identification poses (runs/identification.nc).",
        "Fig. 4.22",
    )


def observability(summary: dict) -> Figure | None:
    """O1–O4 against the number of poses, log x (Fig. 4.21)."""
    obs = summary.get("observability")
    if not obs or not obs.get("poses"):
        return None
    fig, ax = new_figure(4, height=2.2)
    poses = np.asarray(obs["poses"], dtype=float)
    ref = summary.get("reference", {}).get("observability_poses", {})
    for a, k in zip(ax[0], ("O1", "O2", "O3", "O4")):
        a.plot(poses, finite(obs[k]), "o-", ms=2.5, color=COLORS["forward"])
        a.set_xscale("log")
        a.set_yscale("log")
        a.set_xlabel("number of poses")
        a.set_ylabel(f"{k} (1)")
        a.set_title(k)
        if obs.get("O2_plateau_poses"):
            a.axvline(obs["O2_plateau_poses"], color=COLORS["forward"], ls=":", lw=0.8)
        if ref.get("O2_plateau"):
            a.axvline(ref["O2_plateau"], color=COLORS["thesis"], ls="--", lw=0.8)
    caption = (
        "Observability indices O1–O4 of the identification cost function against the number of random "
        f"poses (mean of repeats). Dotted: where O2 stops improving here ({obs.get('O2_plateau_poses')} poses)"
    )
    if ref.get("O2_plateau"):
        caption += f"; dashed: the reference's ≈ {ref['O2_plateau']} poses (it used {ref.get('used')})"
    return finish(fig, "fig-observability", "identification", caption + ".", "Fig. 4.21")


def validation(summary: dict) -> Figure | None:
    """Accuracy per target and model: held-out targets against Θ_T, and the Table 4.7 targets (Fig. 4.25)."""
    models = summary.get("models") or {}
    if not models:
        return None
    fig, ax = new_figure(2, height=2.9)
    for name, m in models.items():
        color = COLORS.get(name)
        if m.get("protocol") == "heldout":
            rows = m["per_target"]
            ax[0, 0].plot(
                [t["theta_deg"] for t in rows],
                finite([t["ap_um"] for t in rows]),
                "o",
                ms=3,
                color=color,
                label=f"Model {name}",
            )
        ref = (m.get("reference_targets") or {}).get("per_target", [])
        ax[0, 1].plot(
            [t["target"] for t in ref],
            finite([t["ap_um"] for t in ref]),
            "o-",
            color=color,
            label=f"Model {name}",
        )
    for a in ax[0]:
        a.set_yscale("log")
        a.set_ylabel("accuracy AP (µm, log scale)")
    ax[0, 0].set_xlabel("target angle Θ_T (°)")
    ax[0, 0].set_title("(a) held-out targets")
    ax[0, 1].set_xlabel("target P_i (Table 4.7)")
    ax[0, 1].set_title("(b) reference targets")
    legend_below(fig, ax[0, 1], ncol=len(models))
    return finish(
        fig,
        "fig-validation",
        "validation",
        "ISO 9283 accuracy at each validation target with Models I–V: (a) the held-out targets, drawn over "
        "the identification workspace, against their angle; (b) the thesis's Table 4.7 targets "
        "(metrics/validation_heldout_*.nc, metrics/validation_*.nc).",
        "Fig. 4.25",
    )


def angle_errors(inputs: Inputs) -> Figure | None:
    """Angle-dependent errors f_ax(Θ), f_ay(Θ) of the models with an angle table (Sec. 4.5.5)."""
    from calflow.xytheta.models.ladder import MicroModel
    from calflow.xytheta.tables.angle import AngleTable

    tables = {}
    for name in MODEL_ORDER + tuple(n for n in inputs.models if n not in MODEL_ORDER):
        if name in inputs.models:
            model = MicroModel.read(inputs.models[name])
            if model.angle is not None:
                tables[name] = model.angle
    if not tables:
        return None
    fig, ax = new_figure(2, height=2.4)
    per_position = swept = False
    for name, t in tables.items():
        color = COLORS.get(name)
        theta = np.asarray(t.theta, dtype=float)
        if isinstance(t, AngleTable):  # rows: forward, backward
            sweep = t.info.get("sweep_theta")
            for a, key, values in zip(ax[0], ("sweep_f_ax", "sweep_f_ay"), (t.f_ax, t.f_ay)):
                if sweep is not None:
                    swept = True
                    for row, marker in zip(np.asarray(t.info[key]), ("^", "v")):
                        a.plot(sweep, row, marker, ms=2, alpha=0.5, color=color)
                a.plot(theta, values[0], "-", lw=1.2, color=color, label=f"Model {name}, forward")
                a.plot(theta, values[1], "--", lw=1.2, color=color, label=f"Model {name}, backward")
                a.plot(theta, values[0], "o", ms=3, color=color)
            continue
        for a, values in zip(ax[0], (t.f_ax, t.f_ay)):
            rows = np.atleast_2d(np.asarray(values, dtype=float))  # (positions, angles) or one row
            if rows.shape[0] > 1:  # a position-angle table: every target faint, their mean bold
                per_position = True
                a.plot(theta, rows.T, "-", lw=0.5, alpha=0.35, color=color)
            a.plot(
                theta,
                np.nanmean(rows, axis=0),
                "o-",
                color=color,
                label=f"Model {name}" + (" (mean over targets)" if rows.shape[0] > 1 else ""),
            )
    for a, k in zip(ax[0], ("f_ax", "f_ay")):
        a.set_xlabel("rotation Θ (°)")
        a.set_ylabel(f"{k}(Θ) (µm)")
        a.legend(loc="best", fontsize=6)
    caption = "Angle-dependent errors measured with the base models and tabulated in the models' angle tables (models/*.nc)"
    if swept:
        caption += (
            "; lines and circles: the tabulated angles, forward (solid) and backward (dashed); small "
            "triangles: the swept curve (mean over positions and cycles) the table's step was chosen from"
        )
    if per_position:
        caption += "; thin lines: each target of the position-angle tables (at the Table 4.7 positions)"
    return finish(fig, "fig-angle", "validation", caption + ".", "Fig. 4.26 (Sec. 4.5.5)")


def build(summary: dict, inputs: Inputs) -> tuple[list[Figure], list[str]]:
    """The report's figures in order, and notes on figures that could not be drawn."""
    if "interim_check" in summary:
        from calflow.xytheta.report import interim_figures

        return interim_figures.build(summary, inputs)
    notes: list[str] = []
    luts = inputs.luts
    draw = guarded(notes)
    figures = [draw(error_tables, luts), draw(coupling_tables, luts), draw(repeatability, luts)]
    if luts is None:
        notes.append(
            "No XY error tables (luts/position.nc) among the report inputs: Fig. 4.7–4.9 analogs omitted."
        )
    figures += [draw(square, summary, inputs), draw(random_points, summary, inputs)]
    poses = draw(identification_poses, inputs.runs.get("identification"))
    if poses is None:
        notes.append(
            "The identification run (runs/identification.nc) is not among the report inputs, so the "
            "identification poses (Fig. 4.22 analog) are not drawn; the pose counts are in the table below."
        )
    from calflow.xytheta.design.study import figure as design_study

    figures += [
        poses,
        draw(observability, summary),
        draw(design_study, summary),
        draw(validation, summary),
        draw(angle_errors, inputs),
    ]
    from calflow.xytheta.report import instrument

    bench = inputs.metrics.get("instrument", {}).get("")
    figures += [
        draw(instrument.example_frame, bench),
        draw(instrument.period_error, bench, instrument.throughput(inputs)),
    ]
    return [f for f in figures if f is not None], notes


def figures(c, args) -> tuple[list, list[str]]:
    """The family's step hook ``figures(c, args)`` (:mod:`calflow.family_contract`): the
    report's figures of ``args.summary`` and notes on omitted ones, from ``args.inputs``."""
    return build(args.summary, args.inputs)
