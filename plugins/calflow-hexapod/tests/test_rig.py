"""The simulated hexapod rig: each effect changes what it should and nothing else, the whole
chain is exact when every error is off, runs are reproducible by seed."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from rig_noise import NOISE_OFF

from calflow.errors import OptionError, RigError
from calflow.rigs.protocol import missing_members
from calflow_hexapod.models.geometry import H811_TRAVEL, rotation
from calflow_hexapod.models.kinematics import forward, inverse
from calflow_hexapod.stage import tracker
from calflow_hexapod.stage.physics import (
    EFFECTS,
    G,
    HexapodTruth,
    check_options,
    options_off,
)
from calflow_hexapod.stage.rig import SENSORS, attained, simulated_hexapod

FRAMES_OFF = {
    "frame_offset_um": (0.0, 0.0, 0.0),
    "frame_rotation_deg": (0.0, 0.0, 0.0),
    "tool_offset_um": (0.0, 0.0, 0.0),
    "tool_rotation_deg": (0.0, 0.0, 0.0),
}
CMDS = np.array(
    [
        [0, 0, 0, 0, 0, 0],
        [3000, -2000, 1500, 2, -1, 5],
        [-8000, 6000, -3000, -4, 3, -10],
        [9000, 6000, 1500, 4, 3, 10],
    ],
    dtype=float,
)


def perfect(**on) -> HexapodTruth:
    """A truth with every effect, the noise and the frames off, then ``on`` switched on."""
    opts = {k: (tuple(v) if isinstance(v, list) else v) for k, v in options_off().items()}
    return HexapodTruth(**{**opts, **NOISE_OFF, **FRAMES_OFF, **on})


def true_poses(truth: HexapodTruth, direction=1.0, temperature=None) -> np.ndarray:
    enc = truth.quantise(inverse(truth.nominal(), CMDS))
    T = np.full(
        len(CMDS),
        truth.reference_temperature_degC if temperature is None else temperature,
    )
    return attained(
        truth,
        truth.geometry(),
        enc,
        np.full((len(CMDS), 6), direction),
        T,
        CMDS,
        np.zeros_like(CMDS),
    )


def test_rig_protocol_members():
    assert missing_members(simulated_hexapod()) == []


def test_without_errors_the_platform_attains_the_command_and_the_tracker_reads_it():
    t = perfect()
    poses = true_poses(t)
    np.testing.assert_allclose(poses, CMDS, atol=1e-6)
    r = tracker.read(t, poses, np.zeros((len(CMDS), 6)))
    np.testing.assert_allclose(np.column_stack([r[s] for s in SENSORS]), CMDS, atol=1e-6)


@pytest.mark.parametrize(
    "effect,on",
    [
        ("joint_errors", {"joint_error_um": 20.0}),
        ("leg_offsets", {"leg_offset_um": 30.0}),
        ("leg_scale", {"leg_scale_ppm": 500.0}),
        ("joint_play", {"joint_play_um": 2.0}),
        ("compliance", {"payload_kg": 2.0}),
        ("expansion", {"expansion_ppm_per_degC": 11.5}),
        ("quantisation", {"encoder_resolution_um": 1.0}),
    ],
)
def test_each_leg_effect_alone_moves_the_platform(effect, on):
    assert set(on) == set(EFFECTS[effect])
    moved = np.abs(true_poses(perfect(**on), temperature=22.0) - CMDS).max(axis=0)
    assert moved[:3].max() > 0.05  # µm: the effect moves the platform ...
    assert np.abs(true_poses(perfect(), temperature=22.0) - CMDS).max() < 1e-6  # ... and it alone


def test_leg_terms_are_their_own_size():
    t = perfect(leg_offset_um=30.0, leg_scale_ppm=100.0)
    enc = t.quantise(inverse(t.nominal(), CMDS))
    legs = t.true_legs(
        enc,
        np.ones((len(CMDS), 6)),
        np.full(len(CMDS), t.reference_temperature_degC),
        CMDS,
    )
    np.testing.assert_allclose(
        legs - enc,
        t.leg_offsets() + t.leg_scales() * (enc - t.home_lengths()),
        atol=1e-9,
    )
    play = perfect(joint_play_um=2.0)
    forth = play.true_legs(enc, np.ones((4, 6)), np.full(4, 21.0), CMDS)
    back = play.true_legs(enc, -np.ones((4, 6)), np.full(4, 21.0), CMDS)
    np.testing.assert_allclose(forth - back, 2.0)  # the whole play between the two approach sides
    warm = perfect(expansion_ppm_per_degC=11.5)
    hot = warm.true_legs(enc, np.ones((4, 6)), np.full(4, warm.reference_temperature_degC + 2.0), CMDS)
    np.testing.assert_allclose(hot - enc, 11.5e-6 * enc * 2.0, rtol=1e-9)


def test_quantisation_holds_whole_counts():
    t = perfect(encoder_resolution_um=0.5)
    enc = t.quantise(inverse(t.nominal(), CMDS))
    counts = (enc - t.home_lengths()) / 0.5
    np.testing.assert_allclose(counts, np.round(counts), atol=1e-6)
    assert np.abs(enc - inverse(t.nominal(), CMDS)).max() <= 0.25 + 1e-9


def test_geometric_draws_are_independent_of_the_other_amplitudes():
    t = HexapodTruth()
    off = t.without("joint_error_um")
    np.testing.assert_array_equal(off.leg_offsets(), t.leg_offsets())
    np.testing.assert_array_equal(off.geometry().base, t.nominal().base)
    assert np.abs(t.geometry().base - t.nominal().base).max() > 1.0


def test_compliance_gives_the_datasheet_z_stiffness():
    """At home, with the payload's centre of mass on the axis, the platform sinks m g / k_z."""
    t = perfect(payload_kg=2.0, payload_com_um=(0.0, 0.0, 50000.0))
    sink = true_poses(t)[0]
    assert sink[2] == pytest.approx(-2.0 * G / t.stiffness_z_n_per_um, rel=0.02)
    assert np.abs(sink[[0, 1, 3, 4, 5]]).max() < 0.05


