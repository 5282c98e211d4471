"""Design for a model that is not exact (issue 15, criterion ``discrepancy``): the expected
integrated squared prediction error under a Gaussian-process discrepancy, its exchange, the
kernel from the XY tables and the ``identification.design.criterion: discrepancy`` option."""

import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from calflow.configuration.campaign import load as load_campaign
from calflow.identification import discrepancy as dc
from calflow.xytheta.design import discrepancy as dd
from calflow.xytheta.design import plan as dp
from calflow.xytheta.tables.position import PositionLUT

ROOT = Path(__file__).resolve().parents[2]


def _line(x: np.ndarray) -> np.ndarray:
    """Jacobians (n, 2, 2) of a toy model: each axis a slope on joint x (y = φ x + c)."""
    J = np.zeros((len(x), 2, 2))
    J[:, 0, 0] = J[:, 1, 1] = x
    return J


def _poses(x: np.ndarray) -> np.ndarray:
    return np.column_stack([x, np.zeros_like(x)])


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10_000), st.floats(0.1, 10.0), st.integers(6, 30))
def test_bias_is_zero_for_a_discrepancy_the_model_spans(seed, s, n):
    # δ(q) = q_x (u, v), u, v ~ N(0, s²): a slope per axis, which the model fits exactly
    rng = np.random.default_rng(seed)
    x, xt = rng.random(n), rng.random(40)
    kernel = lambda a, b: s**2 * np.outer(a[:, 0], b[:, 0])  # noqa: E731
    out = dc.expected_error(_line(x), _poses(x), _line(xt), _poses(xt), kernel, np.zeros(2), 0.3)
    assert abs(out["bias"]) <= 1e-9 * s**2
    assert out["variance"] > 0
    # a discrepancy the model does not span (a bend) leaves a bias
    bend = lambda a, b: s**2 * np.outer(a[:, 0] ** 2, b[:, 0] ** 2)  # noqa: E731
    assert dc.expected_error(_line(x), _poses(x), _line(xt), _poses(xt), bend, np.zeros(2), 0.3)["bias"] > 0


def test_expected_error_is_the_monte_carlo_mean_squared_prediction_error():
    rng = np.random.default_rng(7)
    x, xt = rng.random(15), rng.random(25)
    kern = dc.Discrepancy((1.5, 0.0), (0.2, 1.0))
    sigma, home = 0.4, np.array([0.3, 0.0])
    out = dc.expected_error(_line(x), _poses(x), _line(xt), _poses(xt), kern, home, sigma)
    pts = np.vstack([_poses(x), _poses(xt), home])
    L = np.linalg.cholesky(kern(pts, pts) + 1e-10 * np.eye(len(pts)))
    Jh = dc.augmented(_line(x)).reshape(-1, 4)
    err = []
    for _ in range(4000):
        d = (L @ rng.standard_normal((len(pts), 2))).T  # (2 axes, poses)
        d = d - d[:, -1:]  # the frame is anchored at home
        y = d[:, :15].T.reshape(-1) + sigma * rng.standard_normal(30)
        phi = np.linalg.lstsq(Jh, y, rcond=None)[0]
        pred = _line(xt) @ phi[:2]
        err.append(np.mean(np.sum((d[:, 15:40].T - pred) ** 2, axis=1)))
    mc, se = np.mean(err), np.std(err) / np.sqrt(len(err))
    assert abs(mc - out["imse"]) < 4 * se


def test_exchange_spreads_the_design_as_the_discrepancy_grows():
    # the line's D- (and I-) optimal design sits at both ends; a short-range discrepancy of
    # growing amplitude moves poses inside, and its IMSE falls below the ends-only design's
    pool = np.linspace(0.0, 1.0, 101)
    ends = np.r_[np.arange(6), np.arange(95, 101)]
    xt = np.linspace(0.0, 1.0, 64)
    inside = []
    for s in (0.0, 0.05, 0.5):
        kern = dc.Discrepancy((s, 0.0), (0.05, 1.0))
        idx = dc.exchange(_line(pool), _poses(pool), ends, _line(xt), _poses(xt), kern, np.zeros(2), 0.1)
        inside.append(int(np.sum((pool[idx] > 0.1) & (pool[idx] < 0.9))))
        before = dc.expected_error(
            _line(pool[ends]), _poses(pool[ends]), _line(xt), _poses(xt), kern, np.zeros(2), 0.1
        )
        after = dc.expected_error(
            _line(pool[idx]), _poses(pool[idx]), _line(xt), _poses(xt), kern, np.zeros(2), 0.1
        )
        assert after["imse"] <= before["imse"] + 1e-12
        assert len(idx) == len(ends)
    assert inside[0] == 0 and inside[2] > inside[0], inside
    assert inside[2] >= inside[1], inside


