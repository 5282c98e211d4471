"""Rig loading from `rig.factory` and the simulated XYΘ rig."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from calflow.acquisition.runner import acquire
from calflow.data.runs import RunMetadata
from calflow.errors import RigError
from calflow.rigs import load_rig
from calflow.xytheta.plans import poses as plans
from calflow.xytheta.stage.rig import simulated_xytheta

META = RunMetadata(
    campaign="t", robot="xytheta", source="simulated", plan="identification", config_sha256="0" * 64
)


def test_builtin_and_plugin_factories_load():
    rig, source = load_rig("simulated", "xytheta", {"seed": 1})
    assert source == "simulated" and rig.joints == ("x", "y", "theta")
    rig, source = load_rig("toyrigs:open_toy", "xytheta", {"x_R": 100.0}, allowed=["toyrigs"])
    assert source == "plugin" and rig.p[0] == 100.0


@pytest.mark.parametrize(
    "factory,match",
    [
        ("no_such_module_xyz:make", "cannot import"),
        ("toyrigs:nothing_here", "no callable"),
        ("os.system", "expected 'simulated'"),
    ],
)
def test_bad_factories_give_clear_errors(factory, match):
    with pytest.raises(RigError, match=match):
        load_rig(factory, "xytheta", {}, allowed=["toyrigs", "no_such_module_xyz"])


@pytest.mark.parametrize(
    "factory,allowed",
    [("os:system", []), ("toyrigs:open_toy", ["toy"]), ("toyrigs:open_toy", ["toyrigs.sub"])],
)
def test_plugin_factories_run_only_when_their_module_is_allowed(factory, allowed, monkeypatch):
    monkeypatch.delenv("CALFLOW_RIG_PLUGINS", raising=False)
    with pytest.raises(RigError, match="not allowed to run.*rig_plugins"):
        load_rig(factory, "xytheta", {"command": "true"}, allowed=allowed)


def test_a_parent_package_or_the_environment_allows_a_module(monkeypatch):
    from calflow.rigs.plugin import is_allowed

    assert is_allowed("my_lab.rigs.stage", ["my_lab"]) and not is_allowed("my_labx", ["my_lab"])
    monkeypatch.setenv("CALFLOW_RIG_PLUGINS", "toyrigs, my_lab")
    assert load_rig("toyrigs:open_toy", "xytheta", {})[1] == "plugin"


def test_unknown_option_is_named():
    with pytest.raises(RigError, match="bogus"):
        load_rig("simulated", "xytheta", {"bogus": 1})


def _run(seed, stream="id", **physics):
    return acquire(
        plans.identification(30, seed=0), simulated_xytheta(seed=seed, stream=stream, **physics), META
    )


def test_same_seed_same_readings_different_seed_different_noise():
    a, b, c = _run(1), _run(1), _run(2)
    assert np.array_equal(a["meas_x"].values, b["meas_x"].values, equal_nan=True)
    assert not np.allclose(a["meas_x"].values, c["meas_x"].values, equal_nan=True)
    # the same truth: noise-free tool points coincide
    assert simulated_xytheta(seed=1).truth() == simulated_xytheta(seed=2).truth()


def test_reading_is_the_pattern_frame_view_of_the_tool_point():
    """Eq. (4.26): with noise and physics errors off, the reading is the exact transform."""
    from calflow.xytheta.stage.physics import options_off

    rig = simulated_xytheta(
        seed=0,
        sensor_noise_um=0.0,
        stage_repeatability_um=0.0,
        sensor_resolution_um=1e-9,
        room_swing_degC=0.0,
        sensor_theta_noise_deg=0.0,
        **options_off(),
    )
    from calflow.xytheta.models.kinematics import forward, world_from_pattern

    home = rig.read()
    rig.move({"x": 1500.0, "y": 700.0, "theta": 3.0})
    r = rig.read()
    x_P, y_P = world_from_pattern(r["meas_x"], r["meas_y"], r["meas_theta"], home["meas_x"], home["meas_y"])
    want = forward(1500.0, 700.0, 3.0, rig.truth_model.parameters)
    assert np.allclose([x_P, y_P], want, atol=1e-6)


def test_virtual_time_advances_with_moves_and_dwell():
    rig = simulated_xytheta()
    t0 = rig.read()["time"]
    rig.move({"x": 1000.0, "y": 0.0, "theta": 0.0})
    rig.wait(10.0)
    assert rig.read()["time"] - t0 == pytest.approx(1.0 + 0.5 + 10.0)


@settings(max_examples=25, deadline=None)
@given(
    seed=st.integers(0, 2**31),
    n=st.integers(0, 60),
    split=st.floats(0, 1),
    dwell=st.floats(0, 5),
    lost_motion=st.booleans(),
    gross=st.sampled_from([0.0, 0.001, 0.3]),
    repeat=st.integers(0, 5),
)
def test_visit_in_bulk_is_the_same_as_move_wait_read(seed, n, split, dwell, lost_motion, gross, repeat):
    """The runner's fast path: the simulated XYΘ rig's ``visit`` gives, bit for bit, the
    readings and the final state (time, random stream) of move/wait/read row by row —
    short moves inside the backlash, repeated commands and gross errors included."""
    from calflow.xytheta.stage.rig import simulated_xytheta

    rng = np.random.default_rng(seed)
    cmd = {
        "x": rng.uniform(0, 15000, n),
        "y": rng.uniform(0, 15000, n),
        "theta": rng.choice([-20.0, 0.0, 7.5], n),
    }
    cmd["x"][: n // 2] = np.cumsum(rng.normal(0, 1.5, n // 2)) + 5000  # lost-motion moves, sub-backlash
    cmd["y"][:repeat] = cmd["y"][0] if n else 0.0  # repeated commands
    opts = dict(seed=seed, stream="t", lost_motion=lost_motion, gross_error_rate=gross)
    one, bulk = simulated_xytheta(**opts), simulated_xytheta(**opts)
    rows = []
    for i in range(n):
        one.move({k: float(v[i]) for k, v in cmd.items()})
        one.wait(dwell)
        rows.append(one.read())
    k = int(split * n)
    a, b = (bulk.visit({j: v[s] for j, v in cmd.items()}, dwell) for s in (slice(0, k), slice(k, n)))
    for key in ("time", "meas_x", "meas_y", "meas_theta", "T1"):
        got = np.concatenate([a[key], b[key]])
        assert np.array_equal(got, np.array([r[key] for r in rows], dtype=float), equal_nan=True), key
    one.move({"x": 1.0, "y": 2.0, "theta": 0.0})
    bulk.move({"x": 1.0, "y": 2.0, "theta": 0.0})
    r1, r2 = one.read(), bulk.read()  # the same state and the same place in the random stream
    assert r1.keys() == r2.keys() and np.array_equal(list(r1.values()), list(r2.values()), equal_nan=True)
