"""Metrics of the nanopositioning runs (thesis Sec. 3.2.3, 5.2.5, 5.3.3, 5.4.2).

Run datasets in (dimension ``sample``, lengths in µm, ``time`` in s since the campaign
start), metrics datasets out (dimensions ``test`` × ``pose``, AP/RP in nm).  The
interferometer readings ``meas_x`` (``meas_y``) are already world positions (zeroed at the
start of training, Sec. 5.3.1), directly comparable with ``target_x`` (``target_y``).

* A *test* is the set of cycles a validation run spends in one mode (15 cycles, ≈ 1.25 h
  for the 1-DoF stage).  Metrology and training runs are one test, number 0, mode 0.
* A *pose* is the plan's pose index within a cycle, so forward and backward visits of the
  same position are different poses (1-DoF validation: 0..12 = 0:80:480 forward then
  400..0 backward; Fig. 5.13-5.16 plot them so).
* Per (test, pose), ISO 9283 over the visits of that test (one per cycle): AP = |x̄ − x_T|
  and RP = l̄ + 3 S_l (Eq. 3.5-3.8; d = 1 gives Eq. 3.13-3.18).  A test's accuracy and
  repeatability are the maxima over its poses (Sec. 3.2.3, "Summary").

Extrinsic / intrinsic repeatability (Eq. 3.15-3.18) needs the drift L_i (T_i after
calibration) of every visit.  Analysis uses only measured data, so it is *estimated* as
the slow common-mode part of the deviations (:func:`common_mode_drift`): within a test, the
deviation e = x_m − x_T of each sample minus the test mean of its pose (which removes
g(x_T) + P̄ + L̄), averaged over all valid samples of the same cycle.  That is, per cycle,
the mean deviation over the poses of the cycle minus its test mean; with missing samples
the per-pose centring keeps g(x_T) out of it.  It is one value (vector for d = 2) per
cycle, held for every pose of the cycle (a cycle lasts ≈ 5 min, the drift hours).  Its mean
over a test is zero by construction, so it splits RP only, never AP: the absolute drift
level L̄ cannot be told from g(x_T) without a reference.  The estimate carries 1/M of each
pose's intrinsic scatter (M poses per cycle), so the intrinsic part is slightly low.
"""

from __future__ import annotations

import warnings
from contextlib import contextmanager

import numpy as np
import xarray as xr

from calflow.data.conventions import utc_now
from calflow.errors import DataError
from calflow.metrics import decompose_repeatability, iso9283
from calflow.metrics.iso230_2_runs import iso230_2_of_run  # noqa: F401 (re-exported)

NM_PER_UM = 1000.0
MODES = {"stage1d": ("no_calibration", "adaptive_kmz", "single"), "stage2d": ("no_calibration", "single")}

__all__ = [
    "MODES",
    "accuracy_vs_temperature",
    "common_mode_drift",
    "iso230_2_of_run",
    "mode_names",
    "pose_metrics",
    "pose_metrics_1d",
    "pose_metrics_2d",
    "run_columns",
    "run_seconds",
    "temperature_range",
]


def _where(run: xr.Dataset) -> str:
    return f"run {run.attrs.get('campaign', '?')}/{run.attrs.get('plan', '?')}"


def run_seconds(run: xr.Dataset) -> np.ndarray:
    """``time`` of each sample in seconds since the campaign start (float, CF-decoded or not)."""
    t = run["time"]
    v = t.values
    if np.issubdtype(v.dtype, np.timedelta64):
        return v / np.timedelta64(1, "s")
    if np.issubdtype(v.dtype, np.datetime64):
        units = t.encoding.get("units", "")
        if " since " not in units:
            raise DataError(
                f"{_where(run)}: decoded time has no 'since' origin; open it with decode_times=False"
            )
        origin = np.datetime64(units.split(" since ", 1)[1].strip().split("+")[0].replace(" ", "T"))
        return (v - origin) / np.timedelta64(1, "s")
    return np.asarray(v, dtype=float)


