"""The ``gcs`` rig against the GCS emulator of a campaign: science, faults, resume.

Servers bind to 127.0.0.1 only; ``time_scale`` keeps the runs short.
"""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import ROOT, SMALL_XYTHETA, XY_NOISE_UM

from calflow.acquisition.checkpoint import Journal, plan_digest
from calflow.acquisition.runner import acquire
from calflow.configuration.campaign import load as load_campaign
from calflow.data.io import open_dataset
from calflow.data.runs import RunMetadata
from calflow.errors import RigError
from calflow.gcs import GCSController
from calflow.gcs.emulation.emulator import GCSEmulator
from calflow.gcs.rig import gcs
from calflow.plan import Plan
from calflow.xytheta.models import cost
from calflow.xytheta.models.identification import identify
from calflow.xytheta.models.kinematics import Parameters
from calflow.xytheta.plans import poses as plans
from calflow.xytheta.stage.emulate import EMULATOR, emulated_rig_options
from calflow.xytheta.stage.rig import simulated_xytheta

META = RunMetadata(
    campaign="gcs-test", robot="xytheta", source="gcs", plan="identification", config_sha256="0" * 64
)
PLAN = plans.identification(40, seed=7, dwell_s=0.5)


@pytest.fixture
def emulated():
    emu, options = emulated_rig_options(SMALL_XYTHETA, time_scale=100.0, timeout=0.5)
    try:
        yield emu, options
    finally:
        emu.stop()


def _acquire(rig, plan=PLAN, journal=None, at=None):
    """Acquire ``plan``; ``at = {done: action}`` injects faults after ``done`` samples."""
    at = at or {}

    def progress(done, total):
        if done in at:
            at[done]()

    try:
        return acquire(plan, rig, META, journal, progress)
    finally:
        rig.close()


def _check_intact(ds, plan=PLAN):
    """Every row of the plan once, in order: nothing lost, nothing duplicated."""
    assert ds.sizes["sample"] == len(plan)
    assert np.array_equal(ds["pose"].values, plan.pose)
    for joint, values in plan.commands.items():
        assert np.array_equal(ds[f"cmd_{joint}"].values, values)
    assert np.all(np.diff(ds["time"].values) > 0)


def _identify(ds):
    theta = ds["meas_theta"].values - ds["meas_theta"].values[0]
    P_mx, P_my = cost.measured_points(ds["meas_x"].values, ds["meas_y"].values, theta)
    return identify(
        ds["cmd_x"].values,
        ds["cmd_y"].values,
        theta,
        P_mx,
        P_my,
        free=("x_R", "y_R", "alpha", "beta"),
        initial=Parameters(x_R=10000.0, y_R=8000.0, alpha=180.0, beta=0.0),
    )


# --------------------------------------------------------------------------- science
def test_identification_through_the_emulator_agrees_with_the_simulated_rig(emulated):
    emu, options = emulated
    start = time.monotonic()
    ds = _acquire(gcs(**options))
    assert time.monotonic() - start < 30
    _check_intact(ds)
    sim = _acquire(simulated_xytheta(seed=7, stream="identification"))
    # same physics, same commands: readings differ by noise (sensor and stage repeatability)
    for name in ("meas_x", "meas_y"):
        a, b = ds[name].values, sim[name].values
        assert np.array_equal(np.isnan(a), np.isnan(b))
        assert np.nanmedian(np.abs(a - b)) < 1.5 * XY_NOISE_UM, name
        assert np.nanmax(np.abs(a - b)) < 10 * XY_NOISE_UM, name
    assert np.max(np.abs(ds["meas_theta"].values - sim["meas_theta"].values)) < 0.01
    r_gcs, r_sim = _identify(ds), _identify(sim)
    assert r_gcs.success and r_sim.success
    for name in ("x_R", "y_R", "alpha", "beta"):
        a, b = getattr(r_gcs.parameters, name), getattr(r_sim.parameters, name)
        sigma = np.hypot(r_gcs.std[name], r_sim.std[name])
        assert abs(a - b) <= 3 * sigma, (name, a, b, sigma)
    # Model II leaves the Θ-dependent errors unmodelled: near the truth, not at it (Sec. 4.5.5)
    assert abs(r_gcs.parameters.x_R - 9572.9) < 300 and abs(r_gcs.parameters.alpha - 177.69) < 0.1


