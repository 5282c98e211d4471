"""The GCS emulator at the byte level (raw sockets) and its axis motion model."""

from __future__ import annotations

import socket
import threading
import time

import pytest

from calflow.gcs.emulation.axis import AxisConfig, SimAxis, profile_distance, profile_time
from calflow.gcs.emulation.emulator import GARBAGE, EmulatedController, Faults, GCSEmulator, main, serve
from calflow.gcs.wire.protocol import ReplyFramer


class Raw:
    """A bare socket speaking bytes to the emulator, with bounded reads."""

    def __init__(self, address: tuple[str, int]) -> None:
        self.sock = socket.create_connection(address, timeout=2)
        self.framer = ReplyFramer()

    def send(self, data: bytes) -> None:
        self.sock.sendall(data)

    def reply(self, timeout: float = 2.0) -> list[str] | None:
        deadline = time.monotonic() + timeout
        while (r := self.framer.pop()) is None:
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            self.sock.settimeout(left)
            try:
                data = self.sock.recv(4096)
            except TimeoutError:
                return None
            if not data:
                raise ConnectionError("closed")
            self.framer.feed(data)
        return r

    def ask(self, line: str) -> list[str] | None:
        self.send(line.encode("latin-1") + b"\n")
        return self.reply()

    def close(self) -> None:
        self.sock.close()


@pytest.fixture
def emu():
    with GCSEmulator(axes="1,2", time_scale=10.0) as e:
        yield e


@pytest.fixture
def raw(emu):
    r = Raw(emu.address)
    yield r
    r.close()


def ready_axes(raw: Raw) -> None:
    raw.send(b"SVO 1 1 2 1\nFRF\n")
    deadline = time.monotonic() + 5
    while raw.ask("FRF? 1 2") != ["1=1", "2=1"]:
        assert time.monotonic() < deadline
        time.sleep(0.01)
    assert raw.ask("ERR?") == ["0"]


# ------------------------------------------------------------------ server basics
@pytest.mark.parametrize("host", ["0.0.0.0", "192.168.1.10", "::", ""])
def test_refuses_any_host_but_loopback(host):
    with pytest.raises(ValueError, match="127.0.0.1"):
        GCSEmulator(host=host)


def test_port_zero_picks_a_free_loopback_port(emu):
    host, port = emu.address
    assert host == "127.0.0.1" and port > 0
    assert emu._sock.getsockname()[0] == "127.0.0.1"


def test_several_commands_in_one_segment(raw):
    raw.send(b"*IDN?\nSAI?\nPOS? 1 2\nERR?\n")
    assert "C-863" in raw.reply()[0]
    assert raw.reply() == ["1", "2"]
    assert raw.reply() == ["1=0.000000", "2=0.000000"]
    assert raw.reply() == ["0"]


def test_command_split_across_segments(raw):
    raw.send(b"PO")
    time.sleep(0.15)
    raw.send(b"S? ")
    time.sleep(0.15)
    raw.send(b"2\n")
    assert raw.reply() == ["2=0.000000"]


def test_multiline_reply_uses_continuation_spaces(emu):
    s = socket.create_connection(emu.address, timeout=2)
    s.sendall(b"SAI?\n")
    data = b""
    while not data.endswith(b"2\n"):
        data += s.recv(100)
    s.close()
    assert data == b"1 \n2\n"


def test_mnemonic_case_insensitive_and_err_clears(raw):
    assert raw.ask("csv?") == ["2.0"]
    raw.send(b"\t\n\x00\xff\n")  # junk lines are unknown commands, not a crash
    assert raw.ask("ERR?") == ["2"]
    raw.send(b"XYZ 1\n")
    assert raw.ask("ERR?") == ["2"]
    assert raw.ask("ERR?") == ["0"]


def test_failing_query_sends_nothing_and_sets_error_15(raw):
    raw.send(b"POS? 9\n")
    assert raw.reply(timeout=0.3) is None  # a real controller does not answer either
    raw.send(b"ERR?\n")
    assert raw.reply() == ["15"]


