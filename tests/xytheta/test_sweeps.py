"""Plans of the XY error study (Sec. 4.4) and the angle-residual run (Fig. 4.26)."""

import numpy as np
import pytest

from calflow.acquisition.runner import acquire
from calflow.data.conventions import PLANS
from calflow.data.runs import RunMetadata
from calflow.data.validate import validate_dataset
from calflow.xytheta.models.kinematics import Parameters, inverse
from calflow.xytheta.plans import sweeps
from calflow.xytheta.stage.rig import simulated_xytheta
from calflow.xytheta.tables.position import infer_directions


def test_characterisation_rows_passes_and_approach_directions():
    p = sweeps.characterisation("x", stop_um=100, step_um=5, cycles=3)
    n = 21
    assert len(p) == 1 + 3 * (2 * n + 2)
    assert p.name == "characterisation_x" and p.name in PLANS
    assert p.pose[0] == 0 and p.direction[0] == 0 and p.commands["x"][0] == 0
    assert np.all(p.commands["y"] == 0) and np.all(p.commands["theta"] == 0)
    x, d = p.commands["x"], p.direction
    for c in range(3):
        sel = p.cycle == c
        fwd, bwd = x[sel & (d == 1)], x[sel & (d == -1)]
        assert np.array_equal(fwd, np.arange(0, 101, 5.0)) and np.array_equal(bwd, fwd[::-1])
    # every measured row was reached by a move in its own direction (turning points too)
    moved = np.sign(np.diff(x))
    assert np.array_equal(moved[d[1:] != 0], d[1:][d[1:] != 0])
    # same pose for the same position in both directions
    assert np.array_equal(p.pose[(d == 1) & (p.cycle == 0)], p.pose[(d == -1) & (p.cycle == 0)][::-1])


def test_characterisation_defaults_and_errors():
    assert sweeps.characterisation("x", cycles=1).commands["x"].max() == 9500 + 10
    py = sweeps.characterisation("y", cycles=1)
    assert py.commands["y"].max() == 4200 + 10 and np.all(py.commands["x"] == 0)
    assert int((py.direction == 1).sum()) == 4200 // 5 + 1  # 5 µm steps, thesis: 5043 / 3 cycles / 2 ≈ 841
    for bad in (dict(axis="z"), dict(step_um=0), dict(cycles=0), dict(stop_um=-5), dict(overtravel_um=0)):
        with pytest.raises(ValueError):
            sweeps.characterisation(**{"axis": "x", **bad})


def test_square_targets_corners_and_compensation_callable():
    t = sweeps.square_targets(4000, 10, 4)
    assert t.shape == (16, 2)
    assert np.allclose(t[[0, 4, 8, 12]], [[10, 10], [4010, 10], [4010, 4010], [10, 4010]])
    p = sweeps.square(points_per_segment=4, cycles=2)
    assert p.name == "square" and len(p) == 1 + 32
    assert np.array_equal(p.commands["x"][1:], p.targets["x"][1:])  # identity without compensation
    assert np.isnan(p.targets["x"][0]) and p.commands["x"][0] == 0
    assert np.array_equal(p.pose[1:], np.tile(np.arange(1, 17), 2))
    seen = {}

    def comp(x, y, dx, dy):
        seen["dx"], seen["dy"] = dx, dy
        return x + 2.0 * dx, y - 1.0

    q = sweeps.square(points_per_segment=4, cycles=2, compensate=comp, directions="target")
    assert np.allclose(q.commands["x"][1:] - q.targets["x"][1:], 2.0 * seen["dx"])
    assert np.allclose(q.commands["y"][1:], q.targets["y"][1:] - 1.0)
    assert np.array_equal(seen["dx"], infer_directions(q.targets["x"][1:]))  # Fig. 4.10
    with pytest.raises(ValueError):
        sweeps.square(compensate=comp, directions="sideways")


def test_random_points_table_4_3():
    p = sweeps.random_points(cycles=3)
    assert p.name == "random_points" and len(p) == 31
    assert np.allclose([p.targets["x"][1], p.targets["y"][1]], [3471, 2311])  # P1
    assert np.allclose([p.targets["x"][10], p.targets["y"][10]], [1035, 35])  # P10
    assert np.array_equal(p.pose[1:11], np.arange(1, 11))
    with pytest.raises(ValueError):
        sweeps.random_points(targets=[[1, 2, 3]])


def test_angle_residual_targets_and_plan():
    t = sweeps.angle_residuals()
    assert t.shape == (45, 3)  # 9 positions of Table 4.7 x 5 angles
    assert np.array_equal(t[:5, 2], [1, 2, 3, 4, 5]) and np.all(t[:5, :2] == t[0, :2])
    assert len(np.unique(t[:, :2], axis=0)) == 9
    t2 = sweeps.angle_residuals(targets=[[-1000, -100]], angles=(2, 4))
    assert np.array_equal(t2, [[-1000, -100, 2], [-1000, -100, 4]])
    p_true = Parameters(9572.9, 7795.9, 177.69, -0.11)
    plan = sweeps.angle_residual_plan(lambda x, y, th: inverse(x, y, th, p_true), cycles=2)
    assert plan.name == "angle_residuals" and plan.name in PLANS and len(plan) == 1 + 90
    assert np.array_equal(plan.commands["theta"][1:], np.tile(t[:, 2], 2))


def test_plans_acquire_into_valid_runs():
    meta = RunMetadata(
        campaign="t", robot="xytheta", source="simulated", plan="square", config_sha256="0" * 64
    )
    run = acquire(
        sweeps.square(side_um=500, origin_um=100, points_per_segment=3, cycles=2),
        simulated_xytheta(seed=0, stream="sq"),
        meta,
    )
    assert validate_dataset(run) == []
    assert "target_x" in run and run.attrs["plan"] == "square"
