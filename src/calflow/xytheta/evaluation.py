"""Accuracy and repeatability of a validation run (thesis Sec. 4.5.5, ISO 9283).

The vision readings of a validation run are put in the world frame with Eq. (4.27),
the first sample (the home pose P0) giving x_m0, y_m0; each target's visits are then
scored with ISO 9283 AP and RP, and the test's accuracy and repeatability are the
maxima over targets (Sec. 3.2.3).
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from calflow.data.runs import RunMetadata
from calflow.errors import DataError
from calflow.metrics import iso9283
from calflow.xytheta.models.kinematics import world_from_pattern


def attained_points(run: xr.Dataset) -> tuple[np.ndarray, np.ndarray]:
    """Tool points (µm) in the world frame for every sample of an XYΘ run, Eq. (4.27).

    The home sample (pose 0) defines the world frame: its reading is (x_m0, y_m0) and
    its angle reading is Θ = 0.
    """
    home = np.flatnonzero(run["pose"].values == 0)
    if home.size == 0:
        raise DataError(f"run {run.attrs.get('plan')!r}: no home sample (pose 0) to define the world frame")
    h = home[0]
    theta = run["meas_theta"].values - run["meas_theta"].values[h]
    x_m0, y_m0 = run["meas_x"].values[h], run["meas_y"].values[h]
    return world_from_pattern(run["meas_x"].values, run["meas_y"].values, theta, x_m0, y_m0)


def xytheta_validation_metrics(run: xr.Dataset, meta: RunMetadata) -> xr.Dataset:
    """ISO 9283 AP and RP per validation target (µm) and their maxima."""
    x, y = attained_points(run)
    poses = np.unique(run["pose"].values[run["pose"].values > 0])
    rows, scatter = [], []
    for p in poses:
        sel = (run["pose"].values == p) & np.isfinite(x) & np.isfinite(y)
        if sel.sum() < 2:
            raise DataError(
                f"run {run.attrs.get('plan')!r}: target {p} has {sel.sum()} valid visits, expected >= 2"
            )
        command = np.array([run["target_x"].values[sel][0], run["target_y"].values[sel][0]])
        result = iso9283(command, np.column_stack([x[sel], y[sel]]))
        rows.append((p, command, run["target_theta"].values[sel][0], result, int(sel.sum())))
        scatter.append(np.column_stack([x[sel] - x[sel].mean(), y[sel] - y[sel].mean()]))

    def var(values, units, long_name):
        return xr.Variable(("target",), np.asarray(values), attrs={"units": units, "long_name": long_name})

    ds = xr.Dataset(
        {
            "target_x": var([r[1][0] for r in rows], "um", "target x in the world frame"),
            "target_y": var([r[1][1] for r in rows], "um", "target y in the world frame"),
            "target_theta": var([r[2] for r in rows], "degree", "target rotation angle"),
            "ap": var([r[3].ap for r in rows], "um", "ISO 9283 position accuracy AP"),
            "rp": var([r[3].rp for r in rows], "um", "ISO 9283 position repeatability RP"),
            "ap_x": var([r[3].ap_components[0] for r in rows], "um", "barycentre minus command, x"),
            "ap_y": var([r[3].ap_components[1] for r in rows], "um", "barycentre minus command, y"),
            "visits": var([r[4] for r in rows], "1", "number of valid visits"),
        },
        coords={
            "target": xr.Variable(
                ("target",),
                np.array([r[0] for r in rows], dtype="int32"),
                attrs={"units": "1", "long_name": "validation target index"},
            )
        },
        attrs=meta.attrs("metrics"),
    )
    ds.attrs["accuracy_um"] = float(ds["ap"].max())
    ds.attrs["repeatability_um"] = float(ds["rp"].max())
    # the repeatability floor: pooled within-target scatter per reading and axis (µm), with
    # its degrees of freedom — what a model's fit residual is compared with (adequacy)
    dev = np.vstack(scatter)
    dof = 2 * (len(dev) - len(scatter))
    ds.attrs["within_target_std_um"] = float(np.sqrt(np.sum(dev**2) / dof)) if dof > 0 else float("nan")
    ds.attrs["within_target_dof"] = int(dof)
    return ds
