"""Characterisation of the position-dependent errors of the XY stages (thesis Sec. 4.4.1).

Input: run datasets of ``calflow.xytheta.plans.sweeps.characterisation`` (one stage swept forward
and backward, the other joints at 0, Θ = 0). Output: error tables for Eq. (4.14)/(4.15).

Frames and signs (verified on the simulated rig, ``tests/xytheta/test_characterisation.py``)
-----------------------------------------------------------------------------------
With Θ = 0 the pattern frame is parallel to the world frame and Eq. (4.27) gives
x_P = x_m0 - x_m, y_P = y_m0 - y_m. The *stage-frame measured position* is the
displacement of the reading from the home reading (pose 0),

    u = x_m - x_m0 = -(x_P - x_P0),    v = y_m - y_m0 = -(y_P - y_P0)    [µm].

With α ≈ 180° and β ≈ 0 a +X move makes u grow by ≈ X and a +Y move makes v grow by ≈ Y.
Errors are *target − measured* in this frame: while X moves to x_T (Fig. 4.8, 4.9)

    f_xx(x_T) = x_T - u  (driving axis),    f_xy(x_T) = 0 - v  (coupling),

and likewise f_yy, f_yx while Y moves; forward tables (f_..) hold direction +1, backward
tables (b_..) direction -1. Because Eq. (4.18) reads X - ex, the stage reaches
``X_cmd - e``: commanding ``x_T + e`` brings it onto x_T (``calflow.xytheta.tables.position``).

The linear trend of the coupling tables is the stage misalignment: the trend of f_yx is
the perpendicularity bias δx(y) of Eq. (4.14); the trend of f_xy, δy(x), is what
Eq. (4.15) omits because the thesis X stage was aligned with the pattern (not so on a rig
with α = 177.7°). Both trends are stored apart and removed from the coupling tables, so
that f_xy + δy and f_yx + δx are the raw coupling errors and no term is counted twice.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from calflow.data.runs import RunMetadata
from calflow.errors import DataError
from calflow.metrics import iso9283

REPEATABILITY_DEFINITION = (
    "range (max - min) over cycles of the error at one position and direction (Fig. 4.7)"
)
DIRECTIONS = np.array([1, -1], dtype=np.int8)
_AXES = ("x", "y")


def stage_positions(run: xr.Dataset) -> tuple[np.ndarray, np.ndarray]:
    """Stage-frame measured positions u, v (µm) of a Θ = 0 run: reading minus home reading.

    Raises DataError when the run has no valid home row (pose 0) or moves Θ.
    """
    pose = run["pose"].values
    home = np.flatnonzero(pose == 0)
    if home.size == 0:
        raise DataError(f"run {run.attrs.get('plan')!r}: no home sample (pose 0) to reference the readings")
    if "cmd_theta" in run and np.any(np.abs(run["cmd_theta"].values) > 1e-9):
        raise DataError(f"run {run.attrs.get('plan')!r}: cmd_theta is not 0; XY characterisation needs Θ = 0")
    x_m, y_m = run["meas_x"].values.astype(float), run["meas_y"].values.astype(float)
    h = home[0]
    if not (np.isfinite(x_m[h]) and np.isfinite(y_m[h])):
        raise DataError(f"run {run.attrs.get('plan')!r}: the home reading is NaN (camera off the pattern)")
    return x_m - x_m[h], y_m - y_m[h]


def dominant_period(position, error, min_periods: float = 2.0, pad: int = 16) -> float:
    """Period (µm) of the largest spectral peak of a detrended error table (Fig. 4.8).

    The longest run of finite values is resampled on its median step if needed, a linear
    trend is removed, the FFT (zero-padded ``pad`` times) is taken and the peak is refined
    by parabolic interpolation. Only periods up to span / ``min_periods`` are searched.
    Returns NaN for fewer than 8 finite points.
    """
    q, e = np.asarray(position, dtype=float), np.asarray(error, dtype=float)
    ok = np.isfinite(q) & np.isfinite(e)
    # longest contiguous run of finite values
    edges = np.flatnonzero(np.diff(np.concatenate([[0], ok.astype(int), [0]])))
    if edges.size == 0:
        return float("nan")
    starts, stops = edges[::2], edges[1::2]
    k = np.argmax(stops - starts)
    q, e = q[starts[k] : stops[k]], e[starts[k] : stops[k]]
    order = np.argsort(q)
    q, e = q[order], e[order]
    if q.size < 8:
        return float("nan")
    step = float(np.median(np.diff(q)))
    if not np.allclose(np.diff(q), step, rtol=1e-6, atol=1e-9):
        grid = np.arange(q[0], q[-1] + step / 2, step)
        e, q = np.interp(grid, q, e), grid
    e = e - np.polyval(np.polyfit(q, e, 1), q)
    n = q.size
    nfft = int(2 ** np.ceil(np.log2(n * pad)))
    spec = np.abs(np.fft.rfft(e, nfft))
    freq = np.fft.rfftfreq(nfft, d=step)
    span = step * (n - 1)
    valid = freq >= min_periods / span
    if not valid[1:-1].any():
        return float("nan")
    i = int(np.argmax(np.where(valid, spec, -np.inf)[:-1]))
    i = min(max(i, 1), len(spec) - 2)
    a, b, c = spec[i - 1], spec[i], spec[i + 1]
    shift = 0.5 * (a - c) / (a - 2 * b + c) if (a - 2 * b + c) != 0 else 0.0
    return float(1.0 / (freq[i] + shift * (freq[1] - freq[0])))


def _axis_of(run: xr.Dataset) -> str:
    plan = str(run.attrs.get("plan", ""))
    if plan in ("characterisation_x", "characterisation_y"):
        return plan[-1]
    moving = [a for a in _AXES if np.ptp(run[f"cmd_{a}"].values) > 0]
    if len(moving) != 1:
        raise DataError(f"run {plan!r}: cannot tell the characterised axis (moving joints: {moving})")
    return moving[0]


def _group_stats(index: np.ndarray, values: np.ndarray, size: int):
    """Mean, range (max - min) and count of ``values`` grouped by flat ``index``."""
    count = np.bincount(index, minlength=size).astype(float)
    total = np.bincount(index, weights=values, minlength=size)
    hi, lo = np.full(size, -np.inf), np.full(size, np.inf)
    np.maximum.at(hi, index, values)
    np.minimum.at(lo, index, values)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(count > 0, total / count, np.nan)
    spread = np.where(count > 1, hi - lo, np.nan)
    return mean, spread, count.astype(np.int32)


def _linear_trend(position: np.ndarray, table: np.ndarray) -> tuple[float, float]:
    """(intercept µm, slope µm/µm) of the direction-averaged table (finite points)."""
    if table.ndim == 2:  # average the directions where both, or one, are finite
        count = np.isfinite(table).sum(axis=1)
        total = np.where(np.isfinite(table), table, 0.0).sum(axis=1)
        mean = np.where(count > 0, total / np.maximum(count, 1), np.nan)
    else:
        mean = table
    ok = np.isfinite(mean)
    if ok.sum() < 2:
        raise DataError("characterisation: fewer than 2 valid positions to fit a linear trend")
    slope, intercept = np.polyfit(position[ok], mean[ok], 1)
    return float(intercept), float(slope)


def characterise_axis(run: xr.Dataset, axis: str | None = None) -> xr.Dataset:
    """Error tables of one characterisation run (Sec. 4.4.1, Fig. 4.7–4.9).

    For the moving axis ``a`` and the other axis ``b``, on dims (``a_position``,
    ``direction``) with direction = [+1, -1]: ``err_aa`` (driving error, target −
    measured), ``err_ab`` (coupling error minus its linear trend ``delta_b``), their
    repeatability ``rep_aa``, ``rep_ab`` (range over cycles, Fig. 4.7), ``cycles_a``
    (valid readings per point); scalars ``delta_b_intercept``, ``delta_b_slope`` and
    ``period_aa``, ``period_ab`` (dominant period of the forward table, µm). Readings
    that are NaN (camera off the pattern) are skipped; ``nan_readings_a`` counts them.
    """
    a = axis or _axis_of(run)
    if a not in _AXES:
        raise ValueError(f"characterise_axis.axis: expected 'x' or 'y', got {a!r}")
    b = "y" if a == "x" else "x"
    u, v = stage_positions(run)
    meas = {"x": u, "y": v}
    direction = run["direction"].values.astype(int)
    rows = (direction != 0) & (run["pose"].values != 0)
    if not rows.any():
        raise DataError(f"run {run.attrs.get('plan')!r}: no forward/backward rows (direction ±1)")
    finite = np.isfinite(u) & np.isfinite(v)
    nan_count = int((rows & ~finite).sum())
    rows &= finite
    q_all = np.round(run[f"cmd_{a}"].values.astype(float), 6)
    positions = np.unique(q_all[(direction != 0) & (run["pose"].values != 0)])
    q = q_all[rows]
    pos_idx = np.searchsorted(positions, q)
    dir_idx = (direction[rows] < 0).astype(int)
    flat = pos_idx * 2 + dir_idx
    size = positions.size * 2
    e_drive = q - meas[a][rows]
    e_cross = run[f"cmd_{b}"].values[rows] - meas[b][rows]
    m_drive, r_drive, count = _group_stats(flat, e_drive, size)
    m_cross, r_cross, _ = _group_stats(flat, e_cross, size)
    shape = (positions.size, 2)
    m_drive, r_drive, m_cross, r_cross = (t.reshape(shape) for t in (m_drive, r_drive, m_cross, r_cross))
    intercept, slope = _linear_trend(positions, m_cross)
    trend = intercept + slope * positions
    m_cross = m_cross - trend[:, None]
    dim = f"{a}_position"
    dims = (dim, "direction")
    moving_name = {"x": "X", "y": "Y"}[a]

    def var(data, dims_, units, long_name):
        return xr.Variable(dims_, data, attrs={"units": units, "long_name": long_name})

    data = {
        f"err_{a}{a}": var(
            m_drive,
            dims,
            "um",
            f"{a} error (target - measured) while {moving_name} moves: "
            f"f_{a}{a} forward, b_{a}{a} backward (Eq. 4.14/4.15, Fig. 4.8)",
        ),
        f"err_{a}{b}": var(
            m_cross,
            dims,
            "um",
            f"{b} coupling error (0 - measured) while {moving_name} moves, "
            f"minus its linear trend delta_{b}: f_{a}{b} / b_{a}{b} (Eq. 4.14/4.15, Fig. 4.9)",
        ),
        f"rep_{a}{a}": var(r_drive, dims, "um", f"repeatability of err_{a}{a}: {REPEATABILITY_DEFINITION}"),
        f"rep_{a}{b}": var(r_cross, dims, "um", f"repeatability of err_{a}{b}: {REPEATABILITY_DEFINITION}"),
        f"cycles_{a}": var(count.reshape(shape), dims, "1", f"valid readings per {a} position and direction"),
        f"delta_{b}": var(
            trend,
            (dim,),
            "um",
            f"linear trend of the {b} error while {moving_name} moves"
            + (" (perpendicularity bias delta_x(y), Eq. 4.14)" if b == "x" else " (X misalignment)"),
        ),
        f"delta_{b}_intercept": var(intercept, (), "um", f"intercept of delta_{b}"),
        f"delta_{b}_slope": var(slope, (), "1", f"slope of delta_{b} (um per um of {a})"),
        f"period_{a}{a}": var(
            dominant_period(positions, m_drive[:, 0]),
            (),
            "um",
            f"dominant period of the detrended forward err_{a}{a} (FFT)",
        ),
        f"period_{a}{b}": var(
            dominant_period(positions, m_cross[:, 0]),
            (),
            "um",
            f"dominant period of the forward err_{a}{b} (FFT)",
        ),
    }
    coords = {
        dim: var(positions, (dim,), "um", f"commanded {moving_name} joint position (table abscissa)"),
        "direction": var(DIRECTIONS, ("direction",), "1", "approach direction (+1 forward, -1 backward)"),
    }
    ds = xr.Dataset(data, coords=coords)
    ds.attrs[f"nan_readings_{a}"] = nan_count
    ds.attrs["repeatability_definition"] = REPEATABILITY_DEFINITION
    return ds


def characterise(run_x: xr.Dataset, run_y: xr.Dataset, meta: RunMetadata | None = None) -> xr.Dataset:
    """Error tables of both XY stages (Sec. 4.4.1) for ``calflow.xytheta.tables.position.PositionLUT``.

    Merges :func:`characterise_axis` of the X and Y runs and adds, from the linear trends,
    ``x_stage_angle`` (angle of X motion from x_PF, = α − 180° of Eq. 4.18) and
    ``perpendicularity`` (angle from X to Y motion minus 90°, = β), both in degrees.
    With ``meta`` the global attributes are those of a ``calflow_kind = "luts"`` file.
    """
    dx, dy = characterise_axis(run_x, "x"), characterise_axis(run_y, "y")
    ds = xr.merge([dx, dy], combine_attrs="no_conflicts")
    k_xx = _linear_trend(ds["x_position"].values, ds["err_xx"].values)[1]
    k_yy = _linear_trend(ds["y_position"].values, ds["err_yy"].values)[1]
    k_xy, k_yx = float(ds["delta_y_slope"]), float(ds["delta_x_slope"])
    theta_x = np.degrees(np.arctan2(-k_xy, 1.0 - k_xx))  # u = (1-k_xx) X, v = -k_xy X
    theta_y = np.degrees(np.arctan2(1.0 - k_yy, -k_yx))  # u = -k_yx Y, v = (1-k_yy) Y
    ds["x_stage_angle"] = xr.Variable(
        (),
        theta_x,
        attrs={
            "units": "degree",
            "long_name": "angle of X-stage motion from x_PF (alpha - 180 deg, Eq. 4.18)",
        },
    )
    ds["perpendicularity"] = xr.Variable(
        (),
        theta_y - theta_x - 90.0,
        attrs={"units": "degree", "long_name": "angle from X to Y motion minus 90 deg (beta, Eq. 4.18)"},
    )
    attrs = meta.attrs("luts") if meta is not None else {}
    ds.attrs = {
        **attrs,
        **dx.attrs,
        **dy.attrs,
        "error_convention": "target - measured, stage frame u = x_m - x_m0, v = y_m - y_m0 (Theta = 0)",
    }
    return ds


def xy_positioning_metrics(run: xr.Dataset, meta: RunMetadata | None = None) -> xr.Dataset:
    """ISO 9283 AP/RP per target of a square or random-points run (Fig. 4.13, 4.15).

    Attained positions are the stage-frame u, v (µm) of :func:`stage_positions`;
    commands are ``target_x``, ``target_y``. Visits with NaN readings are skipped
    (``nan_readings``); targets left with fewer than 2 visits are dropped
    (``skipped_targets``). ``accuracy_um`` / ``repeatability_um`` are the maxima.
    """
    u, v = stage_positions(run)
    pose = run["pose"].values
    tx, ty = run["target_x"].values, run["target_y"].values
    finite = np.isfinite(u) & np.isfinite(v)
    rows, skipped = [], []
    for p in np.unique(pose[pose > 0]):
        at = pose == p
        sel = at & finite
        if sel.sum() < 2:
            skipped.append(int(p))
            continue
        r = iso9283([tx[sel][0], ty[sel][0]], np.column_stack([u[sel], v[sel]]))
        rows.append((int(p), tx[sel][0], ty[sel][0], r.ap, r.rp, *r.ap_components, int(sel.sum())))
    if not rows:
        raise DataError(f"run {run.attrs.get('plan')!r}: no target with 2 valid visits")
    cols = np.array(rows, dtype=float).T

    def var(values, units, long_name):
        return xr.Variable(("target",), values, attrs={"units": units, "long_name": long_name})

    ds = xr.Dataset(
        {
            "target_x": var(cols[1], "um", "stage-frame target x"),
            "target_y": var(cols[2], "um", "stage-frame target y"),
            "ap": var(cols[3], "um", "ISO 9283 position accuracy AP"),
            "rp": var(cols[4], "um", "ISO 9283 position repeatability RP"),
            "ap_x": var(cols[5], "um", "barycentre minus target, x"),
            "ap_y": var(cols[6], "um", "barycentre minus target, y"),
            "visits": var(cols[7].astype(np.int32), "1", "number of valid visits"),
        },
        coords={"target": var(cols[0].astype(np.int32), "1", "plan pose index of the target")},
        attrs=meta.attrs("metrics") if meta is not None else {},
    )
    ds.attrs.update(
        accuracy_um=float(ds["ap"].max()),
        repeatability_um=float(ds["rp"].max()),
        nan_readings=int((~finite & (pose > 0)).sum()),
        skipped_targets=len(skipped),
    )
    return ds