@contextmanager
def _quiet():
    """Silence numpy's 'mean of empty slice' warnings (all-NaN rows give NaN, as wanted)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        yield


def _sensor_mean(run: xr.Dataset) -> np.ndarray:
    """Mean of the thermocouples at each sample (degC); NaN when the run has none."""
    if "temperature" not in run:
        return np.full(run.sizes["sample"], np.nan)
    t = run["temperature"]
    values = t.transpose("sample", ...).values.reshape(run.sizes["sample"], -1)
    with _quiet():
        return np.nanmean(values, axis=1)


def mode_names(run_or_metrics: xr.Dataset) -> tuple[str, ...]:
    """Names of the test-mode values: the ``flag_meanings`` of ``test_mode`` (or ``mode``),
    else the robot's default order (Sec. 5.3.3: no calibration, adaptive KMZ, single)."""
    for name in ("test_mode", "mode"):
        if name in run_or_metrics and "flag_meanings" in run_or_metrics[name].attrs:
            return tuple(str(run_or_metrics[name].attrs["flag_meanings"]).split())
    return MODES.get(run_or_metrics.attrs.get("robot", "stage1d"), MODES["stage1d"])


def common_mode_drift(
    deviation: np.ndarray, test: np.ndarray, cycle: np.ndarray, pose: np.ndarray
) -> np.ndarray:
    """Estimated extrinsic drift L_i (Eq. 3.15-3.18) of each sample, in the deviation's unit.

    ``deviation`` (n, d) = x_m − x_T (NaN rows ignored).  Within each test, each sample's
    deviation minus the test mean of its pose, averaged over the samples of its cycle
    (see the module docstring).  Returns (n, d); NaN for samples whose cycle has no valid
    sample.
    """
    dev = np.asarray(deviation, dtype=float)
    out = np.full(dev.shape, np.nan)
    valid = np.all(np.isfinite(dev), axis=1)
    for t in np.unique(test):
        in_test = (test == t) & valid
        resid = np.full(dev.shape, np.nan)
        for p in np.unique(pose[in_test]):
            sel = in_test & (pose == p)
            resid[sel] = dev[sel] - dev[sel].mean(axis=0)
        for c in np.unique(cycle[test == t]):
            cyc = (test == t) & (cycle == c)
            ok = cyc & valid
            if ok.any():
                out[cyc] = resid[ok].mean(axis=0)
    return out


def _decompose(att: np.ndarray, target: np.ndarray, ext: np.ndarray) -> tuple[float, float, float, float]:
    """(rp_intrinsic, intrinsic_term, extrinsic_term, rp_bound) of one pose, Eq. (3.14)/(3.16).

    d = 1: :func:`calflow.metrics.decompose_repeatability`.  d = 2: the same with distances,
    l_j = |P_j − P̄ + L_j − L̄| <= |P_j − P̄| + |L_j − L̄| (triangle inequality)."""
    if att.shape[1] == 1:
        r = decompose_repeatability(att[:, 0], target[0], ext[:, 0])
        return r.rp_intrinsic, r.intrinsic_term, r.extrinsic_term, r.rp_bound
    full = iso9283(target, att)
    corrected = att - ext
    p_dev = corrected - corrected.mean(axis=0)
    l_dev = ext - ext.mean(axis=0)
    i_term = float(np.linalg.norm(p_dev, axis=1).mean())
    e_term = float(np.linalg.norm(l_dev, axis=1).mean())
    return iso9283(target, corrected).rp, i_term, e_term, i_term + e_term + 3.0 * full.s_l


