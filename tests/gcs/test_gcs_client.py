"""GCSController end to end against the emulator: motion, error mapping, faults, serial."""

from __future__ import annotations

import os
import socket
import threading
import time

import pytest

from calflow.gcs import (
    GCSConnectionLost,
    GCSController,
    GCSControllerError,
    GCSError,
    GCSInvalidAxisError,
    GCSMotionNotAllowedError,
    GCSMotionTimeout,
    GCSPositionOutOfLimitsError,
    GCSProtocolError,
    GCSStoppedError,
    GCSTimeout,
    GCSUnknownCommandError,
    GCSVelocityOutOfLimitsError,
)
from calflow.gcs.emulation.emulator import GCSEmulator

AXES = {
    "1": {"tmn": -7.5, "tmx": 7.5, "start_position": 1.0},
    "2": {"tmn": 0.0, "tmx": 25.0, "ref_position": 12.5, "start_position": 12.0},
}


@pytest.fixture
def emu():
    with GCSEmulator(axes=AXES, time_scale=10.0) as e:
        yield e


@pytest.fixture
def ctl(emu):
    with GCSController.connect_tcp(*emu.address, timeout=1.0) as c:
        yield c


@pytest.fixture
def ready(ctl):
    ctl.servo_on(["1", "2"])
    ctl.reference(["1", "2"], timeout=5)
    return ctl


def test_identification_and_axes(ctl):
    assert "C-863" in ctl.idn()
    assert ctl.syntax_version() == "2.0"
    assert ctl.axes() == ["1", "2"]
    assert "MOV" in ctl.help() and ctl.help().count("\n") > 5
    assert ctl.limits("2") == {"2": (0.0, 25.0)}


def test_servo_reference_move_on_target(ctl):
    assert ctl.servo_state() == {"1": False, "2": False}
    ctl.servo_on("1")
    assert ctl.servo_state() == {"1": True, "2": False}
    assert ctl.is_referenced() == {"1": False, "2": False}
    ctl.reference("1", timeout=5)
    assert ctl.is_referenced("1") == {"1": True} and ctl.position("1") == {"1": 0.0}
    ctl.move({"1": 4.0})
    assert ctl.on_target("1") == {"1": False}  # ONT? 0 while moving ...
    assert ctl.moving() == {"1": True, "2": False} and ctl.motion_status() == 1
    mid = ctl.position("1")["1"]
    assert 0.0 <= mid < 4.0
    final = ctl.wait_on_target(timeout=3, poll=0.01)
    assert ctl.on_target("1") == {"1": True}  # ... and 1 after
    assert final == {"1": 4.0, "2": 12.0}
    assert ctl.target("1") == {"1": 4.0} and ctl.motion_status() == 0


def test_reference_waits_for_ready(ctl):
    ctl.servo_on("2")
    t0 = time.monotonic()
    ctl.reference("2", timeout=5, poll=0.01)
    assert time.monotonic() - t0 >= 0.03  # 0.5 mm + 0.3 s search, time_scale 10
    assert ctl.ready() and ctl.position("2") == {"2": 12.5}


def test_move_without_servo_raises_code_5_naming_axis_and_command(ctl):
    with pytest.raises(GCSMotionNotAllowedError) as info:
        ctl.move({"1": 12.5 / 5})
    exc = info.value
    assert exc.code == 5 and exc.axis == "1" and exc.command == "MOV 1 2.5"
    assert "servo off or axis not referenced" in str(exc) and "'MOV 1 2.5'" in str(exc)


def test_move_unreferenced_raises_code_5(ctl):
    ctl.servo_on("1")
    with pytest.raises(GCSMotionNotAllowedError):
        ctl.move({"1": 1.0})


def test_multi_axis_errors_blame_the_right_axis(ready):
    ready.servo_off("2")
    with pytest.raises(GCSMotionNotAllowedError) as info:
        ready.move({"1": 1.0, "2": 3.0})
    assert info.value.axis == "2" and ready.target() == {"1": 0.0, "2": 12.5}
    ready.servo_on("2")
    with pytest.raises(GCSPositionOutOfLimitsError) as info:
        ready.move({"1": 1.0, "2": -3.0})
    assert info.value.axis == "2" and info.value.code == 7


