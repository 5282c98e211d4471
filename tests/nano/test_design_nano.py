"""Designed nano training plans (issue 15): the bound, the design, the plan, the summary block."""

import copy
import json
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from hypothesis import given, settings
from hypothesis import strategies as st

from calflow.configuration.campaign import load as load_campaign
from calflow.identification.design import criterion, information
from calflow.nano.models.thermal import SingleModel
from calflow.nano.plans import campaign as campaign_plans
from calflow.nano.plans import design
from calflow.nano.plans import designed as design_plan
from calflow.nano.plans import sequences as plans

ROOT = Path(__file__).resolve().parents[2]
STROKE = np.array([480.0])


def _campaign(robot="nano1d", **training):
    c = copy.deepcopy(load_campaign(ROOT / "config" / "campaigns" / f"{robot}-thesis.yaml"))  # a variant
    c["training"].update(training)
    return c


def _rows(positions):
    return plans.sweep_1d("t", np.sort(positions), 1, 0.0).commands["x"][:, None]


@settings(max_examples=8, deadline=None)
@given(n=st.integers(5, 12), order=st.integers(2, 3), seed=st.integers(0, 2**16))
def test_bound_is_the_monte_carlo_sigma_under_white_noise(n, order, seed):
    # least squares with an offset on a plan's readings, white noise σ: the empirical σ of
    # every coefficient over many draws matches the Cramér–Rao σ of the design
    rng = np.random.default_rng(seed)
    positions = np.sort(rng.choice(np.arange(0.0, 481.0, 5.0), n, replace=False))
    rows, cycles, sigma = _rows(positions), 3, 0.012
    x = np.tile(rows[:, 0], cycles)
    X = np.column_stack([np.ones_like(x)] + [(x / 480.0) ** i for i in range(1, order + 1)])
    draws = 2000
    Y = X @ rng.normal(size=order + 1)[:, None] + sigma * rng.standard_normal((x.size, draws))
    coef = np.linalg.lstsq(X, Y, rcond=None)[0][1:] / (480.0 ** np.arange(1, order + 1))[:, None]
    bound = design.coefficient_sigma(rows, cycles, sigma, order, STROKE)
    assert np.allclose(coef.std(axis=1, ddof=1) / bound, 1.0, atol=0.1)


def test_bound_matches_the_single_models_standard_error_on_white_noise():
    # the model's own fit (Eq. 5.5, every term in) on one noisy training set reports the σ the bound promised
    rng = np.random.default_rng(4)
    rows, cycles, sigma = _rows(np.arange(0.0, 481.0, 30.0)), 40, 0.012
    x = np.tile(rows[:, 0], cycles)
    t = 20.5 + 0.1 * rng.standard_normal((x.size, 1))  # temperature uncorrelated with the positions
    q = 2.0 + 1.005 * x - 2e-5 * x**2 + 2e-8 * x**3 + 0.5 * t[:, 0] + sigma * rng.standard_normal(x.size)
    m = SingleModel.fit(q, x, t, order=3, select="all")
    bound = design.coefficient_sigma(rows, cycles, sigma, 3, STROKE)
    se = np.array([m.coefficients.set_index("name").loc[f"a_{i}", "std_error"] for i in (1, 2, 3)])
    assert np.allclose(se / bound, 1.0, atol=0.1)


@settings(max_examples=10, deadline=None)
@given(n=st.integers(5, 25), order=st.integers(2, 4))
def test_the_design_carries_at_least_the_grids_information_at_equal_count(n, order):
    _check_d_against_grid(n, order, 0.0)


@pytest.mark.parametrize("order", [2, 3, 4])
def test_with_its_space_filling_guard_the_default_design_still_beats_the_grid(order):
    _check_d_against_grid(17, order, 0.5)  # the thesis grid's 17 positions, half of them space-filling


def _check_d_against_grid(n, order, f):
    pool = design.candidates([0.0], [480.0], 1.0)
    chosen = pool[design.design_positions(pool, n, order, STROKE, "D", f)]
    grid = np.linspace(0.0, 480.0, n)[:, None]
    value = float(criterion(information(design.basis(chosen, order, STROKE)), "D"))
    assert value >= float(criterion(information(design.basis(grid, order, STROKE)), "D")) - 1e-9
    assert len(np.unique(chosen)) == n


