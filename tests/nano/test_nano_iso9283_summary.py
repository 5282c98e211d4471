"""The iso9283 block of the nano summaries on a small run computed by hand."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from test_evaluation_nano import DT_S, run_1d

from calflow.nano.evaluation import pose_metrics_1d
from calflow.nano.report.iso9283 import iso9283_block
from calflow.nano.report.summary import stage1d_summary

POSITIONS = np.array([0.0, 10.0, 20.0, 10.0])  # 0, 10, 20 forward, then 10 backward
DIRS = np.array([1, 1, 1, -1])
# deviations (µm), tests x cycles x poses; both tests of mode 0
DEV = np.array(
    [
        [[0.0, 0.1, 0.05, -0.1], [0.0, 0.3, 0.05, -0.1]],
        [[0.2, 0.2, 0.2, 0.2], [0.2, 0.2, 0.2, 0.2]],
    ]
)
KEYS = {"vAP", "AD", "RD", "dAP", "dRP", "stabilisation_time_s", "overshoot"}


@pytest.fixture
def block():
    run = run_1d(DEV, modes=[0, 0], positions=POSITIONS, dirs=DIRS)
    return iso9283_block(run)


def test_block_by_hand(block):
    b = block["modes"]["no_calibration"]
    assert set(b) == KEYS and list(block["modes"]) == ["no_calibration"] and block["axes"] == ["x"]
    # vAP at 10 µm, test 0: forward mean 0.2, backward mean -0.1 -> 0.3 µm; test 1: 0
    assert (
        b["vAP"]["value"] == pytest.approx(300.0)
        and b["vAP"]["target_um"] == [10.0]
        and b["vAP"]["test"] == 0
    )
    # AD, test 0: (0, 10) D = 10.1, 10.3 -> +0.2; (1, 2) D = 9.95, 9.75 -> -0.15; (2, 3) +0.15;
    # (0, 2) +0.05; (0, 3) -0.1; test 1 all 0 -> AD = +0.2 µm between 0 and 10 µm
    assert b["AD"]["value"] == pytest.approx(200.0)
    assert b["AD"]["pair_targets_um"] == [[0.0], [10.0]] and b["AD"]["command_distance_um"] == 10.0
    # RD: S_D = sqrt(2 x 0.1^2 / 1) for (0, 10) and (10, 20) -> 3 S_D
    assert b["RD"]["value"] == pytest.approx(3000.0 * math.sqrt(0.02))
    # drift, test 0 -> test 1: AP per pose 0, .2, .05, .1 -> .2 everywhere: dAP = .2 at 0 µm;
    # RP per pose in test 0: 0, 0.1, 0, 0 -> 0 in test 1: dRP = 0.1 at 10 µm
    assert b["dAP"]["value"] == pytest.approx(200.0) and b["dAP"]["target_um"] == [0.0]
    assert b["dRP"]["value"] == pytest.approx(100.0) and b["dRP"]["target_um"] == [10.0]
    assert (b["dAP"]["first_test"], b["dAP"]["last_test"]) == (0, 1)
    assert b["dAP"]["period_h"] == pytest.approx(8 * DT_S / 3600.0)  # 8 samples per test
    assert {b[k]["clause"] for k in KEYS} == {"7.3", "7.4.1", "7.4.2", "7.7", "7.5", "7.6"}
    assert all(b[k]["unit"] == "nm" for k in KEYS - {"stabilisation_time_s"})
    assert b["stabilisation_time_s"]["unit"] == "s"


def test_what_the_data_cannot_give_is_null_with_a_reason():
    one_way = run_1d(DEV[:1], modes=[0], positions=POSITIONS, dirs=np.ones(4, int))
    b = iso9283_block(one_way)["modes"]["no_calibration"]
    for key in ("vAP", "dAP", "dRP", "stabilisation_time_s", "overshoot"):
        assert b[key]["value"] is None and b[key]["reason"].startswith("not supported by this data"), key
    assert "two directions" in b["vAP"]["reason"] and "one test" in b["dAP"]["reason"]
    assert "step_response" in b["overshoot"]["reason"]
    assert b["AD"]["value"] is not None  # one test still has pairs of poses


def test_stage1d_summary_carries_the_block_as_json(block):
    run = run_1d(DEV, modes=[0, 0], positions=POSITIONS, dirs=DIRS)
    s = stage1d_summary({"name": "t", "seed": 1}, None, pose_metrics_1d(run), {}, validation_run=run)
    assert json.loads(json.dumps(s, allow_nan=False))["iso9283"] == json.loads(json.dumps(block))
    assert "iso9283" not in stage1d_summary({"name": "t", "seed": 1}, None, pose_metrics_1d(run), {})