def test_out_of_limits_raises_code_7_and_does_not_move(ready):
    with pytest.raises(GCSPositionOutOfLimitsError) as info:
        ready.move({"1": 8.0})
    assert info.value.code == 7 and info.value.axis == "1"
    time.sleep(0.05)
    assert ready.position("1") == {"1": 0.0} and ready.on_target("1") == {"1": True}
    assert ready.error_code() == 0  # the client consumed the error


def test_invalid_axis_and_unknown_command(ctl):
    with pytest.raises(GCSInvalidAxisError) as info:
        ctl.servo_on("9")
    assert info.value.code == 15 and info.value.axis == "9"
    with pytest.raises(GCSInvalidAxisError):  # checked locally: no timeout, link in sync
        ctl.position("9")
    with pytest.raises(GCSUnknownCommandError) as info:
        ctl.command("XYZ", "1")
    assert info.value.code == 2 and info.value.command == "XYZ 1"
    with pytest.raises(ValueError):
        ctl.move({"1 2": 1.0})
    assert ctl.idn()


def test_velocity_roundtrip_and_limit(ctl):
    ctl.set_velocity({"1": 0.5})
    assert ctl.velocity("1") == {"1": 0.5}
    with pytest.raises(GCSVelocityOutOfLimitsError):
        ctl.set_velocity({"1": 99})
    assert ctl.velocity() == {"1": 0.5, "2": 1.5}


def test_stop_all_during_motion(ready):
    ready.move({"1": 7.0})
    time.sleep(0.05)
    assert ready.stop_all() == 10  # ERR? answers 10 after #24
    assert ready.motion_status() == 0
    p1 = ready.position("1")["1"]
    time.sleep(0.1)
    assert ready.position("1")["1"] == p1 and 0.0 < p1 < 7.0
    assert ready.on_target("1") == {"1": True} and ready.error_code() == 0
    ready.move({"1": 1.0})  # the error was consumed: the next move is fine
    assert ready.stop() == 10  # STP behaves the same


def test_wait_on_target_sees_stop_from_another_thread(ready):
    ready.move({"1": 7.0})
    timer = threading.Timer(0.1, ready.stop_all)
    timer.start()
    with pytest.raises(GCSStoppedError) as info:
        ready.wait_on_target(timeout=5, poll=0.01)
    timer.join()
    assert info.value.code == 10


def test_wait_on_target_sees_stop_from_another_connection(ready, emu):
    ready.move({"1": -7.0})
    with socket.create_connection(emu.address, timeout=1) as other:  # e.g. another tool
        timer = threading.Timer(0.1, other.sendall, args=(b"\x18",))
        timer.start()
        with pytest.raises(GCSStoppedError) as info:
            ready.wait_on_target(timeout=5, poll=0.01)
        timer.join()
    assert info.value.code == 10 and ready.position("1")["1"] > -7.0


def test_wait_on_target_motion_timeout(ready):
    ready.set_velocity({"1": 0.1})
    ready.move({"1": 7.0})
    t0 = time.monotonic()
    with pytest.raises(GCSMotionTimeout):
        ready.wait_on_target(timeout=0.2, poll=0.02)
    assert time.monotonic() - t0 < 1.0
    assert ready.idn()  # a motion timeout leaves the link usable


def test_read_timeout_raises_within_limit_then_reconnect(ctl, emu):
    emu.faults.delay = 2.0
    t0 = time.monotonic()
    with pytest.raises(GCSTimeout) as info:
        ctl.position()
    elapsed = time.monotonic() - t0
    assert 0.95 <= elapsed < 1.4 and info.value.command == "POS?"
    with pytest.raises(GCSConnectionLost, match="out of sync"):
        ctl.position()  # a late reply could be mistaken for the next one
    emu.faults.delay = 0.0
    assert ctl.reconnect(max_tries=3, backoff=0.01) == 1
    assert ctl.position() == {"1": 1.0, "2": 12.0}


def test_dropped_connection_then_reconnect_restores_service(ready, emu):
    ready.move({"1": 2.0})
    emu.drop_connections()
    with pytest.raises(GCSConnectionLost):
        ready.position()
    with pytest.raises(GCSConnectionLost):
        ready.position()  # still down until reconnect()
    assert ready.reconnect(max_tries=3, backoff=0.05) == 1
    assert ready.servo_state() == {"1": True, "2": True}  # controller state survived
    assert ready.wait_on_target(timeout=3, poll=0.01)["1"] == 2.0