@settings(max_examples=10, deadline=None)
@given(target_nm=st.floats(0.2, 5.0), n=st.integers(5, 17))
def test_cycles_are_the_fewest_that_reach_the_target(target_nm, n):
    rows = _rows(np.linspace(0.0, 480.0, n))
    k = design.cycles_for(target_nm * 1e-3, rows, 0.012, 3, [0.0], [480.0])
    assert design.shape_sigma_um(rows, k, 0.012, 3, [0.0], [480.0]) <= target_nm * 1e-3 * (1 + 1e-9)
    if k > 1:
        assert design.shape_sigma_um(rows, k - 1, 0.012, 3, [0.0], [480.0]) > target_nm * 1e-3


def test_the_default_plan_is_still_the_thesis_grid():
    c = _campaign()
    assert c["training"]["plan"] == "grid"
    a = campaign_plans.training_1d(c, None)
    t = c["training"]
    ref = plans.training_1d(np.arange(0.0, 481.0, 30.0), t["cycles"], t["dwell_s"], t["average_last_s"])
    assert np.array_equal(a.plan.commands["x"], ref.commands["x"]) and a.plan.start_s == 0.0
    record = json.loads(a.attrs["design"])
    assert record["plan"] == "grid" and record["cycles"] == t["cycles"] and record["crlb_shape_sigma_nm"] > 0


def test_designed_1d_plan_stays_in_the_stroke_and_keeps_both_approach_directions():
    c = _campaign(plan="optimal")
    a = campaign_plans.training_1d(c, None)
    record, plan = json.loads(a.attrs["design"]), a.plan
    x = plan.commands["x"]
    assert x.min() >= 0.0 and x.max() <= 480.0
    assert record["cycles"] >= 2 and len(plan) == record["readings"]
    assert record["crlb_shape_sigma_nm"] <= record["grid"]["crlb_shape_sigma_nm"] * (
        1 + 1e-9
    )  # sized to match it
    one = plan.cycle == 0
    fwd, back = x[one & (plan.direction == 1)], x[one & (plan.direction == -1)]
    assert np.all(np.diff(fwd) > 0) and np.all(np.diff(back) < 0)  # forward up, backward down
    assert set(back) == set(fwd) - {fwd.max()}  # every position but the turning point from both sides
    end = plan.start_s + len(plan) * design_plan.reading_s(c)
    assert end == pytest.approx(c["validation"]["start_h"] * 3600.0)  # training ends when validation starts


def test_designed_2d_plan_is_a_raster_inside_the_square():
    c = _campaign(
        "nano2d",
        plan="optimal",
        design={**_campaign("nano2d")["training"]["design"], "candidate_step_um": 4.0},
    )
    a = campaign_plans.training_2d(c, None)
    plan, record = a.plan, json.loads(a.attrs["design"])
    xy = np.column_stack([plan.commands["x"], plan.commands["y"]])
    assert xy.min() >= 0.0 and xy.max() <= 80.0
    one = xy[plan.cycle == 0]
    assert len(np.unique(one, axis=0)) == record["positions"] == 81
    assert np.all(np.diff(one[:, 0]) >= 0)  # columns of increasing x
    assert set(record["crlb_sigma"]) == {f"{p}_{i}{a}" for p in "ab" for i in (1, 2, 3) for a in "xy"}


def test_the_2d_grid_sweeps_from_start_um_like_the_bound_it_is_sized_with():
    # the grid plan and the design's bound (design_plan._stroke) read the same stroke
    c = _campaign("nano2d", start_um=20.0, stop_um=60.0, step_um=10.0, cycles=2)
    plan = campaign_plans.training_2d(c, None).plan
    xy = np.column_stack([plan.commands["x"], plan.commands["y"]])
    assert xy.min() == 20.0 and xy.max() == 60.0
    assert len(np.unique(xy[plan.cycle == 0], axis=0)) == 25  # 5 × 5 positions


def test_a_rig_without_a_noise_model_needs_one_or_cycles():
    c = _campaign(plan="optimal")
    c["rig"] = {"factory": "replay", "options": {}}
    with pytest.raises(ValueError, match="training.design.noise_nm"):
        design_plan.designed_plan(c)
    c["training"]["design"] = {**c["training"]["design"], "noise_nm": {"pose": 12.0, "sample": 3.0}}
    assert design_plan.designed_plan(c)[1] >= 2


