"""What an interim check asks of the stage, checked when its campaign is loaded.

* **Its tolerance.** The sequential test decides between H0, the reference calibration's own
  rms visit error through its bundle (r0, ``results/<reference>/runs/export_<model>.nc``),
  and H1, the tolerance (``interim_check.tolerance_um``, else the campaign's
  ``tolerance_um``): a tolerance is required, and must exceed r0 — checked here when the
  reference's closed-loop check is on disk (once the check has run, against the r0 its
  summary recorded from that run: no netCDF is read), else by the check's acquisition before
  the rig moves (:func:`calflow.xytheta.plans.interim.interim_check`).
* **Its rig time.** A check is worth running when it costs a small fraction of a
  calibration (:data:`BUDGET`, 5 %). The sequential test
  may stop after two cycles, but the plan asks for up to ``targets × cycles`` visits, each
  at least ``dwell_s``: that worst case, dwell alone, is checked against the budget of an
  upper estimate of the reference's rig time from its plan — each planned visit its dwell
  plus :data:`MOVE_S` of motion (no file is read: loading stays cheap). A check refused here
  would exceed the budget whatever its moves cost; the summary compares the rig times as
  acquired.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from calflow.configuration import layout
from calflow.errors import ConfigError

if TYPE_CHECKING:
    import xarray as xr

#: An interim check's rig time, at most this fraction of a full calibration's.
BUDGET = 0.05
#: Upper estimate of one move of an XYΘ stage between two visits (s): the whole 9.45 mm X
#: travel at 1 mm/s, Θ's 5° at 1°/s, with settling, take well under a minute.
MOVE_S = 60.0


def rig_time_s(run: xr.Dataset) -> float:
    """Span of the run's time axis (s): its last reading minus its first."""
    t = np.asarray(run["time"].values, dtype=float)
    return float(np.nanmax(t) - np.nanmin(t)) if t.size else 0.0


def visit_errors(run: xr.Dataset, mode: int | None = None) -> np.ndarray:
    """(n, 2) errors (µm) of the visits (pose > 0) of a closed-loop run, world frame (Eq. 4.27);
    only segment ``mode`` (``test_mode``) when given."""
    from calflow.xytheta.evaluation import attained_points

    if mode is not None and "test_mode" in run:
        run = run.isel(sample=run["test_mode"].values == mode)
    x, y = attained_points(run)
    keep = run["pose"].values > 0
    return np.column_stack([x[keep] - run["target_x"].values[keep], y[keep] - run["target_y"].values[keep]])


def reference_rms_um(export_run: xr.Dataset) -> float:
    """r0 (µm): the rms visit error of the reference's closed-loop check through its bundle."""
    return float(np.sqrt(np.mean(np.sum(visit_errors(export_run, mode=0) ** 2, axis=1))))


def recorded_reference_rms_um(name: str, reference: str) -> float | None:
    """r0 (µm) as the check's summary recorded it (``interim_check.reference_rms_um``) when the
    summary is newer than the reference's closed-loop run ``reference`` (so it was computed
    from that run), else None. Reading a JSON file keeps a no-op run's parse free of netCDF."""
    summary = layout.summary(name)
    try:
        if os.stat(summary).st_mtime < os.stat(reference).st_mtime:
            return None
        with open(summary, encoding="utf-8") as fh:
            r0 = json.load(fh)["interim_check"]["reference_rms_um"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return float(r0) if isinstance(r0, (int, float)) and not isinstance(r0, bool) else None


def check_tolerance(campaign: dict, path: Path) -> None:
    """A tolerance is given, and exceeds the reference's own error when that is on disk."""
    check = campaign["interim_check"]
    tol = check.get("tolerance_um", campaign.get("tolerance_um"))
    if tol is None:
        raise ConfigError(
            f"{path}: key 'interim_check.tolerance_um': missing; expected the rms visit error (µm) "
            "at which to recalibrate, here or as the campaign's tolerance_um"
        )
    reference = layout.run(check["reference"], f"export_{check['model']}")
    if not os.path.exists(reference):
        return  # not yet known: the check's acquisition checks it before the rig moves
    if os.path.exists(layout.run(path.stem, "interim_check")):
        r0 = recorded_reference_rms_um(path.stem, reference)
        if r0 is None:
            return  # the check ran against another reference run: its rerun's acquisition checks
    else:
        from calflow.data.io import open_dataset

        r0 = reference_rms_um(open_dataset(reference, kind="run"))
    if not tol > r0:
        where = "interim_check.tolerance_um" if "tolerance_um" in check else "tolerance_um"
        raise ConfigError(
            f"{path}: key '{where}': expected a tolerance above the reference's own rms visit error "
            f"through its bundle ({r0:.4g} µm, {reference}), got {tol!r}"
        )


def _positions(stop_um: float, step_um: float) -> int:
    return int(math.floor(stop_um / step_um + 1e-9)) + 1


def planned_visits(ref: dict) -> list[tuple[int, float]]:
    """(visits, dwell_s) of each run a calibration plans: the characterisation sweeps (forward
    and backward over each axis), the identification poses, the reference-target and held-out
    validations and the export check of each model (one visit of home per run)."""
    from calflow.xytheta.plans.poses import TABLE_4_7

    models = list(ref["models"])
    ch, ident, val = ref["characterisation"], ref["identification"], ref["validation"]
    out = []
    if ref["xy_tests"]["compensation"] or any(s.get("position_table") for s in ref["models"].values()):
        for axis in ("x", "y"):
            out.append((2 * _positions(ch[f"{axis}_stop_um"], ch["step_um"]) * ch["cycles"], ch["dwell_s"]))
    out.append((ident["poses"] + 1, ident["dwell_s"]))
    heldout = val["heldout"]
    targets = val.get("targets")
    n_reference = len(TABLE_4_7) if targets is None else len(targets)  # Table 4.7's when absent
    for _ in models:
        out.append((heldout["targets"] * heldout["cycles"] + 1, val["dwell_s"]))
        if n_reference:
            out.append((n_reference * val["cycles"] + 1, val["dwell_s"]))
    return out


def check_rig_time(campaign: Mapping, path: Path, ref: Mapping) -> None:
    """The check's worst case, dwell alone, within the budget of the reference's rig time
    (``ref``, the reference campaign)."""
    check = campaign["interim_check"]
    asked = check["targets"] * check["cycles"] * float(check["dwell_s"])
    reference = sum(n * (dwell + MOVE_S) for n, dwell in planned_visits(ref))
    how = f"at most, each planned visit its dwell plus {MOVE_S:g} s of motion"
    if asked > BUDGET * reference:
        raise ConfigError(
            f"{path}: key 'interim_check.cycles': expected a check within {BUDGET:.0%} of the "
            f"reference's rig time ({BUDGET * reference:.4g} s of {reference:.4g} s, {how}); "
            f"{check['targets']} targets x {check['cycles']} cycles x {check['dwell_s']:g} s of "
            f"dwell ask for {asked:.4g} s"
        )
