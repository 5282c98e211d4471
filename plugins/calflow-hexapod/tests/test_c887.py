"""The C-887-class controller emulation: commands, encoder-true POS?, SPI, limits → error codes,
and a gcs-rig run through it that sees the simulated rig's physics."""

from __future__ import annotations

import time

import numpy as np
import pytest

from calflow.gcs import GCSController, GCSControllerError
from calflow.gcs.emulation.emulator import GCSEmulator
from calflow_hexapod.models.geometry import h811
from calflow_hexapod.models.kinematics import forward, inverse
from calflow_hexapod.stage.c887 import AXIS_IDS, HexapodController
from calflow_hexapod.stage.emulate import (
    SENSOR,
    SENSOR_TARGET,
    campaign_emulator,
    rig_options,
)
from calflow_hexapod.stage.rig import simulated_hexapod
from calflow_hexapod.stage.workspace import leg_stroke_um, reachable

MM = 1000.0


@pytest.fixture
def ctl():
    with GCSEmulator(controller=HexapodController(time_scale=50.0, resolution_um=1.0)) as emu:
        c = GCSController.connect_tcp(*emu.address, timeout=2.0)
        yield c
        c.close()


def ready(c: GCSController) -> None:
    c.servo_on(list(AXIS_IDS))
    c.reference(["X"], timeout=10.0, poll=0.01)


def settle(c: GCSController) -> dict[str, float]:
    return c.wait_on_target(timeout=10.0, poll=0.01, axes=list(AXIS_IDS))


def test_axes_identity_and_limits(ctl):
    assert ctl.axes() == list(AXIS_IDS)
    assert "C-887" in ctl.idn()
    lim = ctl.limits(["X", "Z", "W"])
    assert lim["X"] == (-17.0, 17.0) and lim["Z"] == (-6.5, 6.5) and lim["W"] == (-21.0, 21.0)


def test_move_before_reference_is_error_5(ctl):
    ctl.servo_on(list(AXIS_IDS))
    with pytest.raises(GCSControllerError) as exc:
        ctl.move({"X": 1.0})
    assert exc.value.code == 5


def test_frf_of_one_axis_references_all_six(ctl):
    ready(ctl)
    assert all(ctl.is_referenced(list(AXIS_IDS)).values())


def test_pos_is_encoder_true(ctl):
    """POS? is the nominal forward kinematics of whole-count encoders: within the 1 µm counts
    of the command, and exactly what the controller's own geometry gives for those counts."""
    ready(ctl)
    cmd = np.array([2.3456789, -1.2345671, 0.7654321, 1.23456, -0.65432, 3.14159])
    ctl.move(dict(zip(AXIS_IDS, cmd)))
    pos = settle(ctl)
    got = np.array([pos[a] for a in AXIS_IDS])
    pose_um = cmd * [MM, MM, MM, 1, 1, 1]
    g = h811()
    legs = g.zero_lengths + np.round(inverse(g, pose_um) - g.zero_lengths)
    want = forward(g, legs, start=pose_um) / [MM, MM, MM, 1, 1, 1]
    np.testing.assert_allclose(got, want, atol=2e-6)
    assert np.abs(got - cmd)[:3].max() > 1e-5  # not the command: the counts show
    assert all(ctl.on_target(list(AXIS_IDS)).values())


def test_out_of_axis_limits_is_error_7_and_nothing_moves(ctl):
    ready(ctl)
    with pytest.raises(GCSControllerError) as exc:
        ctl.move({"X": 1.0, "Y": 17.5})
    assert exc.value.code == 7
    assert ctl.target(["X", "Y"]) == {"X": 0.0, "Y": 0.0}


def test_combined_extremes_beyond_the_legs_stroke_are_error_7(ctl):
    ready(ctl)
    pose = np.array([16000.0, 16000.0, 6000.0, 9.0, 9.0, 20.0])
    assert not reachable(pose) and all(abs(pose) <= [17000, 17000, 6500, 10, 10, 21])
    with pytest.raises(GCSControllerError) as exc:
        ctl.move(dict(zip(AXIS_IDS, pose / [MM, MM, MM, 1, 1, 1])))
    assert exc.value.code == 7
    assert all(v == 0.0 for v in ctl.target(list(AXIS_IDS)).values())


def test_unknown_axis_is_error_15(ctl):
    ready(ctl)
    with pytest.raises(GCSControllerError) as exc:
        ctl.command("MOV", "Q", "1.0")
    assert exc.value.code == 15


def test_spi_sets_the_pivot_rotations_turn_about_it(ctl):
    ready(ctl)
    ctl.command("SPI", "R", "0", "S", "0", "T", "50")
    assert ctl.query("SPI?") == ["R=0.000000", "S=0.000000", "T=50.000000"]
    ctl.move({"U": 2.0})
    settle(ctl)
    with pytest.raises(GCSControllerError) as exc:  # U is not 0: the pivot cannot change
        ctl.command("SPI", "T", "0")
    assert exc.value.code == 9
    assert ctl.query("SPI? T") == ["T=50.000000"]
    with pytest.raises(GCSControllerError) as exc:
        ctl.command("SPI", "Q", "1")
    assert exc.value.code == 1