def test_summary_block_sets_the_achieved_sigma_beside_the_bound():
    c = _campaign()
    a = campaign_plans.training_1d(c, None)
    rng = np.random.default_rng(1)
    x = a.plan.commands["x"][:400]
    t = 20.5 + 0.05 * rng.standard_normal((x.size, 4))
    meas = x + 0.012 * rng.standard_normal(x.size)
    run = xr.Dataset(
        {
            "meas_x": ("sample", meas),
            "cmd_x": ("sample", x),
            "temperature": (("sample", "sensor"), t),
            "time": ("sample", np.arange(x.size) * 29.0),
        },
        attrs={"design": a.attrs["design"]},
    )
    m = SingleModel.fit(x, meas, t, order=3, select="all")
    block = design_plan.training_design_block(c, run, {"single": m.coefficients.to_dict(orient="records")})
    assert set(block["crlb_sigma_recorded"]) == {"a_1", "a_2", "a_3", "b_1", "b_2", "b_3", "b_4"}
    assert all(0.5 < block["sigma_ratio_achieved_to_recorded_bound"][k] < 2.0 for k in ("a_1", "a_2", "a_3"))
    assert "not white" in block["statement"] and block["rig_time_h_achieved"] == pytest.approx(
        399 * 29.0 / 3600.0
    )
    assert design_plan.training_design_block(c, run.drop_attrs(), {}) is None


def test_design_study_answers_how_many_positions_and_how_long():
    c = _campaign()
    study = design_plan.design_study(c, counts=(4, 8, 17))
    assert study["positions"] == [4, 8, 17]
    # hours for the target follow σ ∝ 1/√hours; the grid's own count needs the grid's own time
    h = np.array(study["grid_sigma_nm_1h"]) ** 2 / study["target_nm"] ** 2
    assert np.allclose(study["grid_hours"], h)
    assert study["grid_hours"][2] == pytest.approx(
        len(_rows(np.arange(0.0, 481.0, 30.0))) * 67 * 29.0 / 3600.0
    )
    assert study["designed_hours"][2] < study["grid_hours"][2]


def test_noise_model_is_the_rigs_declared_one_and_averaging_reduces_only_the_sensor_part():
    c = _campaign()
    c["rig"]["options"] = {**c["rig"]["options"], "repeatability_nm": 20.0, "interferometer_noise_nm": 4.0}
    noise = design_plan.noise_model(c)
    assert noise["pose"] == 20.0 and noise["sample"] == pytest.approx(np.hypot(4.0, 0.3 / np.sqrt(12)))
    one, fifty = (design_plan.reading_sigma_um(noise, s) for s in (0.1, 5.0))
    assert one == pytest.approx(np.hypot(20.0, noise["sample"]) * 1e-3)
    assert fifty == pytest.approx(np.sqrt(20.0**2 + noise["sample"] ** 2 / 50) * 1e-3)


def test_2d_summary_block_bounds_each_equations_kept_terms():
    from calflow.nano.models.thermal import TwoDoFModel

    c = _campaign("nano2d")
    a = campaign_plans.training_2d(c, None)
    rng = np.random.default_rng(2)
    xy = np.column_stack([a.plan.commands["x"], a.plan.commands["y"]])[:300]
    t = 20.5 + 0.05 * rng.standard_normal((len(xy), 2))
    meas = xy + 0.012 * rng.standard_normal(xy.shape)
    run = xr.Dataset(
        {
            "meas_x": ("sample", meas[:, 0]),
            "meas_y": ("sample", meas[:, 1]),
            "temperature": (("sample", "sensor"), t),
            "time": ("sample", np.arange(len(xy)) * 14.0),
        },
        attrs={"design": a.attrs["design"]},
    )
    m = TwoDoFModel.fit(xy, meas, t, order=(3, 3), select="all")
    block = design_plan.training_design_block(c, run, {"two_dof": m.coefficients.to_dict(orient="records")})
    names = {
        f"{p}_{i}{ax}" for ax in "xy" for p, n in (("a", 3), ("b", 3), ("c", 2)) for i in range(1, n + 1)
    }
    assert set(block["crlb_sigma_recorded"]) == names
    # every term kept: the regression's standard error is its bound scaled by rmse / σ of the noise model
    ratios = np.array([block["sigma_ratio_achieved_to_recorded_bound"][k] for k in sorted(names)])
    assert np.all((ratios > 0.8) & (ratios < 1.25))


def test_a_designed_plans_summary_carries_the_design_study_for_its_target():
    c = _campaign(plan="optimal", design={**_campaign()["training"]["design"], "sigma_target_nm": 3.0})
    a = campaign_plans.training_1d(c, None)
    assert json.loads(a.attrs["design"])["crlb_shape_sigma_nm"] <= 3.0
    x = a.plan.commands["x"]
    run = xr.Dataset(
        {"meas_x": ("sample", x), "time": ("sample", np.arange(x.size) * 29.0)},
        attrs={"design": a.attrs["design"]},
    )
    block = design_plan.training_design_block(c, run, {})
    assert block["study"]["target_nm"] == 3.0 and len(block["study"]["designed_hours"]) == 7
