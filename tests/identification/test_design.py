"""Optimal design of the XYΘ identification poses (issue 15): information, bound, exchange,
order, frames per pose, and the ``identification.plan: optimal`` option."""

import argparse
import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import least_squares

from calflow.configuration.campaign import load as load_campaign
from calflow.identification.diagnostics import observability
from calflow.xytheta.design import criteria as design
from calflow.xytheta.design import plan as dp
from calflow.xytheta.models import cost
from calflow.xytheta.models.kinematics import PARAMETER_NAMES, Parameters, forward

NOMINAL = Parameters(10000.0, 8000.0, 180.0, 0.0)
TRUE = Parameters(9572.9, 7795.8, 177.689, -0.132)
BOX = ((0.0, 4000.0), (800.0, 2800.0), (0.0, 5.0))
ROOT = Path(__file__).resolve().parents[2]


def _pool(n=512, seed=3):
    return dp.candidates(n, *BOX, seed)


def _difference_gram(n: int) -> np.ndarray:
    """D Dᵀ of the interleaved pose-difference operator of Eq. (4.29), dense: for this small
    check only (identification itself never builds it)."""
    m = 2 * (n - 1)
    g = 2.0 * np.eye(m)
    idx = np.arange(m - 2)
    g[idx, idx + 2] = g[idx + 2, idx] = -1.0
    return g


def test_information_is_the_gls_information_of_the_pose_differences():
    # the nuisance-corrected information equals J_dᵀ (D Dᵀ)⁻¹ J_d of Eq. (4.29)–(4.30)
    q = _pool(40)
    J = design.pose_jacobians(q, NOMINAL)
    Jd = cost.jacobian(NOMINAL, q[:, 0], q[:, 1], q[:, 2])
    gls = Jd.T @ np.linalg.solve(_difference_gram(len(q)), Jd)
    assert np.allclose(design.information(J), gls, rtol=1e-8)


def test_observability_criteria_are_the_thesis_indices_of_the_weighted_jacobian():
    q = _pool(60)
    J = design.pose_jacobians(q, NOMINAL)
    centred = (J - J.mean(0)).reshape(-1, 4)
    M = design.information(J)
    o = observability(centred)
    for name in ("O1", "O2", "O3", "O4"):
        assert float(design.criterion(M, name)) == pytest.approx(o[name], rel=1e-8)


@settings(max_examples=8, deadline=None)
@given(n=st.integers(8, 60), seed=st.integers(0, 10_000))
def test_d_optimal_log_det_is_at_least_that_of_random_poses_of_the_same_count(n, seed):
    pool = _pool(512, seed % 7)
    J = design.pose_jacobians(pool, NOMINAL)
    d = design.optimal_design(J, n, "D")
    assert len(np.unique(d.index)) == n  # distinct poses
    random = np.random.default_rng(seed).choice(len(pool), n, replace=False)
    assert d.value >= float(design.criterion(design.information(J[random]), "D"))


@pytest.mark.parametrize("name", ["A", "O1", "O3"])
def test_other_criteria_improve_on_random_poses_by_their_own_measure(name):
    pool = _pool(512)
    J = design.pose_jacobians(pool, NOMINAL)
    random = np.random.default_rng(0).choice(len(pool), 30, replace=False)
    scale = design.crlb_sigma(J[random])
    d = design.optimal_design(J, 30, name, scale=scale)
    s2 = np.outer(scale, scale)
    assert d.value > float(design.criterion(design.information(J[random]) * s2, name))


def _mle(q, P_mx, P_my):
    """Independent maximum-likelihood fit with the initial reading as a nuisance parameter."""

    def fun(v):
        x, y = forward(q[:, 0], q[:, 1], q[:, 2], Parameters.from_array(v[:4]))
        return np.concatenate([x - v[4] - P_mx, y - v[5] - P_my])

    return least_squares(fun, np.r_[NOMINAL.as_array(), 0.0, 0.0], method="lm", x_scale="jac").x[:4]