@settings(max_examples=10, deadline=None)
@given(st.integers(0, 10_000))
def test_exchange_keeps_every_sigma_within_its_bound(seed):
    rng = np.random.default_rng(seed)
    pool = rng.random(80)
    start = np.argsort(np.abs(pool - 0.5))[-20:]  # the 20 poses farthest from the middle
    J = _line(pool)
    Jh = dc.augmented(J[start])
    bound = 0.1 * np.sqrt(np.diag(np.linalg.inv(np.einsum("iap,iaq->pq", Jh, Jh)))[:2]) * 1.02
    kern = dc.Discrepancy((1.0, 0.0), (0.03, 1.0))
    idx = dc.exchange(
        J,
        _poses(pool),
        start,
        _line(pool[:30]),
        _poses(pool[:30]),
        kern,
        np.zeros(2),
        0.1,
        sigma_max=bound,
        keep=start[:3],
    )
    Jh = dc.augmented(J[idx])
    assert np.all(
        0.1 * np.sqrt(np.diag(np.linalg.inv(np.einsum("iap,iaq->pq", Jh, Jh)))[:2]) <= bound * (1 + 1e-9)
    )
    assert set(start[:3]) <= set(idx)


@pytest.mark.parametrize("amp_x, amp_y, pitch", [(4.0, 3.0, 400.0), (1.0, 6.0, 250.0)])
def test_kernel_from_tables_recovers_a_lead_screw_errors_moments(amp_x, amp_y, pitch):
    X, Y = np.arange(0.0, 9450.0, 5.0), np.arange(0.0, 3780.0, 5.0)
    rng = np.random.default_rng(1)
    xx = np.column_stack(
        [amp_x * np.sin(2 * np.pi * X / pitch) + 20e-6 * X + 0.02 * rng.standard_normal(len(X))] * 2
    )
    yy = np.column_stack([amp_y * np.sin(2 * np.pi * Y / pitch + 1.0)] * 2)
    lut = PositionLUT(X, Y, xx, np.zeros((len(X), 2)), np.zeros((len(Y), 2)), yy)
    k = dd.kernel_from_tables(lut)
    # a sinusoid of amplitude a has variance a²/2, on one of the two reading axes: s² = a²/4
    assert k.amplitude[:2] == pytest.approx((amp_x / 2, amp_y / 2), rel=0.03)
    assert k.length[:2] == pytest.approx((pitch / (2 * np.pi),) * 2, rel=0.05)
    assert k.amplitude[2] == 0.0


def _campaign(tmp_path, design: str, random_poses: int = 150):
    text = (
        (ROOT / "config/campaigns/xytheta-thesis.yaml")
        .read_text()
        .replace("identification:\n", f"identification:\n  plan: optimal\n  design: {design}\n", 1)
        .replace("poses: 1200", f"poses: {random_poses}")
    )
    (tmp_path / "xytheta-small.yaml").write_text(text)
    return load_campaign(tmp_path / "xytheta-small.yaml")


def test_discrepancy_criterion_keeps_the_mv_designs_pose_count_and_bound_and_lowers_the_bias(tmp_path):
    kern = "{amplitude_um: [2.0, 1.5, 0.0], length: [64.0, 64.0, 1.0]}"
    c = _campaign(tmp_path, f"{{criterion: discrepancy, candidates: 512, poses: 90, discrepancy: {kern}}}")
    q, frames, record = dp.designed_poses(c)
    qd, _, rd = dp.designed_poses(_campaign(tmp_path, "{criterion: MV, candidates: 512, poses: 90}"))
    assert len(q) == len(qd)
    assert record["sigma_ratio_max_vs_random"] <= max(1.0, rd["sigma_ratio_max_vs_random"]) * (1 + 1e-9)
    d = record["discrepancy"]
    assert d["bias_um2"] <= d["bias_um2_before"]
    assert d["swapped_poses"] > 0 and np.all(q[0] == 0.0)