def test_drop_after_n_commands_raises_connection_lost(ctl, emu):
    emu.faults.drop_after = 1
    ctl.idn()
    with pytest.raises(GCSConnectionLost):
        ctl.idn()


def test_reconnect_backs_off_exponentially(ctl, emu):
    ctl.idn()  # make sure the first connection was accepted before refusing new ones
    emu.faults.refuse = 2
    emu.drop_connections()
    t0 = time.monotonic()
    assert ctl.reconnect(max_tries=5, backoff=0.1) == 3
    assert time.monotonic() - t0 >= 0.1 + 0.2 - 0.02
    assert ctl.axes() == ["1", "2"]


def test_reconnect_gives_up(emu):
    c = GCSController.connect_tcp(*emu.address, timeout=0.5)
    emu.stop()
    t0 = time.monotonic()
    with pytest.raises(GCSConnectionLost, match="after 3 tries"):
        c.reconnect(max_tries=3, backoff=0.05)
    assert 0.05 + 0.1 - 0.02 <= time.monotonic() - t0 < 3
    with pytest.raises(GCSConnectionLost):
        c.idn()
    c.close()


def test_connect_to_nothing_raises_connection_lost():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]  # bound but not listening: connection refused
        with pytest.raises(GCSConnectionLost):
            GCSController.connect_tcp("127.0.0.1", port, timeout=0.5)


def test_garbage_reply_raises_protocol_error(ctl, emu):
    emu.faults.garbage = 1
    with pytest.raises(GCSProtocolError):
        ctl.position()
    assert ctl.position() == {"1": 1.0, "2": 12.0}  # the reply was complete: still in sync
    emu.faults.garbage = 1
    with pytest.raises(GCSProtocolError):
        ctl.servo_on("1")  # garbage instead of the ERR? answer


def test_address_prefixed_replies_are_understood():
    with (
        GCSEmulator(axes="1,2", address_prefix=1) as e,
        GCSController.connect_tcp(*e.address, timeout=1) as c,
    ):
        assert c.on_target() == {"1": True, "2": True}
        assert c.error_code() == 0 and c.ready() and "C-863" in c.idn()


def test_closed_controller_raises(emu):
    with GCSController.connect_tcp(*emu.address, timeout=1) as c:
        c.idn()
    with pytest.raises(GCSConnectionLost, match="not connected"):
        c.idn()


def test_errors_are_gcs_errors():
    assert issubclass(GCSTimeout, GCSError) and issubclass(GCSTimeout, TimeoutError)
    assert issubclass(GCSConnectionLost, ConnectionError)
    assert issubclass(GCSMotionNotAllowedError, GCSControllerError)


# ------------------------------------------------------------------ serial transport
def _need_pyserial() -> None:
    pytest.importorskip("serial", reason="pyserial not installed (optional extra)")


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a pseudo-terminal")
def test_serial_transport_over_pty(emu):
    _need_pyserial()
    path = emu.serve_pty()
    with GCSController.connect_serial(path, baudrate=115200, timeout=1.0) as c:
        assert "C-863" in c.idn() and c.axes() == ["1", "2"]
        c.servo_on("1")
        c.reference("1", timeout=5)
        c.move({"1": 1.5})
        assert c.wait_on_target(timeout=3, poll=0.01)["1"] == 1.5
        with pytest.raises(GCSPositionOutOfLimitsError):
            c.move({"1": -9})
        emu.faults.delay = 2.0
        t0 = time.monotonic()
        with pytest.raises(GCSTimeout):
            c.position()
        assert time.monotonic() - t0 < 1.5


def test_serial_loopback_url_times_out_on_silence():
    _need_pyserial()
    c = GCSController.connect_serial("loop://", timeout=0.2)
    c._transport.write(b"1=1 \n2=0\n")  # loop:// echoes: the framer sees a 2-line reply
    assert c._read_reply("ONT?") == ["1=1", "2=0"]
    t0 = time.monotonic()
    with pytest.raises(GCSTimeout):
        c._read_reply("ONT?")
    assert time.monotonic() - t0 < 0.6
    c.close()
