"""Plans of the hexapod campaign: reachable poses, held-out targets, ISO 9283 poses, the model
inverse against the simulated rig's truth, the designed plan against the random one."""

from __future__ import annotations

import json

import numpy as np
import pytest
from rig_noise import NOISE_OFF

from calflow.identification import design
from calflow.step import Job
from calflow_hexapod.models.calibration import command
from calflow_hexapod.models.geometry import AXES, h811
from calflow_hexapod.models.kinematics import inverse
from calflow_hexapod.plans import campaign as campaign_plans
from calflow_hexapod.plans import design as design_plan
from calflow_hexapod.plans import poses as plans
from calflow_hexapod.stage import tracker
from calflow_hexapod.stage.physics import HexapodTruth
from calflow_hexapod.stage.rig import attained, truth_parameters
from calflow_hexapod.stage.workspace import reachable


def campaign(**identification) -> dict:
    return {
        "name": "hexapod-test",
        "seed": 7,
        "rig": {"factory": "simulated", "options": {}},
        "identification": {
            "plan": "random",
            "poses": 40,
            "fraction": 0.7,
            "dwell_s": 1.0,
            "initial": {"tool": [0, 0, 60000, 0, 0, 0]},
            "design": {"criterion": "D", "model": "offsets", "candidates": 200},
            **identification,
        },
        "models": {"nominal": {}, "offsets": {}},
        "validation": {"dwell_s": 1.0, "heldout": {"targets": 8, "cycles": 3}},
        "iso9283": {"fraction": 0.5, "cycles": 30},
    }


def commands(plan) -> np.ndarray:
    return np.column_stack([plan.commands[a] for a in AXES])


def test_identification_poses_start_at_home_reachable_and_seeded():
    a, b = plans.identification(50, 0.8, seed=3), plans.identification(50, 0.8, seed=3)
    q = commands(a)
    assert len(a) == 51 and np.all(q[0] == 0) and reachable(q).all()
    np.testing.assert_array_equal(q, commands(b))
    assert not np.array_equal(q, commands(plans.identification(50, 0.8, seed=4)))
    assert np.all(np.abs(q) <= 0.8 * np.array([17000, 17000, 6500, 10, 10, 21]) + 1e-9)


def test_heldout_poses_are_not_identification_poses():
    c = campaign()
    ident = commands(plans.identification(40, 0.7, c["seed"]))
    rng = np.random.default_rng(np.random.SeedSequence([campaign_plans.heldout_seed(c), 9_283]))
    held = plans.workspace_poses(8, 0.7, rng)
    assert np.min(np.linalg.norm(held[:, None, :] - ident[None], axis=2)) > 1.0


def test_heldout_poses_leave_the_margin_free():
    from calflow_hexapod.plans.poses import MARGIN_UM, workspace_poses

    q = workspace_poses(50, 0.8, np.random.default_rng(1), margin_um=MARGIN_UM)
    assert reachable(q, margin_um=MARGIN_UM).all()
    assert not reachable(workspace_poses(200, 0.8, np.random.default_rng(1)), margin_um=MARGIN_UM).all()
    with pytest.raises(ValueError, match="iso9283.fraction"):
        plans.iso9283_commands(1.0)


def test_iso9283_poses():
    q = plans.iso9283_commands(0.4, (1.0, 0.0, 2.0))
    assert np.all(q[0, :3] == 0) and np.all(q[:, 3:] == [1.0, 0.0, 2.0])
    np.testing.assert_allclose(np.abs(q[1:, :3]), np.tile(0.8 * 0.4 * np.array([17000, 17000, 6500]), (4, 1)))
    assert reachable(q).all()