def test_discrepancy_criterion_without_a_kernel_is_refused(tmp_path):
    c = _campaign(tmp_path, "{criterion: discrepancy, candidates: 256}")
    with pytest.raises(ValueError, match="identification.design.discrepancy"):
        dp.designed_poses(c)


def test_the_plan_takes_its_kernel_from_the_xy_tables_when_the_config_gives_none(tmp_path):
    import argparse

    from calflow.data.io import write_dataset
    from calflow.data.runs import RunMetadata
    from calflow.xytheta.plans.campaign import identification

    X, Y = np.arange(0.0, 9450.0, 5.0), np.arange(0.0, 3780.0, 5.0)
    xx = np.column_stack([4.0 * np.sin(2 * np.pi * X / 400.0)] * 2)
    yy = np.column_stack([3.0 * np.sin(2 * np.pi * Y / 400.0)] * 2)
    meta = RunMetadata(
        campaign="t", robot="xytheta", source="simulated", plan="characterisation_x", config_sha256="0" * 64
    )
    write_dataset(
        PositionLUT(X, Y, xx, np.zeros((len(X), 2)), np.zeros((len(Y), 2)), yy).to_dataset(meta),
        tmp_path / "position.nc",
    )
    c = _campaign(tmp_path, "{criterion: discrepancy, candidates: 256, poses: 30}")
    acq = identification(c, argparse.Namespace(luts=str(tmp_path / "position.nc")))
    record = json.loads(acq.attrs["design"])["discrepancy"]
    assert record["from"] == "tables"
    assert record["amplitude_um"][:2] == pytest.approx([2.0, 1.5], rel=0.03)
    assert (
        c["identification"]["design"]["discrepancy"].get("amplitude_um") is None
    )  # the campaign is not changed


@settings(max_examples=8, deadline=None)
@given(st.integers(0, 10_000))
def test_mv_is_the_worst_parameters_variance_and_its_design_beats_d_by_it(seed):
    from calflow.identification import design as gd

    rng = np.random.default_rng(seed)
    A = rng.standard_normal((6, 8, 3))
    M = np.einsum("nij,nik->njk", A, A)
    assert gd.criterion(M, "MV") == pytest.approx([-np.max(np.diag(np.linalg.inv(m))) for m in M])
    J = rng.standard_normal((60, 2, 3)) * [1.0, 5.0, 0.2]
    worst = [np.max(gd.crlb_sigma(J[gd.optimal_design(J, 10, name).index])) for name in ("D", "MV")]
    assert worst[1] <= worst[0] * (1 + 1e-9)


@pytest.mark.parametrize("criterion", ["D", "discrepancy"])
def test_time_budget_takes_the_most_poses_within_it(tmp_path, criterion):
    # the polished design's tour (other poses) is timed too: the budget holds for the final plan
    kern = "discrepancy: {amplitude_um: [2.0, 1.5, 0.0], length: [64.0, 64.0, 1.0]}"
    c = _campaign(tmp_path, f"{{criterion: {criterion}, candidates: 256, {kern}}}", 80)
    q0, _, r0 = dp.designed_poses(c)
    c = _campaign(tmp_path, f"{{criterion: {criterion}, candidates: 256, time_budget: 0.5, {kern}}}", 80)
    q, frames, r = dp.designed_poses(c)
    tm = dp.time_model(c)
    budget = 0.5 * tm.plan_s(dp._random_poses(c, 80))
    assert len(q) > len(q0) and tm.plan_s(q, frames) <= budget
    assert (
        r["sigma_ratio_max_vs_random"] <= max(1.0, r0["sigma_ratio_max_vs_random"]) + 1e-9
    )  # the bound holds
    per = tm.plan_s(q, frames) / len(q)
    assert tm.plan_s(q, frames) + 3 * per > budget  # no room left for a few more poses