@pytest.mark.parametrize("designed", [False, True])
def test_crlb_is_the_monte_carlo_sigma_on_an_exact_model_rig(designed):
    rng = np.random.default_rng(11)
    pool = _pool()
    if designed:
        poses = pool[design.optimal_design(design.pose_jacobians(pool, NOMINAL), 30, "D").index]
    else:
        poses = pool[rng.choice(len(pool), 30, replace=False)]
    q = np.vstack([np.zeros(3), poses])
    sigma = 0.5
    bound = design.crlb_sigma(design.pose_jacobians(q, TRUE), sigma)
    x, y = forward(q[:, 0], q[:, 1], q[:, 2], TRUE)
    est = []
    for _ in range(200):
        c = rng.normal(0.0, 100.0, 2)
        est.append(_mle(q, x - c[0] + rng.normal(0, sigma, len(q)), y - c[1] + rng.normal(0, sigma, len(q))))
    ratio = np.std(est, axis=0, ddof=1) / bound
    # 200 replications: the sample σ is within ±15 % of the truth (3 standard errors)
    assert np.all(np.abs(ratio - 1.0) < 0.15), ratio


def test_order_travels_less_than_the_random_order():
    rng = np.random.default_rng(2)
    q = _pool(300)[rng.choice(300, 200, replace=False)]
    tm = dp.TimeModel()
    tour = dp.order(q, tm)
    assert sorted(tour) == list(range(200))  # every pose once
    moving = tm.plan_s(q[tour]) - 200 * (tm.settle_s + tm.dwell_s)
    assert moving < 0.5 * (tm.plan_s(q) - 200 * (tm.settle_s + tm.dwell_s))


def test_time_model_is_the_simulated_rigs_clock():
    from calflow.acquisition.runner import acquire
    from calflow.commands.common import meta
    from calflow.xytheta.plans.poses import identification
    from calflow.xytheta.stage.rig import simulated_xytheta

    c = load_campaign(ROOT / "config/campaigns/xytheta-thesis.yaml")
    plan = identification(20, *BOX, seed=1)
    run = acquire(plan, simulated_xytheta(seed=1), meta(c, "simulated", "identification"))
    q = np.column_stack([plan.commands[k] for k in ("x", "y", "theta")])
    assert float(run["time"].values[-1]) == pytest.approx(dp.TimeModel().plan_s(q), rel=1e-9)


def test_frames_per_pose_average_only_where_the_frame_noise_dominates():
    assert dp.frames_per_pose(dp.NoiseModel(0.5, 0.05), 3.0, 0.04) == 1  # stage repeatability dominates
    k = dp.frames_per_pose(dp.NoiseModel(0.01, 0.5), 3.0, 0.04)
    assert 1 < k <= 10
    assert dp.frames_per_pose(dp.NoiseModel(0.01, 0.5), 3.0, 0.04, frames_max=3) == 3


def test_approach_rows_make_every_pose_approached_from_below():
    q = _pool(50)
    rows, measured = dp.approach(q, 20.0)
    prev = np.vstack([np.zeros(3), rows[:-1]])
    assert np.all(rows[measured, 0] >= prev[measured, 0]) and np.all(rows[measured, 1] >= prev[measured, 1])
    assert np.array_equal(rows[measured], q)


def test_optimal_plan_option_builds_a_plan_with_its_bound(tmp_path):
    from calflow.xytheta.plans.campaign import identification

    text = (
        (ROOT / "config/campaigns/xytheta-thesis.yaml")
        .read_text()
        .replace(
            "identification:\n",
            "identification:\n  plan: optimal\n  design: {poses: 60, candidates: 512}\n",
            1,
        )
    )
    (tmp_path / "xytheta-small.yaml").write_text(text)
    c = load_campaign(tmp_path / "xytheta-small.yaml")
    acq = identification(c, argparse.Namespace())
    plan, record = acq.plan, json.loads(acq.attrs["design"])
    assert len(plan) == 60 and plan.row(0) == {"x": 0.0, "y": 0.0, "theta": 0.0}
    q = np.column_stack([plan.commands[k] for k in ("x", "y", "theta")])
    assert np.all((q[1:, 0] >= 0) & (q[1:, 0] <= 4000) & (q[1:, 1] >= 800) & (q[1:, 1] <= 2800))
    assert record["plan"] == "optimal" and record["criterion"] == "D" and record["poses"] == 60
    assert set(record["crlb_sigma"]["II"]) == {"x_R_um", "y_R_um", "alpha_deg", "beta_deg"}
    assert record["rig_time_h"] == pytest.approx(dp.TimeModel().plan_s(q) / 3600)
    # the random plan carries the bound of its own poses
    rnd = identification(load_campaign(ROOT / "config/campaigns/xytheta-thesis.yaml"), argparse.Namespace())
    bound = json.loads(rnd.attrs["design"])["crlb_sigma"]["II"]
    assert record["crlb_sigma"]["II"]["alpha_deg"] > bound["alpha_deg"]  # 60 poses do not reach 1200


