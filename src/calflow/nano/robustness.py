"""Robustness of the five-day validation per test mode (thesis Sec. 5.3.3, Table 5.2).

Space robustness R_S, Eq. (5.8), and time robustness R_T, Eq. (5.9), from the per-pose
AP of each test in a validation run's metrics (:func:`calflow.nano.evaluation.pose_metrics`).
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from calflow.metrics import space_robustness, time_robustness
from calflow.nano.evaluation import NM_PER_UM, mode_names


def robustness_by_mode(metrics: xr.Dataset) -> dict:
    """Space and time robustness per test mode (Eq. 5.8, 5.9), as Table 5.2.

    AP_i = the per-pose AP of test i in µm (as Table 5.2).  Per mode, the tests of that
    mode with at least one finite AP (NaN poses dropped).  R_S = mean over tests of
    [max AP_i − min AP_i] in µm; R_T = mean over tests of max AP_i divided by Time, with
    Time = duration spanned by the mode's tests in hours (first sample of its first test
    to last sample of its last test; the thesis does not give the unit), so µm/h.
    Returns ``{mode_name: {"space", "time", "n_tests", "duration_h", "units"}}``; modes
    without tests are left out; ``time`` is None when the duration is not positive.
    """
    names = mode_names(metrics)
    out: dict = {}
    ap_um = metrics["ap"].transpose("test", "pose").values / NM_PER_UM
    mode = metrics["mode"].values
    for k, name in enumerate(names):
        rows = [i for i in np.flatnonzero(mode == k) if np.isfinite(ap_um[i]).any()]
        if not rows:
            continue
        per_test = [ap_um[i][np.isfinite(ap_um[i])] for i in rows]
        duration = float(
            metrics["time_end_h"].values[rows].max() - metrics["time_start_h"].values[rows].min()
        )
        out[name] = {
            "space": space_robustness(per_test),  # Eq. (5.8), µm
            "time": time_robustness(per_test, duration) if duration > 0 else None,  # Eq. (5.9), µm/h
            "n_tests": len(rows),
            "duration_h": duration,
            "units": {"space": "um", "time": "um/h", "ap": "um", "duration": "h"},
        }
    return out
