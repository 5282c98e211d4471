"""The E-727-class piezo controller emulation and a nano campaign through it.

Controller semantics with a fake clock (no sockets); the nano runs go over TCP on
127.0.0.1 with a large ``time_scale``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import SMALL_NANO1D, SMALL_NANO2D

from calflow.acquisition.runner import acquire
from calflow.data.runs import RunMetadata
from calflow.gcs.emulation.datarecorder import parse_array
from calflow.gcs.emulation.piezo import PiezoAxisConfig, PiezoController, piezo_emulator
from calflow.gcs.rig import gcs
from calflow.gcs.wire.client import GCSController
from calflow.gcs.wire.protocol import ReplyFramer
from calflow.nano.plans import sequences as plans
from calflow.nano.stage.emulate import emulated_rig_options
from calflow.nano.stage.rig import nano1d


def _controller(**axis):
    c = PiezoController({"1": PiezoAxisConfig(**axis), "2": PiezoAxisConfig(tmx=80.0)}, seed=1)
    clock = {"now": 0.0}
    c.now = lambda: clock["now"]
    return c, clock


def _ok(c, line):
    assert c.handle(line) is None and c.handle("ERR?") == ["0"], line


def test_piezo_axes_are_closed_loop_um_with_a_first_order_step_and_no_referencing():
    c, clock = _controller(
        servo_tau=0.01, settle_window=0.02, settle_time=0.05, sensor_noise=0.0, sensor_resolution=0.0
    )
    assert c.handle("FRF?") == ["1=1", "2=1"] and c.handle("TMX? 2") == ["2=80.000000"]
    assert "E-727" in c.handle("*IDN?")[0]
    _ok(c, "SVO 1 1")
    _ok(c, "MOV 1 50")
    clock["now"] = 0.01  # one time constant: 1 - 1/e of the step
    assert float(c.handle("POS? 1")[0][2:]) == pytest.approx(50 * (1 - math.exp(-1)), abs=1e-6)
    entry = 0.01 * math.log(50 / 0.02)  # |50 exp(-t/tau)| = window
    for t, on in ((entry - 1e-4, "0"), (entry + 0.049, "0"), (entry + 0.0501, "1")):
        clock["now"] = t
        assert c.handle("ONT? 1") == [f"1={on}"], t
    assert c.handle("SPA? 1 0x07000900 1 0x07000901") == ["1 0x07000900=0.02", "1 0x07000901=0.05"]
    _ok(c, "SPA 2 0x07000901 0.5")
    assert c.axes["2"].settle_time == 0.5
    assert c.handle("MOV 1 200") is None and c.handle("ERR?") == ["7"]  # beyond TMX


def test_pos_is_the_capacitive_sensor_noise_and_resolution():
    c, clock = _controller(sensor_noise=0.001, sensor_resolution=0.0005)
    _ok(c, "SVO 1 1")
    _ok(c, "MOV 1 10")
    clock["now"] = 1.0
    values = np.array([float(c.handle("POS? 1")[0][2:]) for _ in range(400)])
    assert np.allclose(values / 0.0005, np.round(values / 0.0005))  # quantised
    assert 0.0007 < values.std() < 0.0013 and abs(values.mean() - 10) < 0.0003


def test_data_recorder_records_target_and_position_from_the_trigger():
    c, clock = _controller(servo_tau=0.01, sensor_noise=0.0, sensor_resolution=0.0)
    _ok(c, "SVO 1 1")
    _ok(c, "DRC 1 1 2 2 1 1")
    assert c.handle("DRC? 1 2") == ["1=1 2", "2=1 1"]
    _ok(c, "RTR 100")  # 100 servo cycles of 50 us: 5 ms per point
    _ok(c, "DRT 0 1 0")  # start with the next MOV
    clock["now"] = 0.5
    assert c.handle("DRL? 1") == ["1=0"]
    _ok(c, "MOV 1 40")
    clock["now"] = 0.5 + 0.0451
    assert c.handle("DRL? 1 2") == ["1=10", "2=10"]
    header, data = parse_array(c.handle("DRR? 1 10 1 2"))
    assert header["DIM"] == "2" and float(header["SAMPLE_TIME"]) == pytest.approx(0.005)
    assert header["NAME0"] == "Current Position of axis 1"
    t = 0.005 * np.arange(10)
    assert np.allclose(data[:, 0], 40 * (1 - np.exp(-t / 0.01)), atol=1e-6)
    assert np.all(data[:, 1] == 40.0)
    _, part = parse_array(c.handle("DRR? 4 3 1"))
    assert np.allclose(part[:, 0], data[3:6, 0])
    for line, code in (
        ("DRC 9 1 2", "57"),
        ("DRC 1 1 7", "58"),
        ("DRC 1 Z 2", "59"),
        ("DRT 0 9 0", "17"),
        ("RTR 0", "17"),
        ("DRC 1 1", "1"),
    ):
        assert c.handle(line) is None and c.handle("ERR?") == [code], line
    assert c.handle("DRR? 5 99 1") is None and c.handle("ERR?") == ["17"]  # not recorded yet
    assert c.handle("DRC? 1") == ["1=1 2"]  # failed lines changed nothing


def test_drr_reply_is_a_gcs_array_as_pipython_frames_it():
    """Header lines ``# KEY = VALUE`` up to ``# END_HEADER``, data lines of DIM columns,
    every line but the last ending with "SP LF" (pipython reads to ``# END_HEADER``, then
    the rows until a LF without a space)."""
    emu = piezo_emulator({"1": {}}, time_scale=1.0).start()
    try:
        with GCSController.connect_tcp(*emu.address, timeout=2.0) as ctl:
            ctl.servo_on("1")
            ctl.configure_recorder({1: ("1", 2), 2: ("1", 1)}, rate=20)
            ctl.arm_recorder(2)
            ctl.move({"1": 5.0})
            ctl.wait_on_target(timeout=2.0, poll=0.002)
            n = ctl.recorded_points(1)
            assert n > 5
            header, data = ctl.read_recorder([1, 2], 1, 5)
            assert data.shape == (5, 2) and header["NDATA"] == "5"
            ctl._send(b"DRR? 1 3 1\n")  # the raw bytes of the same reply
            raw = b""
            while not raw.endswith(b"\n") or raw.endswith(b" \n"):
                raw += ctl._transport.read(1.0)
    finally:
        emu.stop()
    text = raw.decode("latin-1")
    head, _, rows = text.partition("# END_HEADER \n")
    assert head.startswith("# REM ") and "# SAMPLE_TIME = 0.001 \n" in head
    assert rows.count(" \n") == 2 and rows.endswith("\n") and len(rows.split("\n")) == 4
    framer = ReplyFramer()
    framer.feed(raw)
    assert parse_array(framer.pop())[1].shape == (3, 1)


META = RunMetadata(
    campaign="gcs-nano", robot="stage1d", source="gcs", plan="training", config_sha256="0" * 64
)


def _by_pose(ds):
    """Mean and standard error of meas_x - cmd_x per (pose, direction) over the cycles."""
    err = ds["meas_x"].values - ds["cmd_x"].values
    keys = sorted(set(zip(ds["pose"].values, ds["direction"].values)))
    sel = [(ds["pose"].values == p) & (ds["direction"].values == d) for p, d in keys]
    return (
        np.array([err[m].mean() for m in sel]),
        np.array([err[m].std(ddof=1) / math.sqrt(m.sum()) for m in sel]),
    )


def _through_emulator_and_simulated(plan, runner, seed):
    """``plan`` run by ``runner`` with the gcs rig through the E-727-class emulator of
    SMALL_NANO1D's stage and on the simulated rig: same world (seed 3), other noise."""
    emu, options = emulated_rig_options(SMALL_NANO1D, time_scale=1000.0)
    try:
        options["sensor"]["options"].update(seed=seed, world_seed=3)
        rig = gcs(**options)
        ds = runner(plan, rig, META)
        rig.close()
    finally:
        emu.stop()
    return ds, runner(plan, nano1d(profile="lab5day", seed=seed + 1, world_seed=3), META)