def test_optimal_plan_without_a_noise_model_is_refused(tmp_path):
    from calflow.errors import ConfigError

    text = (
        (ROOT / "config/campaigns/xytheta-thesis.yaml")
        .read_text()
        .replace("identification:\n", "identification:\n  plan: optimal\n  design: {model: IV}\n", 1)
    )
    (tmp_path / "xytheta-bad.yaml").write_text(text)
    with pytest.raises(ConfigError, match="identification.design.model"):
        load_campaign(tmp_path / "xytheta-bad.yaml")


def test_design_study_answers_poses_and_hours_where_the_curve_crosses_the_target():
    from calflow.xytheta.design.study import needed

    counts = np.array([10, 100, 1000])
    sigma = np.zeros((2, 3, 2))
    sigma[0, :, 0] = 1.0 / np.sqrt(counts)  # random: σ ∝ 1/√n
    sigma[1, :, 0] = 0.5 / np.sqrt(counts)  # designed: half of it
    sigma[:, :, 1] = 1e-9  # the other parameter is not targeted
    hours = np.vstack([counts * 3.0, counts * 1.5]) / 3600.0
    out = needed(counts, sigma, hours, ["x_R_um", "alpha_deg"], {"x_R_um": 0.05, "y_R_um": 1.0})
    assert out["random"]["poses"] == pytest.approx(400, abs=1)  # 1/√n = 0.05
    assert out["designed"]["poses"] == pytest.approx(100, abs=1)
    assert out["random"]["rig_time_h"] == pytest.approx(400 * 3.0 / 3600, rel=1e-6)
    beyond = needed(counts, sigma, hours, ["x_R_um", "alpha_deg"], {"x_R_um": 0.01})  # past the largest count
    assert beyond["random"]["poses"] == pytest.approx(10_000, rel=1e-6)


def test_design_study_command_writes_curves_the_summary_and_report_read(tmp_path):
    from calflow.data.io import open_dataset
    from calflow.xytheta.design.study import figure, study, summary_block

    text = (
        (ROOT / "config/campaigns/xytheta-thesis.yaml")
        .read_text()
        .replace("identification:\n", "identification:\n  design: {candidates: 256}\n", 1)
    )
    text += "design_study: {min_poses: 10, max_poses: 100, steps: 3, sigma_target: {x_R_um: 1.0}}\n"
    (tmp_path / "xytheta-study.yaml").write_text(text)
    out = tmp_path / "design_study.nc"
    study(argparse.Namespace(campaign=str(tmp_path / "xytheta-study.yaml"), out=str(out)))
    block = summary_block(open_dataset(out, kind="metrics"))
    assert block["poses"] == [10, 32, 100]
    s_r, s_d = np.array(block["sigma"]["random"]), np.array(block["sigma"]["designed"])
    assert np.all(np.diff(s_r, axis=0) < 0)  # more poses, smaller σ
    assert np.all(s_d[-1] < s_r[-1])  # the design beats random poses of its count
    assert block["needed"]["designed"]["poses"] <= block["needed"]["random"]["poses"]
    assert "designed:" in figure({"design_study": block}).caption


def test_parameter_keys_are_the_summarys():
    from calflow.xytheta.report.summary import parameter_key

    assert [design.parameter_key(k) for k in PARAMETER_NAMES] == [parameter_key(k) for k in PARAMETER_NAMES]