def test_model_inverse_of_the_truth_puts_the_probe_on_the_targets():
    """A rig with only the errors the models represent, no noise: commanding targets through the
    inverse of the rig's own parameters makes the tracker read the targets."""
    off = {
        "joint_play_um": 0.0,
        "payload_kg": 0.0,
        "tracker_systematic_um": 0.0,
        "encoder_resolution_um": 0.0,
        "expansion_ppm_per_degC": 0.0,
        **NOISE_OFF,
    }
    t = HexapodTruth(**off)
    targets = plans.heldout_targets(6, 0.6, design_plan.nominal_parameters(campaign()), seed=1)
    q = command(truth_parameters(t), h811(), targets)
    enc = inverse(h811(), q)
    pose = attained(t, t.geometry(), enc, np.ones((6, 6)), np.full(6, 20.0), q, np.zeros((6, 6)))
    r = tracker.read(t, pose, np.zeros((6, 6)))
    np.testing.assert_allclose(np.column_stack([r[f"meas_{a}"] for a in AXES]), targets, atol=1e-5)
    nominal = command(design_plan.nominal_parameters(campaign()), h811(), targets)
    assert np.abs(nominal - q)[:, :3].max() > 20.0  # the nominal model misses by the rig's errors


def test_validation_plan_cycles_and_targets():
    targets = np.arange(12.0).reshape(2, 6)
    p = plans.validation(lambda t: t * 2, targets, cycles=3, dwell_s=2.0)
    assert len(p) == 7 and list(p.pose) == [0, 1, 2, 1, 2, 1, 2] and list(p.cycle) == [0, 0, 0, 1, 1, 2, 2]
    assert np.isnan(p.targets["x"][0]) and p.targets["w"][2] == 11.0 and p.commands["w"][2] == 22.0


def test_bound_shrinks_with_more_poses():
    c = campaign()
    small = design_plan.bound(c, commands(plans.identification(30, 0.7, 1)))
    large = design_plan.bound(c, commands(plans.identification(120, 0.7, 1)))
    for name in ("nominal", "offsets"):
        s, big = small["crlb_sigma"][name], large["crlb_sigma"][name]
        assert set(s) == set(big) and all(big[k] < s[k] for k in s)
    assert large["rig_time_h"] > small["rig_time_h"] > 0


def test_designed_plan_carries_more_information_than_random(tmp_path):
    c = campaign(plan="optimal")
    acq = campaign_plans.identification(c, Job.of("acquire"))
    record = json.loads(acq.attrs["design"])
    q = commands(acq.plan)
    rq = commands(plans.identification(40, 0.7, c["seed"]))
    assert len(q) == len(rq) and reachable(q).all() and np.all(q[0] == 0)
    phi = design_plan.nominal_parameters(c)
    free = tuple(record["bounded_parameters"])
    d_opt, d_rand = (
        design.criterion(design.information(design_plan.jacobians(x, phi, free, record["noise"])))
        for x in (q, rq)
    )
    assert d_opt > d_rand
    assert set(record["crlb_sigma"]) == {"nominal", "offsets"}


def test_plans_without_a_model_say_so():
    with pytest.raises(Exception, match="--model"):
        campaign_plans.validation_heldout(campaign(), Job.of("acquire", model=None))


def test_noise_model_of_the_simulated_hexapod_behind_the_emulator():
    """A gcs rig whose sensor is the simulated tracker has the simulated rig's noise model (the
    identification's weights); another sensor declares none."""
    sim = campaign()
    sim["rig"]["options"] = {"tracker_distance_m": 3.0}
    gcs = campaign()
    gcs["rig"] = {
        "factory": "gcs",
        "options": {
            "sensor": {"factory": "simulated_tracker", "options": {"seed": 1, "tracker_distance_m": 3.0}}
        },
    }
    assert design_plan.noise_model(gcs) == design_plan.noise_model(sim)
    assert design_plan.noise_model(gcs)["position_um"] > design_plan.noise_model(campaign())["position_um"]
    gcs["rig"]["options"]["sensor"]["factory"] = "my_lab.sensors:tracker"
    assert design_plan.noise_model(gcs) is None


def test_too_large_an_iso_cube_is_one_line(tmp_path):
    from calflow.errors import CalflowError

    c = campaign()
    c["iso9283"] = {"fraction": 0.9, "cycles": 30}
    with pytest.raises(CalflowError, match=r"campaign hexapod-test: iso9283.fraction"):
        campaign_plans.iso9283(c, Job.of("acquire", model=["unused.nc"]))