def test_a_small_nano1d_training_through_the_emulator_agrees_with_the_simulated_rig():
    plan = plans.training_1d(np.arange(0.0, 481.0, 80.0), 4, 10.0, 5.0, 0.0)
    ds, sim = _through_emulator_and_simulated(plan, acquire, 11)
    assert ds.sizes["sample"] == len(plan) and np.array_equal(ds["cmd_x"].values, plan.commands["x"])
    m_gcs, se_gcs = _by_pose(ds)
    m_sim, se_sim = _by_pose(sim)
    # the stage's error curve (~380 nm over the stroke) is the same within the noise
    assert np.ptp(m_sim) > 0.1
    assert np.all(np.abs(m_gcs - m_sim) < 4 * np.hypot(se_gcs, se_sim) + 0.005), m_gcs - m_sim
    assert np.allclose(ds["temperature"].values, sim["temperature"].values, atol=0.05)


def test_nano2d_stage_reads_both_interferometer_axes_through_the_emulator():
    emu, options = emulated_rig_options(SMALL_NANO2D, time_scale=1000.0)
    try:
        rig = gcs(**options)
        assert rig.joints == ("x", "y") and rig.sensors == ("meas_x", "meas_y")
        rig.move({"x": 40.0, "y": 20.0})
        chunk = next(rig.stream(3.0))
        r = rig.read()
        rig.close()
    finally:
        emu.stop()
    assert chunk["time"].size == 30 and np.all(np.diff(chunk["time"]) > 0)
    assert abs(np.mean(chunk["meas_x"]) - 40.0) < 2.0 and abs(r["meas_y"] - 20.0) < 2.0