# --------------------------------------------------------------------------- faults
def test_dropped_connections_mid_run_lose_and_duplicate_nothing(emulated):
    emu, options = emulated
    rig = gcs(**options)

    def drop_after(n):
        return lambda: setattr(emu.faults, "drop_after", n)

    # drops land on different commands of a sample: MOV, its ERR?, ONT? polls, POS?
    at = {3: drop_after(0), 9: drop_after(1), 15: drop_after(3), 22: drop_after(6), 30: emu.drop_connections}
    ds = _acquire(rig, at=at)
    _check_intact(ds)
    assert rig.recoveries >= len(at)
    assert np.isfinite(ds["meas_theta"].values).all()


def test_delayed_replies_time_out_and_are_recovered_by_reconnecting(emulated):
    emu, options = emulated
    options = {**options, "timeout": 0.15, "reconnect": {"tries": 6, "backoff_s": 0.05}}
    rig = gcs(**options)

    def slow_controller():
        emu.faults.delay = 0.4  # beyond the timeout, for a while
        threading.Timer(0.5, lambda: setattr(emu.faults, "delay", 0.0)).start()

    ds = _acquire(rig, at={5: slow_controller})
    _check_intact(ds)
    assert rig.recoveries >= 1


def test_garbage_replies_are_recovered_by_reconnecting(emulated):
    emu, options = emulated
    rig = gcs(**options)
    ds = _acquire(
        rig, at={4: lambda: setattr(emu.faults, "garbage", 2), 20: lambda: setattr(emu.faults, "garbage", 1)}
    )
    _check_intact(ds)
    assert rig.recoveries >= 2


def test_persistent_garbage_fails_with_a_clear_message_and_keeps_the_journal(emulated, tmp_path):
    emu, options = emulated
    rig = gcs(**{**options, "reconnect": {"tries": 2, "backoff_s": 0.01}})
    journal = Journal(tmp_path / "run.nc.journal", plan_digest(PLAN))
    with pytest.raises(RigError) as err:
        _acquire(rig, journal=journal, at={4: lambda: setattr(emu.faults, "garbage", 10**6)})
    message = str(err.value)
    assert "tcp://127.0.0.1" in message and "garbage" in message
    assert "reconnect" in message or "giving up" in message
    assert len(journal.load()) == 4


def test_move_out_of_limits_stops_all_axes_and_names_axis_command_and_code(emulated, tmp_path):
    emu, options = emulated
    seen: list[str] = []
    handle = emu.controller.handle
    emu.controller.handle = lambda line: (seen.append(line), handle(line))[1]
    q = {j: v.copy() for j, v in PLAN.commands.items()}
    q["theta"][6] = 45.0  # the Θ stage travels +-30 degrees
    plan = Plan("identification", q, PLAN.pose, PLAN.cycle, PLAN.direction, dwell_s=0.5)
    journal = Journal(tmp_path / "run.nc.journal", plan_digest(plan))
    with pytest.raises(RigError) as err:
        _acquire(gcs(**options), plan, journal)
    message = str(err.value)
    assert "joint 'theta'" in message and "axis '3'" in message
    assert "MOV 1 " in message and " 3 45'" in message and "GCS error 7" in message
    assert "all axes stopped (#24)" in message
    assert "#24" in seen[seen.index(next(s for s in seen if s.endswith(" 3 45"))) :]
    assert len(journal.load()) == 6  # the samples already taken are kept