def test_whole_line_rejected_when_one_part_fails(raw):
    ready_axes(raw)
    raw.send(b"MOV 1 2.0 2 99\n")
    assert raw.ask("ERR?") == ["7"]
    assert raw.ask("MOV? 1 2") == ["1=0.000000", "2=0.000000"]


def test_mov_needs_servo_and_reference(raw):
    raw.send(b"MOV 1 1\n")
    assert raw.ask("ERR?") == ["5"]
    raw.send(b"SVO 1 1\nMOV 1 1\n")
    assert raw.ask("ERR?") == ["5"]  # servo on, but not referenced
    raw.send(b"SVO 1 2\n")
    assert raw.ask("ERR?") == ["1"]


def test_motion_takes_time_then_on_target(raw, emu):
    ready_axes(raw)
    raw.send(b"VEL 1 2.0\nMOV 1 5\n")
    t0 = time.monotonic()
    assert raw.ask("ONT? 1") == ["1=0"]
    raw.send(b"\x05")
    assert raw.reply() == ["1"]  # axis 1 moving: bit 0
    mid = float(raw.ask("POS? 1")[0].split("=")[1])
    assert 0.0 <= mid < 5.0
    while raw.ask("ONT? 1") != ["1=1"]:
        assert time.monotonic() - t0 < 3
    elapsed = time.monotonic() - t0
    expected = profile_time(5.0, 2.0, AxisConfig().accel) / emu.controller.time_scale
    assert expected * 0.8 <= elapsed <= expected + 0.2
    assert raw.ask("POS? 1") == ["1=5.000000"]
    raw.send(b"\x05")
    assert raw.reply() == ["0"]


def test_reference_not_ready_then_ready(raw):
    raw.send(b"SVO 2 1\nFRF 2\n\x07")
    assert raw.reply() == ["\xb0"]
    deadline = time.monotonic() + 3
    while raw.send(b"\x07") or raw.reply() != ["\xb1"]:
        assert time.monotonic() < deadline
    assert raw.ask("FRF?") == ["1=0", "2=1"]


def test_stop_all_halts_motion_and_sets_error_10(raw):
    ready_axes(raw)
    raw.send(b"MOV 1 7\n")
    time.sleep(0.1)
    raw.send(b"\x18")
    first = raw.ask("POS? 1")
    time.sleep(0.1)
    assert raw.ask("POS? 1") == first and raw.ask("ONT? 1") == ["1=1"]
    assert 0.0 < float(first[0].split("=")[1]) < 7.0
    assert raw.ask("ERR?") == ["10"]


def test_velocity_limits_error_8(raw):
    raw.send(b"VEL 1 0\n")
    assert raw.ask("ERR?") == ["8"]
    raw.send(b"VEL 1 1.25\n")
    assert raw.ask("VEL? 1") == ["1=1.250000"] and raw.ask("ERR?") == ["0"]


# ------------------------------------------------------------------ faults and hooks
def test_true_position_hook_backs_pos():
    hook = lambda axis, commanded: commanded * 1.001 + 0.002  # noqa: E731
    with GCSEmulator(time_scale=50, true_position=hook) as e:
        r = Raw(e.address)
        assert r.ask("POS? 1") == ["1=0.002000"]
        r.close()


def test_garbage_fault_replaces_next_replies(raw, emu):
    emu.faults.garbage = 2
    raw.send(b"ERR?\n")
    raw.sock.settimeout(2)
    data = b""
    while not data.endswith(b"\n"):
        data += raw.sock.recv(100)
    assert data == GARBAGE and emu.faults.garbage == 1
    raw.send(b"ERR?\nERR?\n")  # one more garbage reply, then normal again
    assert raw.reply() == [GARBAGE[:-1].decode("latin-1")]
    assert raw.reply() == ["0"] and emu.faults.garbage == 0