def test_nano_emulate_main_prints_a_rig_section_the_config_check_accepts(capsys, tmp_path):
    import yaml

    from calflow.configuration.campaign import load as load_campaign
    from calflow.nano.stage.emulate import EMULATOR

    path = tmp_path / "small.yaml"
    path.write_text(yaml.safe_dump(SMALL_NANO1D))
    assert (
        EMULATOR.main(["--campaign", str(path), "--port", "0", "--duration", "0.2", "--time-scale", "500"])
        == 0
    )
    rig = yaml.safe_load(capsys.readouterr().out.split("campaign rig section for it:\n", 1)[1])["rig"]
    assert rig["options"]["axes"] == {"x": "1"} and rig["options"]["time_scale"] == 500
    assert rig["runs"]["metrology"]["sensor"]["options"]["profile"] == "metrology"  # the run override
    campaign = {**SMALL_NANO1D, "rig": rig}
    path.write_text(yaml.safe_dump(campaign))
    assert load_campaign(path, [])["rig"]["factory"] == "gcs"


def test_a_second_order_axis_follows_the_closed_loop_step_and_ont_waits_for_its_envelope():
    from calflow.nano.stage.piezo import closed_loop_step

    c, clock = _controller(
        natural_hz=100.0,
        damping=0.7,
        settle_window=0.01,
        settle_time=0.0,
        sensor_noise=0.0,
        sensor_resolution=0.0,
    )
    _ok(c, "SVO 1 1")
    _ok(c, "MOV 1 20")
    t = np.linspace(0.0, 0.03, 61)
    assert np.allclose(c.axes["1"].positions_at(t), 20 * closed_loop_step(t, 100.0, 0.7), atol=1e-9)
    peak = c.axes["1"].positions_at(t).max()
    assert peak - 20 == pytest.approx(20 * math.exp(-math.pi * 0.7 / math.sqrt(1 - 0.49)), rel=0.02)
    entry = c.axes["1"].window_entry()
    late = np.linspace(entry, entry + 0.05, 200)
    assert np.all(np.abs(c.axes["1"].positions_at(late) - 20) <= 0.01)  # inside for good
    clock["now"] = entry - 1e-4
    assert c.handle("ONT? 1") == ["1=0"]
    clock["now"] = entry + 1e-6
    assert c.handle("ONT? 1") == ["1=1"]


def test_record_move_records_the_step_from_the_move_through_the_data_recorder():
    """``record_move`` through the E-727-class emulator: DRC (current position), RTR for the
    rate, DRT on the next target change, MOV, DRR?; the interferometer's record of the
    step and the controller's agree, point 0 at the move's start."""
    emu, options = emulated_rig_options(SMALL_NANO1D, time_scale=1000.0)
    try:
        options["sensor"]["options"].update(seed=11, world_seed=3)
        rig = gcs(**options)
        rig.move({"x": 100.0})
        chunks = list(rig.record_move({"x": 110.0}, 0.04, 1000.0, chunk=16))
        recorder = emu.controller.recorder
        assert recorder.rate == 20 and recorder.trigger == 1  # 1 kHz of 50 us cycles, on MOV
        assert recorder.config == {1: ("1", 2)}
        rig.close()
    finally:
        emu.stop()
    rec = {k: np.concatenate([c[k] for c in chunks]) for k in chunks[0]}
    assert [c["time"].size for c in chunks] == [16, 16, 8]
    assert np.allclose(np.diff(rec["time"]), 1e-3)
    for name in ("pos_x", "meas_x"):  # the step seen by both sensors, from its start
        r = rec[name] - rec[name][-10:].mean()
        assert abs(r[0] + 10) < 0.1 and abs(r[-1]) < 0.05, name
        assert 0.2 < r.max() < 0.8, name  # the loop's ~4.6 % overshoot of the 10 um step
    assert np.abs(np.diff(rec["meas_x"] - rec["pos_x"])).max() < 0.05  # same motion, the stage's error apart
    assert set(rec) >= {"T1", "T4", "meas_y"}