@pytest.mark.process  # the emulated controller moves in real time (4.7 s of travel)
def test_controller_error_stops_a_moving_axis():
    """#24 halts motion: an axis moving when another controller error occurs stops at once."""
    emu, options = emulated_rig_options(SMALL_XYTHETA, time_scale=1.0, timeout=1.0)
    try:
        rig = gcs(**{**options, "poll_s": 0.01})
        with GCSController.connect_tcp(*emu.address, timeout=1.0) as other:
            other.move({"1": 0.5})  # from the reference at 7.5 mm: 4.7 s of travel at 1.5 mm/s
            time.sleep(0.2)
            with pytest.raises(RigError, match=r"joint 'theta'.*GCS error 7"):
                rig.move({"x": 0.0, "y": 0.0, "theta": -40.0})
            x = emu.controller.axes["1"]
            now = emu.controller.now()
            assert not x.moving(now) and 0.5 < x.position(now) < 7.4
        rig.close()
    finally:
        emu.stop()


def test_servo_off_is_reported_with_the_joint_and_code_5(emulated):
    emu, options = emulated
    rig = gcs(**options)
    with GCSController.connect_tcp(*emu.address, timeout=1.0) as other:
        other.servo_off("2")
    with pytest.raises(RigError, match=r"joint 'y' \(axis '2'.*'MOV .*GCS error 5"):
        rig.move({"x": 100.0, "y": 100.0, "theta": 1.0})
    rig.close()


# --------------------------------------------------------------------------- options
class EchoSensor:
    """A sensor plug-in for tests: reads back the positions it is given."""

    sensors = ("meas_x", "meas_y")
    thermometers = ()

    def __init__(self, offset=0.0):
        self.offset = offset

    def read(self, positions, time_s):
        return {"meas_x": positions["x"] + self.offset, "meas_y": positions["y"] + self.offset}


def test_one_controller_per_joint_over_tcp_and_serial_and_a_plugin_sensor(monkeypatch):
    monkeypatch.setenv("CALFLOW_RIG_PLUGINS", "test_rigs_gcs")  # plug-in sensors are code: allowed
    a = GCSEmulator(axes={"1": {"tmn": 0, "tmx": 25}}, time_scale=100.0).start()
    b = GCSEmulator(axes={"A": {"needs_reference": False}}, time_scale=100.0).start()
    try:
        rig = gcs(
            axes={
                "x": {"axis": "1", "host": "127.0.0.1", "port": a.address[1]},
                "y": {"axis": "A", "serial": b.serve_pty()},
            },
            scale={"x": 1000.0},
            timeout=0.5,
            time_scale=100.0,
            poll_s=0.005,
            sensor={"factory": "test_rigs_gcs:EchoSensor", "options": {"offset": 0.5}},
            reconnect={"tries": 3, "backoff_s": 0.01},
        )
        assert rig.joints == ("x", "y") and len(rig.controllers) == 2
        rig.move({"x": 1500.0, "y": 2.0})
        assert rig.read()["meas_x"] == pytest.approx(1500.5)
        assert rig.read()["meas_y"] == pytest.approx(2.5)
        a.drop_connections()
        rig.move({"x": 1000.0, "y": -1.0})
        r = rig.read()
        assert (r["meas_x"], r["meas_y"]) == (pytest.approx(1000.5), pytest.approx(-0.5))
        assert rig.recoveries == 1
        rig.close()
    finally:
        a.stop()
        b.stop()


def test_bad_options_are_rig_errors(emulated):
    emu, options = emulated
    with pytest.raises(RigError, match="has no axis '9'"):
        gcs(**{**options, "axes": {"x": "1", "y": "9"}})
    with pytest.raises(RigError, match="option 'sensor' is required"):
        gcs(**{**options, "sensor": None})
    with pytest.raises(RigError, match="sensor.factory"):
        gcs(**{**options, "sensor": {"factory": "no such thing"}})
    emu.faults.refuse = 1
    with pytest.raises(RigError, match="cannot open controller|preparing controller"):
        gcs(**options)