def test_delay_fault_delays_replies(raw, emu):
    emu.faults.delay = 0.3
    t0 = time.monotonic()
    assert raw.ask("ERR?") == ["0"]
    assert time.monotonic() - t0 >= 0.28


def test_drop_after_n_commands(raw, emu):
    emu.faults.drop_after = 2
    assert raw.ask("ERR?") == ["0"] and raw.ask("ERR?") == ["0"]
    with pytest.raises(ConnectionError):
        raw.ask("ERR?")
    assert emu.faults.drop_after is None  # one-shot; new connections work
    again = Raw(emu.address)
    assert again.ask("ERR?") == ["0"]
    again.close()


def test_drop_on_demand_and_refuse(emu):
    r = Raw(emu.address)
    assert r.ask("ERR?") == ["0"]
    emu.drop_connections()
    with pytest.raises((ConnectionError, OSError)):
        r.ask("ERR?")
    emu.faults.refuse = 1
    refused = Raw(emu.address)
    with pytest.raises((ConnectionError, OSError)):
        refused.ask("ERR?")
    ok = Raw(emu.address)
    assert ok.ask("ERR?") == ["0"]
    for s in (r, refused, ok):
        s.close()


def test_address_prefix_in_first_line():
    with GCSEmulator(axes="1,2", address_prefix=1) as e:
        r = Raw(e.address)
        assert r.ask("ONT?") == ["0 1 1=1", "2=1"]
        r.close()


def test_serve_runs_for_duration_and_main_parses(capsys):
    t0 = time.monotonic()
    serve({"port": 0, "axes": "A,B", "duration": 0.3})
    assert 0.25 <= time.monotonic() - t0 < 3
    out = capsys.readouterr().out
    assert "127.0.0.1:" in out and "axes A, B" in out
    stop = threading.Event()
    th = threading.Thread(target=serve, args=({"port": 0},), kwargs={"stop_event": stop})
    th.start()
    stop.set()
    th.join(3)
    assert not th.is_alive()
    assert main(["--port", "0", "--axes", "1,2", "--duration", "0.1"]) == 0


# ------------------------------------------------------------------ motion model
def test_profile_is_continuous_and_ends_at_target():
    d, v, a = 4.0, 1.5, 10.0
    total = profile_time(d, v, a)
    assert total == pytest.approx(d / v + v / a)
    ts = [total * i / 200 for i in range(201)]
    s = [profile_distance(t, d, v, a) for t in ts]
    assert s[0] == 0.0 and s[-1] == d
    assert all(b >= x for x, b in zip(s, s[1:]))
    assert max(abs(b - x) for x, b in zip(s, s[1:])) <= v * total / 200 + 1e-9
    assert profile_time(0.01, v, a) == pytest.approx(2 * (0.01 / a) ** 0.5)
    assert profile_distance(total / 2, -d, v, a) == pytest.approx(-d / 2)


def test_sim_axis_stop_and_reference_abort():
    ax = SimAxis("1", AxisConfig(start_position=2.0))
    ax.servo = True
    ax.reference(0.0)
    assert ax.referencing(0.1) and not ax.referenced
    ax.stop(0.1)
    assert not ax.referencing(0.2) and not ax.referenced  # aborted reference
    ax.reference(1.0)
    assert ax.referencing(1.0) and ax.moving(1.0)
    assert not ax.referencing(10.0) and ax.referenced and ax.position(10.0) == 0.0


@pytest.mark.parametrize(
    "kwargs",
    [{"tmn": 1, "tmx": 0}, {"velocity": 0}, {"velocity": 3, "max_velocity": 2}, {"ref_position": 99}],
)
def test_axis_config_validation(kwargs):
    with pytest.raises(ValueError):
        AxisConfig(**kwargs)
    with pytest.raises(ValueError, match="unknown axis setting"):
        AxisConfig.from_mapping({"speed": 1})