@settings(max_examples=30, deadline=None)
@given(st.lists(st.floats(-1.0, 1.0), min_size=6, max_size=6), st.floats(0.1, 10.0))
def test_leg_forces_balance_the_weight(frac, mass):
    t = perfect(payload_kg=mass, payload_com_um=(2000.0, -1000.0, 40000.0))
    pose = np.asarray(frac) * H811_TRAVEL * 0.5
    f = t.leg_forces(pose, t.nominal())[0]
    R = rotation(*pose[3:])
    P = pose[:3] + t.nominal().platform @ R.T
    n = (P - t.nominal().base) / np.linalg.norm(P - t.nominal().base, axis=1)[:, None]
    np.testing.assert_allclose(f @ n, [0.0, 0.0, mass * G], atol=1e-9 * mass)
    C = pose[:3] + R @ np.array(t.payload_com_um)
    np.testing.assert_allclose(np.sum(np.cross(P - C, f[:, None] * n), axis=0), 0.0, atol=1e-6 * mass)


def test_tracker_systematic_error_is_across_the_beam_and_leaves_the_angles():
    t_off, t_on = perfect(), perfect(tracker_systematic_um=3.0)
    a, b = (tracker.read(t, CMDS, np.zeros((4, 6))) for t in (t_off, t_on))
    d = np.column_stack([b[k] - a[k] for k in ("meas_x", "meas_y", "meas_z")])
    p, _ = tracker.probe_pose(t_on, CMDS)
    beam = tracker.beam_basis(t_on, p)[0]
    np.testing.assert_allclose(np.sum(d * beam, axis=1), 0.0, atol=1e-9)
    assert np.all(np.linalg.norm(d, axis=1) <= 3.0 * np.sqrt(2) + 1e-9) and np.abs(d).max() > 0.1
    for k in ("meas_u", "meas_v", "meas_w"):
        np.testing.assert_array_equal(a[k], b[k])