def test_emulate_main_serves_and_prints_the_rig_section(capsys, tmp_path):
    path = tmp_path / "small.yaml"
    path.write_text(yaml.safe_dump(SMALL_XYTHETA))
    assert (
        EMULATOR.main(["--campaign", str(path), "--port", "0", "--duration", "0.2", "--time-scale", "50"])
        == 0
    )
    out = capsys.readouterr().out
    assert "127.0.0.1" in out
    rig = yaml.safe_load(out.split("campaign rig section for it:\n", 1)[1])["rig"]
    assert rig["options"]["axes"] == {"x": "1", "y": "2", "theta": "3"}
    assert rig["options"]["time_scale"] == 50 and rig["options"]["sensor"]["options"]["seed"] == 7


# --------------------------------------------------------------------------- resume
def _run_cli(campaign: Path, out: Path, kill_after: float | None = None) -> int:
    # toyrigs from tests/, before whatever calflow PYTHONPATH already names (a worktree's src)
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT / "tests"), os.environ.get("PYTHONPATH")])),
    }
    cmd = [
        sys.executable,
        "-m",
        "calflow",
        "acquire",
        "--campaign",
        str(campaign),
        "--plan",
        "identification",
        "--out",
        str(out),
    ]
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    if kill_after is None:
        proc.wait(timeout=120)
        return proc.returncode
    journal = Path(f"{out}.journal")
    deadline = time.monotonic() + 60
    while not journal.exists() and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.02)
    time.sleep(kill_after)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    return proc.returncode


@pytest.mark.process  # SIGKILLs a `calflow acquire` process
def test_killed_acquisition_continues_after_the_last_sample(tmp_path):
    c = yaml.safe_load(yaml.safe_dump(SMALL_XYTHETA))
    emu, options = emulated_rig_options(c, time_scale=20.0, timeout=1.0)
    try:
        c["rig"] = {"factory": "calflow.gcs.rig:gcs", "options": options}
        campaign = tmp_path / "gcs-resume.yaml"
        campaign.write_text(yaml.safe_dump(c))
        out = tmp_path / "killed.nc"
        assert _run_cli(campaign, out, kill_after=random.uniform(0.5, 1.5)) == -signal.SIGKILL
        assert not out.exists()
        done = len(Path(f"{out}.journal").read_text().splitlines()) - 1
        assert 0 < done < 61, "the kill landed mid-run"
        assert _run_cli(campaign, out) == 0
    finally:
        emu.stop()
    assert not Path(f"{out}.journal").exists()
    ds = open_dataset(out)
    ident = load_campaign(campaign)["identification"]  # with the schema's defaults
    plan = plans.identification(
        ident["poses"],
        ident["x_um"],
        ident["y_um"],
        ident["theta_deg"],
        seed=c["seed"],
        dwell_s=ident["dwell_s"],
    )
    _check_intact(ds, plan)
    assert ds.attrs["source"] in ("plugin", "gcs")
    # the continued run sees the same physics as an uninterrupted simulated one
    sim = acquire(plan, simulated_xytheta(seed=7, stream="identification"), META)
    for name in ("meas_x", "meas_y"):
        diff = np.abs(ds[name].values - sim[name].values)
        assert np.nanmax(diff) < 10 * XY_NOISE_UM, (name, done, np.nanargmax(diff), np.nanmax(diff))


def test_two_rigs_on_one_controller_take_turns(emulated):
    """A second acquisition on the same controller waits until the first rig is closed."""
    import threading

    emu, options = emulated
    first = gcs(**options)
    opened = threading.Event()

    def second():
        rig = gcs(**options)
        opened.set()
        rig.close()

    t = threading.Thread(target=second)
    t.start()
    assert not opened.wait(0.5), "the second rig opened while the first held the controller"
    first.close()
    assert opened.wait(10)
    t.join(10)