def test_piezo_axis_needs_no_reference_and_faults_default():
    c = EmulatedController(
        {
            "A": AxisConfig(
                tmn=0, tmx=100, velocity=1000, max_velocity=1e4, accel=1e6, needs_reference=False, servo=True
            )
        }
    )
    assert c.handle("FRF? A") == ["A=1"]
    assert c.handle("MOV A 50") is None and c.handle("ERR?") == ["0"]
    assert Faults() == Faults(drop_after=None, delay=0.0, garbage=0, refuse=0)


def test_campaign_emulator_pos_is_the_encoder_and_the_vision_sees_the_stage():
    """Asked for 2.0 mm, ``POS?`` answers 2.0 within the encoder's 50 nm (Table 4.1), as a
    real controller's encoder would; the external sensor still sees the lead screw."""
    from calflow.gcs.wire.client import GCSController
    from calflow.xytheta.models.kinematics import forward, world_from_pattern
    from calflow.xytheta.stage.emulate import ENCODER_UM, campaign_emulator
    from calflow.xytheta.stage.vision_sensor import simulated_vision

    campaign = {"robot": "xytheta", "rig": {"factory": "simulated", "options": {}}}
    with campaign_emulator(campaign, time_scale=500.0) as e:
        ctl = GCSController.connect_tcp(*e.address, timeout=2.0)
        try:
            ctl.servo_on(["1", "2"])
            ctl.reference(["1", "2"])
            ctl.move({"1": 2.0, "2": 1.0})
            pos = ctl.wait_on_target(timeout=10.0)
        finally:
            ctl.close()
    assert abs(pos["1"] - 2.0) <= ENCODER_UM["x"] / 1000 and abs(pos["2"] - 1.0) <= ENCODER_UM["y"] / 1000
    quiet = dict(
        sensor_noise_um=0.0,
        stage_repeatability_um=0.0,
        decode_error_um=0.0,
        gross_error_rate=0.0,
        room_swing_degC=0.0,
        sensor_resolution_um=1e-6,
    )
    vision = simulated_vision(**quiet)
    home = vision.read({"x": 0.0, "y": 0.0, "theta": 0.0}, 0.0)
    r = vision.read({"x": pos["1"] * 1000, "y": pos["2"] * 1000, "theta": 0.0}, 0.0)
    x, y = world_from_pattern(r["meas_x"], r["meas_y"], 0.0, home["meas_x"], home["meas_y"])
    ideal = forward(pos["1"] * 1000, pos["2"] * 1000, 0.0, vision.truth_model.parameters)
    assert 1.0 < float(abs(x - ideal[0]) + abs(y - ideal[1])) < 30.0  # lead screw, coupling, scale...


# --------------------------------------------------------------------------- settling (ONT?)
from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st


@settings(max_examples=60, deadline=None)
@given(distance=st.floats(-14.0, 14.0).filter(lambda d: abs(d) > 1e-3), window=st.floats(1e-5, 0.5))
def test_window_entry_is_where_the_trajectory_enters_the_settle_window(distance, window):
    ax = SimAxis("1", AxisConfig(tmn=-7.5, tmx=7.5, start_position=0.0, settle_window=window))
    ax.move(distance, 0.0)
    entry = ax.window_entry()
    assert 0.0 <= entry <= profile_time(distance, ax.velocity, ax.config.accel) + 1e-12
    assert abs(distance - ax.position(entry)) <= window * (1 + 1e-9) + 1e-12
    if abs(distance) > window:  # just before, it was outside
        assert abs(distance - ax.position(entry - 1e-6)) > window * (1 - 1e-6)