def test_tracker_noise_follows_the_mpe():
    t = perfect(**{k: getattr(HexapodTruth(), k) for k in NOISE_OFF if k.startswith("tracker")})
    z = np.random.default_rng(3).standard_normal((4000, 6))
    pose = np.zeros((4000, 6))
    r = tracker.read(t, pose, z)
    spread = np.std(np.column_stack([r["meas_x"], r["meas_y"], r["meas_z"]]), axis=0)
    D = t.tracker_distance_m
    adm, across = (10.0 + 0.3 * D) / 4, (15.0 + 6.0 * D) / 4
    # the beam runs mostly along x (10° down): x sees the ADM, y the transverse error
    assert spread[0] == pytest.approx(np.hypot(adm * np.cos(0.1745), across * np.sin(0.1745)), rel=0.08)
    assert spread[1] == pytest.approx(across, rel=0.08)
    assert np.std(r["meas_u"]) == pytest.approx(0.01 / 4, rel=0.08)


def test_unmodelled_false_switches_off_exactly_the_unmodelled_effects():
    t = HexapodTruth(unmodelled=False)
    for name in EFFECTS.unmodelled_fields:
        assert getattr(t, name) == 0.0
    assert t.joint_error_um == HexapodTruth().joint_error_um and t.leg_scale_ppm > 0


def test_same_seed_same_bytes_other_stream_other_noise():
    def run(seed, stream):
        rig = simulated_hexapod(seed=seed, stream=stream)
        out = []
        for c in CMDS:
            rig.move(dict(zip(rig.joints, c)))
            rig.wait(1.0)
            out.append(list(rig.read().values()))
        return np.array(out)

    assert run(4, "identification").tobytes() == run(4, "identification").tobytes()
    assert not np.array_equal(run(4, "identification"), run(4, "validation"))
    assert not np.array_equal(run(4, "identification"), run(5, "identification"))


def test_visit_equals_move_wait_read():
    rig_a, rig_b = (
        simulated_hexapod(seed=2, stream="s"),
        simulated_hexapod(seed=2, stream="s"),
    )
    fast = rig_a.visit({j: CMDS[:, k] for k, j in enumerate(rig_a.joints)}, 2.0)
    for i, c in enumerate(CMDS):
        rig_b.move(dict(zip(rig_b.joints, c)))
        rig_b.wait(2.0)
        slow = rig_b.read()
        for k, v in slow.items():
            assert fast[k][i] == v, k


def test_positions_are_encoder_true_not_true():
    rig = simulated_hexapod(seed=0)
    rig.move(dict(zip(rig.joints, CMDS[2])))
    pos = np.array(list(rig.positions().values()))
    assert np.abs(pos - CMDS[2]).max() < 0.01  # the nominal FK of the encoders: the command, quantised
    assert np.abs(rig._pose - CMDS[2]).max() > 5.0  # where the platform really is: tens of µm off


def test_thermometers_read_room_and_lagging_legs():
    rig = simulated_hexapod(seed=0, room_profile="lab5day")
    temps = []
    for _ in range(144):  # one day, every 10 min
        rig.wait(600.0)
        r = rig.read()
        temps.append((r["T1"], r["T2"]))
    temps = np.array(temps)
    assert np.ptp(temps[:, 0]) > 0.1 and np.ptp(temps[:, 1]) > 0.05
    assert np.ptp(temps[:, 1]) < np.ptp(temps[:, 0])  # the lag damps the daily swing ...
    assert np.argmax(temps[:, 1]) > np.argmax(temps[:, 0])  # ... and delays its peak


@pytest.mark.parametrize(
    "key,value",
    [
        ("joint_error_um", -1.0),
        ("payload_kg", float("nan")),
        ("room_profile", "sauna"),
        ("unmodelled", 1),
        ("velocity_um_s", 0.0),
        ("frame_offset_um", [1.0, 2.0]),
        ("geometry_seed", 1.5),
    ],
)
def test_bad_options_name_the_option(key, value):
    with pytest.raises(OptionError) as exc:
        check_options(**{key: value})
    assert exc.value.option == key


