"""ISO 9283 position stabilisation time (7.5) and overshoot (7.6) of a nano step-response run.

The run (:func:`calflow.acquisition.recorded_moves.acquire_recorded_moves`, plan
:func:`calflow.nano.plans.sequences.step_response`) holds, per move, the record of the sensors along
the stage's joints from the start of the move (``record_time``, ``record_meas_*``) and the
attained position P_a (the sample's ``meas_*``, the mean of the record's last milliseconds).

Limit band (ISO 9283:1998, 7.5): the pose repeatability RP, or a band the manufacturer
states. Here: the run's ``band_nm`` attribute when the campaign sets one, else the largest
RP (7.2.2, l̄ + 3 S_l over the cycles) of the run's poses. Per move,
:func:`calflow.metrics.iso9283_stabilisation` gives the time from the first entry into the
band to the start of the final stay, and the overshoot (largest distance to P_a after the
first entry, 0 when it stays inside). A step passes through the band faster than a record
period (at 1 kHz a 10 µm step crosses a 0.1 µm band in about 0.05 ms), so the record is read
as the straight segments between its points: between each two points the point of the
segment closest to P_a is added, and a pass through the band between two points counts as
the first entry (at the closest approach, within a record period of the true instant). The standard averages each over the cycles: per pose
(a step out or back) the mean over cycles; the entry reports the largest mean over poses,
and every pose's means beside it. Lengths in nm out, times in s.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from calflow.metrics import iso9283, iso9283_stabilisation

__all__ = ["stabilisation_entries"]

NM_PER_UM = 1000.0


def _axes(run: xr.Dataset) -> list[str]:
    return [a for a in ("x", "y") if f"cmd_{a}" in run and f"record_meas_{a}" in run]


def _band_um(run: xr.Dataset, attained: np.ndarray, pose: np.ndarray) -> tuple[float, str]:
    if "band_nm" in run.attrs:
        return float(run.attrs["band_nm"]) / NM_PER_UM, "the band the campaign states (step_response.band_nm)"
    rps = [
        iso9283(attained[pose == p].mean(axis=0), attained[pose == p]).rp
        for p in np.unique(pose)
        if (pose == p).sum() >= 2
    ]
    if not rps or not max(rps) > 0:
        raise ValueError(
            "step_response run: the band is RP, which needs two cycles of a pose and attained positions "
            "that differ; set step_response.band_nm"
        )
    return max(rps), "RP (clause 7.2.2), the largest over the run's poses"


def _with_closest_points(t: np.ndarray, x: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The record (times ``t``, points ``x`` (n, d)) with, between each two consecutive points,
    the point of the straight segment joining them closest to ``p`` (module docstring)."""
    d = np.diff(x, axis=0)
    length2 = np.sum(d * d, axis=1)
    u = np.where(length2 > 0, np.sum((p - x[:-1]) * d, axis=1) / np.where(length2 > 0, length2, 1.0), 0.0)
    mid = (u > 0) & (u < 1)
    tm = t[:-1][mid] + u[mid] * np.diff(t)[mid]
    xm = x[:-1][mid] + u[mid, None] * d[mid]
    order = np.argsort(np.concatenate([t, tm]), kind="stable")
    return np.concatenate([t, tm])[order], np.concatenate([x, xm])[order]


def stabilisation_entries(run: xr.Dataset) -> tuple[dict, dict]:
    """The ``stabilisation_time_s`` (clause 7.5, s) and ``overshoot`` (7.6, nm) entries of a
    step-response run (module docstring): ``{"value", "unit", "clause", ...}``; a null value
    comes with a ``reason``."""
    axes = _axes(run)
    t = np.asarray(run["record_time"].values, dtype=float)
    rec = np.stack([np.asarray(run[f"record_meas_{a}"].values, dtype=float) for a in axes], axis=-1)
    attained = np.stack([np.asarray(run[f"meas_{a}"].values, dtype=float) for a in axes], axis=-1)
    pose = np.asarray(run["pose"].values)
    step = np.asarray(run[f"step_{axes[0]}"].values, dtype=float)
    band, band_def = _band_um(run, attained, pose)
    ts = np.full(pose.size, np.nan)
    ov = np.full(pose.size, np.nan)
    for i in range(pose.size):
        ti, xi = _with_closest_points(t[i], rec[i], attained[i])
        r = iso9283_stabilisation(ti, xi, attained[i], band)
        ts[i], ov[i] = r.stabilisation_time_s, r.overshoot
    per_pose = []
    for p in np.unique(pose):
        at = pose == p
        per_pose.append(
            {
                "step_um": float(np.median(step[at])),
                "cycles": int(at.sum()),
                "stabilised": int(np.isfinite(ts[at]).sum()),
                "stabilisation_time_s": float(np.nanmean(ts[at])) if np.isfinite(ts[at]).any() else None,
                "overshoot_nm": float(np.nanmean(ov[at]) * NM_PER_UM) if np.isfinite(ov[at]).any() else None,
            }
        )
    common = {
        "source": "step_response run",
        "band_nm": band * NM_PER_UM,
        "band": band_def,
        "record_s": float(run.attrs.get("record_s", np.nan)),
        "rate_hz": float(run.attrs.get("record_rate_hz", np.nan)),
        "per_step": per_pose,
        "over": "mean over cycles per step (out and back), the largest over the steps; the stage's closed loop, "
        "the same for every test type",
    }
    reason = (
        "not supported by this data: no move of the step_response run stays inside the band until the end of "
        "its record (record longer, or state a wider band)"
    )
    t_means = [e["stabilisation_time_s"] for e in per_pose if e["stabilisation_time_s"] is not None]
    o_means = [e["overshoot_nm"] for e in per_pose if e["overshoot_nm"] is not None]
    stab = {"value": max(t_means) if t_means else None, "unit": "s", "clause": "7.5", **common}
    over = {"value": max(o_means) if o_means else None, "unit": "nm", "clause": "7.6", **common}
    for e in (stab, over):
        if e["value"] is None:
            e["reason"] = reason
    return stab, over