def test_ont_turns_true_after_the_settling_time_in_the_window():
    """Settling time 0x3F = 2 s: the axis is on target 2 s after it entered the window,
    not when the trajectory ends (C-863 parameters, MS249E)."""
    c = EmulatedController(
        {"1": AxisConfig(settle_window=0.001, settle_time=2.0, needs_reference=False, servo=True)}
    )
    t = {"now": 0.0}
    c.now = lambda: t["now"]
    assert c.handle("ONT? 1") == ["1=1"]  # at rest since power-up
    assert c.handle("MOV 1 3") is None and c.handle("ERR?") == ["0"]
    end = profile_time(3.0, 1.5, AxisConfig().accel)
    entry = c.axes["1"].window_entry()
    assert end - 0.1 < entry < end
    for when, expected in ((end, "0"), (entry + 1.99, "0"), (entry + 2.0, "1")):
        t["now"] = when
        assert c.handle("ONT? 1") == [f"1={expected}"], when


def test_spa_sets_and_reports_the_settle_window_and_time_per_axis():
    c = EmulatedController({"1": AxisConfig(counts_per_unit=20000.0), "2": AxisConfig()})
    assert c.handle("SPA? 1 0x36 1 0x3F 1 0xE") == ["1 0x36=10", "1 0x3F=0.01", "1 0xE=20000"]
    assert c.handle("SPA 1 0x36 40 2 0x3F 0.5") is None and c.handle("ERR?") == ["0"]
    assert c.axes["1"].settle_window == pytest.approx(0.002)  # 40 counts of 50 nm
    assert c.axes["2"].settle_time == 0.5 and c.axes["2"].settle_window == 0.0005
    assert c.handle("SPA? 1 54") == ["1 54=40"]  # decimal IDs too
    for line, code in (
        ("SPA 1 0xE 5", "60"),
        ("SPA 1 0x99 5", "54"),
        ("SPA 1 0x36 -1", "17"),
        ("SPA 9 0x36 1", "15"),
        ("SPA 1 0x36", "1"),
        ("SPA 1 0x3F nan", "17"),
    ):
        assert c.handle(line) is None and c.handle("ERR?") == [code], line
    assert c.handle("SPA? 1 0x99") is None and c.handle("ERR?") == ["54"]  # no reply, error set
    assert c.axes["1"].settle_window == pytest.approx(0.002)  # failed lines changed nothing


def test_client_reads_and_writes_parameters(emu):
    from calflow.gcs.wire.client import GCSController
    from calflow.gcs.wire.protocol import GCSControllerError

    with GCSController.connect_tcp(*emu.address, timeout=1.0) as ctl:
        ctl.set_parameter("2", 0x3F, 0.25)
        assert ctl.parameter("2", 0x3F) == 0.25 and ctl.parameter("1", 0x3F) == 0.01
        with pytest.raises(GCSControllerError, match="60"):
            ctl.set_parameter("1", 0xF, 2)


def test_the_gcs_rig_sets_settling_parameters_per_joint_at_open(monkeypatch):
    from calflow.errors import OptionError
    from calflow.gcs.rig import gcs
    from calflow.gcs.rig_options import check_options

    monkeypatch.setenv("CALFLOW_RIG_PLUGINS", "test_rigs_gcs")
    with GCSEmulator(
        axes={"1": {"needs_reference": False}, "2": {"needs_reference": False}}, time_scale=10.0
    ) as e:
        options = dict(
            axes={"x": "1", "y": "2"},
            host="127.0.0.1",
            port=e.address[1],
            timeout=1.0,
            parameters={"x": {"0x3F": 0.2}, "y": {54: 40}},
            sensor={"factory": "test_rigs_gcs:EchoSensor", "options": {}},
        )
        check_options(**options)
        rig = gcs(**options)
        rig.close()
        assert e.controller.axes["1"].settle_time == 0.2
        assert e.controller.axes["2"].settle_window == pytest.approx(0.002)  # 40 counts
    with pytest.raises(OptionError, match="parameters.z"):
        check_options(**{**options, "parameters": {"z": {"0x3F": 1}}})
    with pytest.raises(OptionError, match="parameters.x.settle"):
        check_options(**{**options, "parameters": {"x": {"settle": 1}}})