def run_columns(run: xr.Dataset, axes) -> tuple[np.ndarray, ...]:
    """The per-sample columns of a nano run over ``axes``: ``meas``, ``target`` (n, d) in µm,
    then ``pose``, ``cycle``, ``direction``, ``test``, ``mode`` (int; 0 where the run has no
    such variable) and ``hours`` since the campaign start.  A missing reading, target,
    pose, cycle or time is a :class:`DataError` naming the run and the variable."""
    for name in [f"meas_{a}" for a in axes] + [f"target_{a}" for a in axes] + ["pose", "cycle", "time"]:
        if name not in run:
            raise DataError(f"{_where(run)}: variable {name!r} is missing; a nano run needs it")
    n = run.sizes["sample"]
    meas = np.column_stack([run[f"meas_{a}"].values.astype(float) for a in axes])
    tgt = np.column_stack([run[f"target_{a}"].values.astype(float) for a in axes])
    mode_var = "test_mode" if "test_mode" in run else "mode" if "mode" in run else None
    ints = [
        run[v].values.astype(int) if v is not None and v in run else np.zeros(n, int)
        for v in ("pose", "cycle", "direction", "test", mode_var)
    ]
    return (meas, tgt, *ints, run_seconds(run) / 3600.0)


def pose_metrics(run: xr.Dataset, axes: tuple[str, ...]) -> xr.Dataset:
    """ISO 9283 AP and RP (nm) per test and pose of a nano run over ``axes`` (d = len(axes)).

    See the module docstring.  Samples with a NaN reading or target are dropped; a
    (test, pose) with fewer than 2 valid visits gets NaN.  Per test: mean time (h since
    campaign start), first/last sample time (h), mean of the thermocouples (degC) and its
    range, min and max within the test, the mode, and the maxima of AP and RP over poses.
    """
    n = run.sizes["sample"]
    meas, tgt, pose, cycle, direction, test, mode, hours = run_columns(run, axes)
    temp = _sensor_mean(run)
    names = mode_names(run)

    tests, poses = np.unique(test), np.unique(pose)
    targets = np.full((poses.size, len(axes)), np.nan)
    pose_dir = np.zeros(poses.size, int)
    for k, p in enumerate(poses):
        tp = tgt[pose == p]
        tp = tp[np.all(np.isfinite(tp), axis=1)]
        if tp.size == 0:
            raise DataError(f"{_where(run)}: pose {p} has no finite target")
        if np.ptp(tp, axis=0).max() > 1e-6:
            raise DataError(
                f"{_where(run)}: pose {p} has several targets ({np.unique(tp, axis=0)[:3].tolist()} um); "
                "one target per pose expected"
            )
        targets[k] = tp[0]
        pose_dir[k] = direction[pose == p][0]
    dev = meas - tgt
    valid = np.all(np.isfinite(dev), axis=1)
    drift = common_mode_drift(dev, test, cycle, pose)

    shape = (tests.size, poses.size)
    cells = {
        k: np.full(shape, np.nan)
        for k in ("ap", "rp", "rp_intrinsic", "intrinsic_term", "extrinsic_term", "rp_bound")
    }
    bias = np.full(shape + (len(axes),), np.nan)
    visits = np.zeros(shape, int)
    per_test = {
        k: np.full(tests.size, np.nan)
        for k in (
            "time_h",
            "time_start_h",
            "time_end_h",
            "temperature_c",
            "temperature_min_c",
            "temperature_max_c",
        )
    }
    test_mode = np.zeros(tests.size, int)
    for i, t in enumerate(tests):
        in_t = test == t
        modes_t = np.unique(mode[in_t])
        if modes_t.size != 1:
            raise DataError(
                f"{_where(run)}: test {t} mixes modes {modes_t.tolist()}; one mode per test expected"
            )
        test_mode[i] = modes_t[0]
        h = hours[in_t]
        per_test["time_h"][i], per_test["time_start_h"][i], per_test["time_end_h"][i] = (
            h.mean(),
            h.min(),
            h.max(),
        )
        tt = temp[in_t][np.isfinite(temp[in_t])]
        if tt.size:
            per_test["temperature_c"][i], per_test["temperature_min_c"][i] = tt.mean(), tt.min()
            per_test["temperature_max_c"][i] = tt.max()
        for k, p in enumerate(poses):
            sel = in_t & (pose == p) & valid
            visits[i, k] = sel.sum()
            if visits[i, k] < 2:
                continue
            r = iso9283(targets[k], meas[sel])  # Eq. (3.5)-(3.8); d = 1: Eq. (3.13)/(3.14)
            cells["ap"][i, k], cells["rp"][i, k] = r.ap, r.rp
            bias[i, k] = r.ap_components
            parts = _decompose(meas[sel], targets[k], drift[sel])  # Eq. (3.16)/(3.18)
            for key, value in zip(("rp_intrinsic", "intrinsic_term", "extrinsic_term", "rp_bound"), parts):
                cells[key][i, k] = value

    def tp(values, long_name):
        return xr.Variable(
            ("test", "pose"), values * NM_PER_UM, attrs={"units": "nm", "long_name": long_name}
        )

    def tv(values, units, long_name):
        return xr.Variable(("test",), values, attrs={"units": units, "long_name": long_name})

    with _quiet():
        ap_max, rp_max = np.nanmax(cells["ap"], axis=1), np.nanmax(cells["rp"], axis=1)
    data = {
        "ap": tp(cells["ap"], "ISO 9283 pose accuracy AP, Eq. (3.13)/(3.15)/(3.17)"),
        "rp": tp(cells["rp"], "ISO 9283 pose repeatability RP, Eq. (3.14)/(3.16)/(3.18)"),
        "rp_intrinsic": tp(cells["rp_intrinsic"], "RP of the readings minus the estimated drift, Eq. (3.14)"),
        "rp_intrinsic_term": tp(cells["intrinsic_term"], "(1/n) sum |P_i - mean P|, Eq. (3.16)"),
        "rp_extrinsic_term": tp(
            cells["extrinsic_term"], "(1/n) sum |L_i - mean L| (estimated drift), Eq. (3.16)"
        ),
        "rp_bound": tp(
            cells["rp_bound"], "intrinsic term + extrinsic term + 3 sigma, right side of Eq. (3.16)"
        ),
        "visits": xr.Variable(("test", "pose"), visits, attrs={"units": "1", "long_name": "valid visits"}),
        "ap_max": tv(ap_max * NM_PER_UM, "nm", "accuracy of the test, max over poses of AP (Sec. 3.2.3)"),
        "rp_max": tv(
            rp_max * NM_PER_UM, "nm", "repeatability of the test, max over poses of RP (Sec. 3.2.3)"
        ),
        "time_h": tv(per_test["time_h"], "h", "mean sample time of the test since campaign start"),
        "time_start_h": tv(
            per_test["time_start_h"], "h", "first sample time of the test since campaign start"
        ),
        "time_end_h": tv(per_test["time_end_h"], "h", "last sample time of the test since campaign start"),
        "temperature_c": tv(per_test["temperature_c"], "degC", "test mean of the thermocouple mean"),
        "temperature_min_c": tv(
            per_test["temperature_min_c"], "degC", "min of the thermocouple mean in the test"
        ),
        "temperature_max_c": tv(
            per_test["temperature_max_c"], "degC", "max of the thermocouple mean in the test"
        ),
        "temperature_range_c": tv(
            per_test["temperature_max_c"] - per_test["temperature_min_c"],
            "degC",
            "range of the thermocouple mean within the test",
        ),
        "mode": xr.Variable(
            ("test",),
            test_mode,
            attrs={
                "units": "1",
                "long_name": "test mode",
                "flag_values": list(range(len(names))),
                "flag_meanings": " ".join(names),
            },
        ),
        "direction": xr.Variable(
            ("pose",), pose_dir, attrs={"units": "1", "long_name": "approach direction"}
        ),
    }
    for j, a in enumerate(axes):
        data[f"target_{a}"] = xr.Variable(
            ("pose",), targets[:, j], attrs={"units": "um", "long_name": f"target {a}"}
        )
        data[f"bias_{a}"] = tp(bias[..., j], f"mean {a} deviation from target (signed), x̄ - x_T")
    coords = {
        "test": xr.Variable(("test",), tests, attrs={"units": "1", "long_name": "test index"}),
        "pose": xr.Variable(("pose",), poses, attrs={"units": "1", "long_name": "pose index within a cycle"}),
    }
    if "kmz_visit" in run.dims and "kmz_time" in run and "kmz_measured" in run and "kmz_command" in run:
        kt = run["kmz_time"].values
        kt = kt / np.timedelta64(1, "s") if np.issubdtype(kt.dtype, np.timedelta64) else kt.astype(float)
        data["kmz_time_h"] = xr.Variable(
            ("kmz_visit",), kt / 3600.0, attrs={"units": "h", "long_name": "KMZ visit time"}
        )
        data["kmz_offset"] = xr.Variable(
            ("kmz_visit",),
            (run["kmz_measured"].values - run["kmz_command"].values) * NM_PER_UM,
            attrs={"units": "nm", "long_name": "KMZ reading minus command"},
        )
    attrs = {k: v for k, v in run.attrs.items() if k not in ("created", "dwell_s")}
    attrs.update(
        calflow_kind="metrics",
        created=utc_now(),
        axes=" ".join(axes),
        start_time_h=float(np.nanmin(hours)) if n else float("nan"),
        end_time_h=float(np.nanmax(hours)) if n else float("nan"),
        drift_estimator="per-cycle mean of pose-centred deviations within each test (no simulated truth)",
    )
    return xr.Dataset(data, coords=coords, attrs=attrs)