def test_system_velocity(ctl):
    ctl.command("VLS", "2.5")
    assert ctl.query("VLS?") == ["2.500000"]
    assert ctl.velocity(["X", "W"]) == {"X": 2.5, "W": 2.5}
    with pytest.raises(GCSControllerError) as exc:
        ctl.command("VLS", "1000")
    assert exc.value.code == 8


def test_pivot_changes_the_legs_of_a_rotation():
    a, b = HexapodController(resolution_um=0.0), HexapodController(resolution_um=0.0)
    b.pivot_um = np.array([0.0, 0.0, 50000.0])
    pose = np.array([0.0, 0.0, 0.0, 3.0, 0.0, 0.0])
    la, lb = a.encoder_legs(pose), b.encoder_legs(pose)
    assert np.abs(la - lb).max() > 100.0  # a 3° tilt about a point 50 mm higher moves the legs
    np.testing.assert_allclose(a.encoder_legs(np.zeros(6)), b.encoder_legs(np.zeros(6)))


def test_leg_stroke_admits_every_single_axis_extreme():
    travel = np.array([17000.0, 17000.0, 6500.0, 10.0, 10.0, 21.0])
    assert reachable(np.diag(travel)).all() and reachable(-np.diag(travel)).all()
    assert 3000.0 < leg_stroke_um() < 20000.0


@pytest.fixture
def allow_sensor(monkeypatch):
    """The family registers the tracker as the gcs rig's ``simulated_tracker`` sensor."""
    monkeypatch.setattr("calflow.gcs.sensors.builtin_sensors", lambda: {SENSOR: SENSOR_TARGET})


def test_gcs_rig_through_the_emulator_sees_the_simulated_physics(allow_sensor):
    """The same seed and stream, noise and temperature off (the clocks differ): the gcs rig's
    readings through the C-887 emulator equal the simulated rig's."""
    from calflow.gcs.rig import gcs

    physics = {"room_profile": "constant", "expansion_ppm_per_degC": 0.0}
    campaign = {
        "name": "hex",
        "robot": "hexapod",
        "seed": 3,
        "rig": {"factory": "simulated", "options": physics},
    }
    emu = campaign_emulator(campaign, time_scale=200.0).start()
    try:
        opts = rig_options(emu.address, campaign, time_scale=200.0, timeout=2.0)
        opts["sensor"]["options"]["stream"] = "s"
        rig = gcs(**opts)
        sim = simulated_hexapod(seed=3, stream="s", **physics)
        a, b = rig.read(), sim.read()  # at home, before any move
        assert a["meas_x"] == pytest.approx(b["meas_x"], abs=0.11) and a["meas_w"] == pytest.approx(
            b["meas_w"]
        )
        cmds = [
            [1500.0, -800.0, 300.0, 0.5, -0.3, 1.0],
            [-4000.0, 2500.0, -900.0, -1.5, 2.0, -4.0],
        ]
        for c in cmds:
            for r in (rig, sim):
                r.move(dict(zip(r.joints, c)))
            a, b = rig.read(), sim.read()
            for k in ("meas_x", "meas_y", "meas_z"):
                assert a[k] == pytest.approx(b[k], abs=0.11), k
            for k in ("meas_u", "meas_v", "meas_w"):
                assert a[k] == pytest.approx(b[k], abs=1e-6), k
        rig.close()
    finally:
        emu.stop()


def test_lines_as_pipython_formats_them():
    """pipython writes floats with format '.12g' (exponents for small values), several axes per
    line, and checks each command with ERR?; queries answer one 'axis=value' line per axis."""
    import socket

    from calflow.gcs.wire.protocol import ReplyFramer

    with GCSEmulator(controller=HexapodController(time_scale=50.0)) as emu:
        sock = socket.create_connection(emu.address, timeout=2)
        framer = ReplyFramer()

        def ask(line: str) -> list[str]:
            sock.sendall(line.encode() + b"\n")
            while (reply := framer.pop()) is None:
                framer.feed(sock.recv(4096))
            return reply

        sock.sendall(b"SVO X 1 Y 1 Z 1 U 1 V 1 W 1\nFRF X\n")
        assert ask("ERR?") == ["0"]
        deadline = time.monotonic() + 10
        while ask("FRF? X Y Z U V W") != [f"{a}=1" for a in AXIS_IDS]:
            assert time.monotonic() < deadline
            time.sleep(0.01)
        sock.sendall(f"MOV X {format(1e-05, '.12g')} W {format(-0.5, '.12g')}\n".encode())
        assert ask("ERR?") == ["0"]
        sock.sendall(b"SPI R 0 S 0 T 12.5\n")
        assert ask("ERR?") == ["9"]  # W is not 0: the pivot stays
        assert ask("SPI? R S T") == ["R=0.000000", "S=0.000000", "T=0.000000"]
        assert [line.split("=")[0] for line in ask("POS? X Y Z U V W")] == list(AXIS_IDS)
        sock.close()