def test_record_move_needs_a_sensor_that_can_be_read_along_the_move():
    from calflow.errors import RigError

    class ReadOnly:  # a sensor plug-in with the required interface only
        def __init__(self, inner):
            self.sensors, self.thermometers, self.read = inner.sensors, inner.thermometers, inner.read

    emu, options = emulated_rig_options(SMALL_NANO1D, time_scale=1000.0)
    try:
        rig = gcs(**options)
        rig.sensor = ReadOnly(rig.sensor)
        with pytest.raises(RigError, match="cannot be read along a move"):
            rig.record_move({"x": 10.0}, 0.01, 1000.0)
        rig.close()
    finally:
        emu.stop()


def test_step_response_run_through_the_emulator_gives_the_simulated_rigs_settling_and_overshoot():
    """ISO 9283 7.5/7.6 from the recorded moves of a step-response run, gcs rig through the
    E-727-class emulator vs the simulated rig (same world, other noise), in one band."""
    from calflow.acquisition.recorded_moves import acquire_recorded_moves
    from calflow.nano.report.stabilisation import stabilisation_entries

    plan = plans.step_response([1.0, 10.0, 50.0], 3, [100.0], 0.05, 1000.0, 0.01)
    ds, sim = _through_emulator_and_simulated(plan, acquire_recorded_moves, 21)
    entries = []
    for run in (ds, sim):
        run.attrs["band_nm"] = 50.0
        stab, over = stabilisation_entries(run)
        entries.append((stab["per_step"], over["per_step"]))
    assert ds.sizes["record"] == 50 and np.allclose(ds["record_time"].values[:, 0], 0.0)
    noise_nm = 3.0  # interferometer noise (1 sigma per point), the option's default
    for a, b in zip(entries[0][0], entries[1][0]):
        assert a["step_um"] == b["step_um"] and a["stabilised"] == b["stabilised"] == 3
        assert abs(a["stabilisation_time_s"] - b["stabilisation_time_s"]) <= 2e-3, (
            a,
            b,
        )  # two record periods
        assert abs(a["overshoot_nm"] - b["overshoot_nm"]) < 5 * noise_nm * math.sqrt(2), (a, b)
        if abs(a["step_um"]) >= 10:  # the loop's ~4.6 % overshoot (a 1 um step's stays in the band)
            assert a["overshoot_nm"] > 0.04 * abs(a["step_um"]) * 1e3


def test_calflow_emulate_gcs_serves_a_nano_campaign_with_the_piezo_controller(capsys, tmp_path):
    import yaml

    from calflow.cli import main

    path = tmp_path / "small2d.yaml"
    path.write_text(yaml.safe_dump(SMALL_NANO2D))
    assert main(["emulate", "gcs", "--campaign", str(path), "--port", "0", "--duration", "0.2"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("E-727-class emulator of campaign") and "(axes 1, 2, um;" in out
    rig = yaml.safe_load(out.split("campaign rig section for it:\n", 1)[1])["rig"]
    assert rig["options"]["axes"] == {"x": "1", "y": "2"}
    assert rig["options"]["sensor"]["factory"] == "simulated_interferometer"


def test_calflow_emulate_gcs_refuses_a_family_without_an_emulator_in_one_line(capsys, tmp_path, monkeypatch):
    import dataclasses

    import yaml

    import calflow.family
    from calflow.cli import main

    path = tmp_path / "small.yaml"
    path.write_text(yaml.safe_dump(SMALL_NANO1D))
    real = calflow.family.family_of
    monkeypatch.setattr(
        calflow.family, "family_of", lambda robot: dataclasses.replace(real(robot), emulator=None)
    )
    assert main(["emulate", "gcs", "--campaign", str(path), "--port", "0", "--duration", "0.1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "small.yaml: robot 'stage1d' (family nano) has no controller emulator" in err[0]