def pose_metrics_1d(run: xr.Dataset) -> xr.Dataset:
    """AP and RP (nm) per (test, pose) of a 1-DoF stage run, d = 1 (Eq. 3.13-3.18); see
    :func:`pose_metrics`.  ``meas_y`` (the coupling beam) is not part of d = 1."""
    return pose_metrics(run, ("x",))


def pose_metrics_2d(run: xr.Dataset) -> xr.Dataset:
    """AP and RP (nm) per (test, pose) of a 2-DoF stage run over (x, y), d = 2 (Eq. 3.5-3.8)."""
    return pose_metrics(run, ("x", "y"))


def temperature_range(run: xr.Dataset) -> tuple[float, float]:
    """[min, max] (degC) of the thermocouple mean over a run (e.g. the training run)."""
    t = _sensor_mean(run)
    t = t[np.isfinite(t)]
    if t.size == 0:
        raise DataError(f"{_where(run)}: no finite temperature readings")
    return float(t.min()), float(t.max())


def accuracy_vs_temperature(metrics: xr.Dataset, training_range_c: tuple[float, float] | None) -> dict:
    """Per mode, the (mean temperature, max AP) of each test, Fig. 5.20.

    ``in_training_range``: whether all of the test's thermocouple-mean temperatures lie
    within ``training_range_c`` = [min, max] of the training run (:func:`temperature_range`);
    None when no range is given or the test has no temperature.  Lists, nm and degC.
    """
    names = mode_names(metrics)
    out: dict = {}
    for k, name in enumerate(names):
        rows = np.flatnonzero(metrics["mode"].values == k)
        if rows.size == 0:
            continue
        lo_t, hi_t = metrics["temperature_min_c"].values[rows], metrics["temperature_max_c"].values[rows]
        if training_range_c is None:
            inside = [None] * rows.size
        else:
            lo, hi = training_range_c
            inside = [
                None if not (np.isfinite(a) and np.isfinite(b)) else bool(a >= lo and b <= hi)
                for a, b in zip(lo_t, hi_t)
            ]
        out[name] = {
            "test": metrics["test"].values[rows].tolist(),
            "temperature_c": metrics["temperature_c"].values[rows].tolist(),
            "max_ap_nm": metrics["ap_max"].values[rows].tolist(),
            "max_rp_nm": metrics["rp_max"].values[rows].tolist(),
            "in_training_range": inside,
        }
    return out