def test_unknown_option_and_bad_command():
    with pytest.raises(OptionError, match="warp"):
        simulated_hexapod(warp=9)
    rig = simulated_hexapod()
    with pytest.raises(RigError, match="'w'"):
        rig.move({"x": 0, "y": 0, "z": 0, "u": 0, "v": 0})
    rig.close()
    with pytest.raises(RigError, match="close"):
        rig.read()


def test_forward_of_true_geometry_is_consistent():
    t = HexapodTruth()
    poses = true_poses(t)
    legs = inverse(t.geometry(), poses)
    np.testing.assert_allclose(forward(t.geometry(), legs, start=CMDS), poses, atol=1e-6)


def test_run_options_give_each_run_its_stream_and_start():
    from calflow_hexapod.stage.run_options import rig_options

    c = {"seed": 9}
    sim = rig_options(c, "simulated", "validation_heldout_geometric", {"payload_kg": 1.0}, 3600.0)
    assert sim == {
        "payload_kg": 1.0,
        "seed": 9,
        "stream": "validation_heldout_geometric",
        "start_offset_s": 3600.0,
    }
    a, b = (
        simulated_hexapod(**rig_options(c, "simulated", run, {}, 0.0))
        for run in ("identification", "iso9283")
    )
    a.move(dict(zip(a.joints, CMDS[1])))
    b.move(dict(zip(b.joints, CMDS[1])))
    assert a.read()["meas_x"] != b.read()["meas_x"]
    gcs = rig_options(c, "gcs", "identification", {"sensor": {"factory": "simulated_tracker"}}, 0.0)
    assert gcs["sensor"]["options"] == {"seed": 9, "stream": "identification", "start_offset_s": 0.0}


@pytest.mark.parametrize("effect", ["leg_offsets", "leg_scale", "joint_play", "compliance", "expansion"])
def test_switching_a_leg_effect_off_removes_exactly_its_term(effect):
    """On the full rig, the true legs with ``effect`` off differ from those with it on by that
    effect's own term, and by nothing else."""
    full = HexapodTruth()
    off = full.without(*EFFECTS[effect])
    enc = full.quantise(inverse(full.nominal(), CMDS))
    direction = np.where(np.arange(6) % 2, -1.0, 1.0) * np.ones((len(CMDS), 1))
    T = np.full(len(CMDS), 21.3)
    diff = full.true_legs(enc, direction, T, CMDS) - off.true_legs(enc, direction, T, CMDS)
    base = enc + full.leg_offsets() + full.leg_scales() * (enc - full.home_lengths()) + full.play(direction)
    term = {
        "leg_offsets": full.leg_offsets() * (1 + full.expansion_ppm_per_degC * 1e-6 * (21.3 - 20.0)),
        "leg_scale": full.leg_scales()
        * (enc - full.home_lengths())
        * (1 + full.expansion_ppm_per_degC * 1e-6 * 1.3),
        "joint_play": full.play(direction) * (1 + full.expansion_ppm_per_degC * 1e-6 * 1.3),
        "compliance": full.compliance(CMDS),
        "expansion": full.expansion(base, T),
    }[effect]
    np.testing.assert_allclose(diff, np.broadcast_to(term, diff.shape), atol=1e-9)
    assert np.abs(diff).max() > 0.1


def test_the_rig_refuses_what_the_controller_refuses():
    rig = simulated_hexapod()
    beyond = [16000.0, 16000.0, 6000.0, 9.0, 9.0, 20.0]  # each coordinate inside its travel
    with pytest.raises(RigError, match="outside the workspace"):
        rig.move(dict(zip(rig.joints, beyond)))
    with pytest.raises(RigError, match="outside the workspace"):
        rig.visit({j: np.array([0.0, v]) for j, v in zip(rig.joints, beyond)}, 1.0)
    rig.move(dict(zip(rig.joints, CMDS[3])))  # still usable
