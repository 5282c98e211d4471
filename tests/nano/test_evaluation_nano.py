"""Nano-stage metrics and summaries on small synthetic runs with hand-known values."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import xarray as xr

from calflow.errors import DataError
from calflow.metrics import iso230_2
from calflow.nano.evaluation import (
    accuracy_vs_temperature,
    iso230_2_of_run,
    pose_metrics_1d,
    pose_metrics_2d,
    temperature_range,
)
from calflow.nano.report.reference import STAGE1D
from calflow.nano.report.summary import stage1d_summary, stage2d_summary
from calflow.nano.robustness import robustness_by_mode

MODES_1D = "no_calibration adaptive_kmz single"
FWD = np.arange(0.0, 481.0, 80.0)
SWEEP = np.concatenate([FWD, FWD[-2::-1]])  # 13 poses: 0..480 then 400..0
DIRS = np.r_[np.ones(7, int), -np.ones(6, int)]
DT_S = 600.0  # one sample every 10 min: a 4-cycle test of 13 poses lasts 8.5 h


def run_1d(dev_um, plan="validation", modes=None, t0_s=0.0, temps=None, positions=SWEEP, dirs=DIRS):
    """A 1-DoF run: ``dev_um`` (tests, cycles, poses) deviations from target, µm."""
    dev_um = np.asarray(dev_um, dtype=float)
    n_t, n_c, n_p = dev_um.shape
    shape = (n_t, n_c, n_p)
    test = np.broadcast_to(np.arange(n_t)[:, None, None], shape).ravel()
    cycle = np.broadcast_to(np.arange(n_c)[None, :, None], shape).ravel()
    pose = np.broadcast_to(np.arange(n_p)[None, None, :], shape).ravel()
    target = np.asarray(positions)[pose]
    n = test.size
    time = t0_s + DT_S * np.arange(n)
    if temps is None:
        temps = 20.0 + 0.1 * test[:, None] + np.array([0.0, 0.01, 0.02, 0.03]) + 0.001 * cycle[:, None]
    data = {
        "time": ("sample", time, {"units": "seconds since 2026-01-01T00:00:00+00:00"}),
        "cmd_x": ("sample", target.copy(), {"units": "um"}),
        "target_x": ("sample", target, {"units": "um"}),
        "meas_x": ("sample", target + dev_um.ravel(), {"units": "um"}),
        "meas_y": ("sample", np.zeros(n), {"units": "um"}),
        "temperature": (("sample", "sensor"), temps, {"units": "degC"}),
        "pose": ("sample", pose),
        "cycle": ("sample", cycle),
        "direction": ("sample", np.asarray(dirs)[pose]),
    }
    if plan == "validation":
        data["test"] = ("sample", test)
        m = test % 3 if modes is None else np.asarray(modes)[test]
        data["test_mode"] = ("sample", m, {"flag_values": [0, 1, 2], "flag_meanings": MODES_1D})
    return xr.Dataset(
        data,
        coords={"sensor": ["T1", "T2", "T3", "T4"]},
        attrs={"robot": "stage1d", "plan": plan, "campaign": "t"},
    )


def hand_rp(x):
    l = np.abs(x - x.mean())
    return l.mean() + 3 * l.std(ddof=1)


@pytest.fixture
def validation():
    rng = np.random.default_rng(3)
    n_t, n_c = 6, 4
    offset = np.array([0.8, 0.05, 0.2, 0.9, 0.04, 0.3])  # µm, per test
    geometric = 0.1 * np.sin(np.arange(13))
    dev = offset[:, None, None] + geometric[None, None, :] + 0.02 * rng.standard_normal((n_t, n_c, 13))
    dev[0, 1, 3] = np.nan  # one lost reading: pose 3 of test 0 has 3 visits
    dev[2, 1:, 5] = np.nan  # only 1 visit left: AP/RP undefined
    return dev, run_1d(dev)


def test_ap_rp_per_pose_equal_hand_computation(validation):
    dev, run = validation
    m = pose_metrics_1d(run)
    assert m["ap"].dims == ("test", "pose") and m.sizes == {"test": 6, "pose": 13}
    for t in range(6):
        for p in range(13):
            x = SWEEP[p] + dev[t, :, p]
            x = x[np.isfinite(x)]
            if x.size < 2:
                assert np.isnan(m["ap"].values[t, p]) and np.isnan(m["rp"].values[t, p])
                continue
            assert m["ap"].values[t, p] == pytest.approx(abs(x.mean() - SWEEP[p]) * 1000, abs=1e-6)
            assert m["rp"].values[t, p] == pytest.approx(hand_rp(x) * 1000, abs=1e-6)
    assert m["visits"].values[0, 3] == 3 and m["visits"].values[2, 5] == 1
    assert np.array_equal(m["mode"].values, np.arange(6) % 3)
    assert m["mode"].attrs["flag_meanings"] == MODES_1D
    np.testing.assert_allclose(m["ap_max"], np.nanmax(m["ap"].values, axis=1))
    np.testing.assert_allclose(m["rp_max"], np.nanmax(m["rp"].values, axis=1))
    assert np.isfinite(m["ap_max"]).all()


def test_known_offsets_give_known_ap():
    # deviations ±a around an offset per test: AP = |offset|, RP = a (all l_j = a, S_l = 0)
    a = 0.03
    offset = np.array([0.5, -0.1, 0.2])
    eps = np.array([-a, a, -a, a])
    dev = offset[:, None, None] + eps[None, :, None] + np.zeros((3, 4, 13))
    m = pose_metrics_1d(run_1d(dev))
    np.testing.assert_allclose(m["ap"], np.abs(offset)[:, None] * 1000 * np.ones((1, 13)), atol=1e-6)
    np.testing.assert_allclose(m["rp"], a * 1000, atol=1e-6)
    np.testing.assert_allclose(m["target_x"], SWEEP)
    np.testing.assert_array_equal(m["direction"], DIRS)


def test_time_and_temperature_per_test(validation):
    _, run = validation
    m = pose_metrics_1d(run)
    per = 4 * 13
    for t in range(6):
        times = DT_S * np.arange(t * per, (t + 1) * per) / 3600
        assert m["time_h"].values[t] == pytest.approx(times.mean())
        assert m["time_start_h"].values[t] == pytest.approx(times[0])
        assert m["time_end_h"].values[t] == pytest.approx(times[-1])
        # thermocouple mean = 20 + 0.1 t + 0.015 + 0.001 cycle
        assert m["temperature_c"].values[t] == pytest.approx(20 + 0.1 * t + 0.015 + 0.0015)
        assert m["temperature_range_c"].values[t] == pytest.approx(0.003)


def test_metrology_run_is_one_test():
    dev = 0.35 + np.zeros((1, 5, 13))
    dev[0, :, 0] += np.array([0, 0.01, 0.02, 0.01, 0])
    m = pose_metrics_1d(run_1d(dev, plan="metrology"))
    assert m.sizes["test"] == 1 and int(m["mode"].values[0]) == 0
    assert m["ap_max"].values[0] == pytest.approx(1000 * (0.35 + 0.008))


def test_drift_decomposition_eq_3_16(validation):
    # pure common-mode drift per cycle + geometric error: the estimator recovers the drift
    drift = np.array([0.0, 0.05, 0.1, 0.2])
    dev = 0.1 * np.cos(np.arange(13))[None, None, :] + drift[None, :, None] + np.zeros((2, 4, 13))
    m = pose_metrics_1d(run_1d(dev))
    np.testing.assert_allclose(m["rp_intrinsic"], 0.0, atol=1e-6)
    np.testing.assert_allclose(m["rp_intrinsic_term"], 0.0, atol=1e-6)
    np.testing.assert_allclose(m["rp_extrinsic_term"], 1000 * np.abs(drift - drift.mean()).mean(), atol=1e-6)
    np.testing.assert_allclose(m["rp"], 1000 * hand_rp(drift), atol=1e-6)
    # with noise: RP <= intrinsic term + extrinsic term + 3σ_E, equality of the bound's parts
    dev_n, run = validation
    m = pose_metrics_1d(run)
    ok = np.isfinite(m["rp"].values)
    assert np.all(m["rp"].values[ok] <= m["rp_bound"].values[ok] + 1e-9)
    x = dev_n[1, :, 4]
    l = np.abs(x - x.mean())
    sigma = l.std(ddof=1) * 1000
    parts = m["rp_intrinsic_term"].values[1, 4] + m["rp_extrinsic_term"].values[1, 4] + 3 * sigma
    assert m["rp_bound"].values[1, 4] == pytest.approx(parts)


def test_robustness_by_mode_hand_computed(validation):
    _, run = validation
    m = pose_metrics_1d(run)
    r = robustness_by_mode(m)
    assert set(r) == {"no_calibration", "adaptive_kmz", "single"}
    for k, name in enumerate(MODES_1D.split()):
        rows = [k, k + 3]
        aps = [m["ap"].values[i][np.isfinite(m["ap"].values[i])] / 1000 for i in rows]
        rs = np.mean([a.max() - a.min() for a in aps])
        dur = m["time_end_h"].values[rows[-1]] - m["time_start_h"].values[rows[0]]
        rt = np.mean([a.max() for a in aps]) / dur
        assert r[name]["space"] == pytest.approx(rs)
        assert r[name]["time"] == pytest.approx(rt)
        assert r[name]["duration_h"] == pytest.approx(dur) and r[name]["n_tests"] == 2
        assert r[name]["units"] == {"space": "um", "time": "um/h", "ap": "um", "duration": "h"}


def test_accuracy_vs_temperature_training_range(validation):
    _, run = validation
    m = pose_metrics_1d(run)
    out = accuracy_vs_temperature(m, (20.0, 20.25))
    # test t spans 20 + 0.1 t + [0.015, 0.018]: tests 0, 1 inside; 2.. outside
    assert out["no_calibration"]["in_training_range"] == [True, False]
    assert out["adaptive_kmz"]["in_training_range"] == [True, False]
    assert out["single"]["temperature_c"][0] == pytest.approx(20.2165)
    assert out["single"]["max_ap_nm"] == pytest.approx(m["ap_max"].values[[2, 5]].tolist())
    train = run_1d(np.zeros((1, 2, 13)), plan="training")
    assert temperature_range(train) == pytest.approx((20.015, 20.016))


def test_iso230_2_helper_matches_direct_call():
    rng = np.random.default_rng(5)
    pos = np.arange(0.0, 481.0, 30.0)
    sweep = np.concatenate([pos, pos[-2::-1]])
    dirs = np.r_[np.ones(pos.size, int), -np.ones(pos.size - 1, int)]
    dev = (
        0.2 * np.sin(sweep / 100)[None, None, :]
        + 0.01 * dirs
        + 0.03 * rng.standard_normal((1, 5, sweep.size))
    )
    run = run_1d(dev, plan="training", positions=sweep, dirs=dirs)
    out = iso230_2_of_run(run)
    used = pos[:-1]  # 480 is the turning point, forward only
    fwd = np.array([[used[i] + dev[0, c, i] for c in range(5)] for i in range(used.size)])
    bwd_idx = [pos.size + (pos.size - 2 - i) for i in range(used.size)]
    bwd = np.array([[used[i] + dev[0, c, bwd_idx[i]] for c in range(5)] for i in range(used.size)])
    assert np.allclose(sweep[bwd_idx], used)
    r = iso230_2(used, fwd, bwd)
    for k in ("E", "M", "B", "R", "A", "E_fwd", "R_bwd", "A_fwd"):
        assert out[f"{k}_nm"] == pytest.approx(getattr(r, k) * 1000)
    assert out["excluded_targets_um"] == [480.0] and out["cycles_forward"] == 5
    json.dumps(out, allow_nan=False)


def run_2d(dev_xy, modes):
    pts = np.array([[0, 0], [45, 45], [75, 15], [75, 75], [15, 75], [15, 15]], dtype=float)
    n_t, n_c, n_p, _ = dev_xy.shape
    shape = (n_t, n_c, n_p)
    test = np.broadcast_to(np.arange(n_t)[:, None, None], shape).ravel()
    cycle = np.broadcast_to(np.arange(n_c)[None, :, None], shape).ravel()
    pose = np.broadcast_to(np.arange(n_p)[None, None, :], shape).ravel()
    tgt = pts[pose]
    meas = tgt + dev_xy.reshape(-1, 2)
    n = pose.size
    return xr.Dataset(
        {
            "time": ("sample", 30.0 * np.arange(n)),
            "cmd_x": ("sample", tgt[:, 0]),
            "cmd_y": ("sample", tgt[:, 1]),
            "target_x": ("sample", tgt[:, 0]),
            "target_y": ("sample", tgt[:, 1]),
            "meas_x": ("sample", meas[:, 0]),
            "meas_y": ("sample", meas[:, 1]),
            "temperature": (("sample", "sensor"), np.full((n, 4), 21.0)),
            "pose": ("sample", pose),
            "cycle": ("sample", cycle),
            "direction": ("sample", np.zeros(n, int)),
            "test": ("sample", test),
            "test_mode": (
                "sample",
                np.asarray(modes)[test],
                {"flag_values": [0, 1], "flag_meanings": "no_calibration single"},
            ),
        },
        coords={"sensor": ["T1", "T2", "T3", "T4"]},
        attrs={"robot": "stage2d", "plan": "validation", "campaign": "t2"},
    )


def test_pose_metrics_2d_and_summary(tmp_path):
    rng = np.random.default_rng(9)
    dev = 0.01 * rng.standard_normal((4, 3, 6, 2))
    dev[0::2] += np.array([1.2, -0.5])  # no calibration: ≈ 1300 nm
    dev[1::2] += np.array([0.1, 0.1])
    run = run_2d(dev, [0, 1, 0, 1])
    m = pose_metrics_2d(run)
    pts = np.array([[0, 0], [45, 45], [75, 15], [75, 75], [15, 75], [15, 15]], dtype=float)
    for t in range(4):
        for p in range(6):
            att = pts[p] + dev[t, :, p]
            bary = att.mean(axis=0)
            assert m["ap"].values[t, p] == pytest.approx(1000 * np.hypot(*(bary - pts[p])))
            l = np.hypot(*(att - bary).T)
            assert m["rp"].values[t, p] == pytest.approx(1000 * (l.mean() + 3 * l.std(ddof=1)))
    ok = np.isfinite(m["rp"].values)
    assert np.all(m["rp"].values[ok] <= m["rp_bound"].values[ok] + 1e-9)
    s = stage2d_summary(
        {"name": "t2"}, m, {"single": {"a_1x": np.float64(1.0)}}, None, [], training_metrics=m.isel(test=[0])
    )
    json.dumps(s, allow_nan=False)
    # a campaign that declares no reference carries none, and no sentence compares it with the thesis
    assert s["reference"] == {} and s["robot"] == "stage2d"
    assert "thesis" not in s["ordering"]["statement"] and s["ordering"]["agrees"] is None
    assert s["tests"]["no_calibration"]["max_accuracy_nm"] == pytest.approx(float(m["ap_max"][[0, 2]].max()))
    assert s["tests"]["single"]["max_accuracy_nm"] < 200
    assert s["training"]["accuracy_nm"] == pytest.approx(float(m["ap_max"][0]))


def test_stage1d_summary_keys_by_day_and_json(validation, tmp_path):
    _, run = validation
    m = pose_metrics_1d(run)
    metro = pose_metrics_1d(run_1d(0.35 + 0.01 * np.sin(np.arange(65)).reshape(1, 5, 13), plan="metrology"))
    f = tmp_path / "validation.nc"
    f.write_bytes(b"calflow")
    pos = np.arange(0.0, 481.0, 30.0)
    sweep = np.concatenate([pos, pos[-2::-1]])
    dirs = np.r_[np.ones(17, int), -np.ones(16, int)]
    train = run_1d(
        0.01 * np.cos(np.arange(99)).reshape(1, 3, 33), plan="training", positions=sweep, dirs=dirs
    )
    from calflow.instruments.interferometer import interferometer_budget

    s = stage1d_summary(
        {"name": "t", "seed": 1, "robot": "stage1d", "reference": "thesis-sec5.3"},
        metro,
        m,
        {"single": {"a_1": np.float32(2.454e-8), "lam": np.nan}},
        interferometer_budget(),
        [str(f)],
        training_range_c=temperature_range(train),
        iso230_2=iso230_2_of_run(train),
    )
    text = json.dumps(s, allow_nan=False)
    assert json.loads(text) == s
    assert s["intrinsic"]["accuracy_nm"] == pytest.approx(float(np.nanmax(metro["ap"])))
    assert s["intrinsic"]["repeatability_nm"] == pytest.approx(float(np.nanmax(metro["rp"])))
    for name in ("no_calibration", "adaptive_kmz", "single"):
        t = s["tests"][name]
        rows = [i for i in range(6) if i % 3 == MODES_1D.split().index(name)]
        assert t["max_accuracy_nm"] == pytest.approx(float(m["ap_max"].values[rows].max()))
        assert t["max_repeatability_nm"] == pytest.approx(float(m["rp_max"].values[rows].max()))
        assert isinstance(t["max_accuracy_nm_by_day"], list)
        assert set(t["series"]) >= {"time_h", "max_ap_nm", "max_rp_nm", "temperature_c"}
        assert set(s["robustness"][name]) >= {"space", "time", "units"}
    # tests last 8.5 h (mean times 4.25, 12.92, 21.58, 30.25, 38.92, 47.58 h): days 0,0,0,1,1,1
    assert s["validation"]["days"] == 3
    assert s["tests"]["no_calibration"]["series"]["day"] == [0, 1]
    by_day = s["tests"]["no_calibration"]["max_accuracy_nm_by_day"]  # run ends at 51.8 h: days 0, 1, 2
    assert by_day[:2] == pytest.approx([float(m["ap_max"][0]), float(m["ap_max"][3])]) and by_day[2] is None
    assert s["tests"]["single"]["series"]["time_h"] == pytest.approx([21.583333, 47.583333])
    assert s["reference"] == STAGE1D  # the set it declares, with its source
    assert s["reference"]["source"].startswith("Tan,")
    assert s["models"]["single"]["lam"] is None and isinstance(s["models"]["single"]["a_1"], float)
    assert s["budget"]["combined_nm"] == pytest.approx(interferometer_budget().combined_nm)
    assert len(s["budget"]["rows"]) == 9
    assert s["inputs"] == {str(f): __import__("hashlib").sha256(b"calflow").hexdigest()}
    assert s["iso230_2"]["units"] == "nm" and s["robot"] == "stage1d"


def test_bad_runs_are_reported():
    run = run_1d(np.zeros((2, 2, 13)))
    with pytest.raises(DataError, match="target_x"):
        pose_metrics_1d(run.drop_vars("target_x"))
    mixed = run.copy()
    mixed["test_mode"] = ("sample", np.r_[np.zeros(27, int), np.ones(25, int)], run["test_mode"].attrs)
    with pytest.raises(DataError, match="mixes modes"):
        pose_metrics_1d(mixed)
    assert math.isnan(float(pose_metrics_1d(run.assign(meas_x=run["meas_x"] * np.nan))["ap_max"][0]))


def test_metrics_write_netcdf_with_kmz_and_decoded_time(tmp_path):
    run = run_1d(0.2 + np.zeros((3, 2, 13)))
    run = run.assign(
        kmz_time=("kmz_visit", [0.0, 3600.0]),
        kmz_command=("kmz_visit", [0.0, 0.0]),
        kmz_measured=("kmz_visit", [0.001, 0.004]),
    )
    m = pose_metrics_1d(run)
    np.testing.assert_allclose(m["kmz_offset"], [1.0, 4.0])
    np.testing.assert_allclose(m["kmz_time_h"], [0.0, 1.0])
    m.to_netcdf(tmp_path / "m.nc")
    back = xr.open_dataset(tmp_path / "m.nc")
    assert robustness_by_mode(back)["single"]["time"] == pytest.approx(
        robustness_by_mode(m)["single"]["time"]
    )
    run.to_netcdf(tmp_path / "r.nc")
    decoded = xr.open_dataset(tmp_path / "r.nc")  # CF-decoded datetime64 time
    np.testing.assert_allclose(pose_metrics_1d(decoded)["time_h"], m["time_h"])
