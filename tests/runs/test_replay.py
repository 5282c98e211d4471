"""Replay of recorded runs: a replayed campaign reproduces its run datasets exactly."""

import json

import numpy as np
import pytest

from calflow.acquisition.runner import acquire
from calflow.data.io import open_dataset, write_dataset, write_json
from calflow.data.runs import RunMetadata
from calflow.data.validate import validate_dataset
from calflow.errors import RigError
from calflow.rigs.protocol import Rig
from calflow.rigs.replay import replay
from calflow.xytheta.models.kinematics import Parameters, inverse
from calflow.xytheta.plans import poses as plans
from calflow.xytheta.stage.rig import simulated_xytheta

SEED = 3


def meta(source, plan, model=None):
    return RunMetadata(
        campaign="rec", robot="xytheta", source=source, plan=plan, config_sha256="0" * 64, model=model
    )


def id_plan(seed=0):
    return plans.identification(25, seed=seed, dwell_s=0.5)


def val_plan(x_R=9572.9):
    p = Parameters(x_R, 7795.9, 177.69, -0.11)
    return plans.validation(lambda x, y, t: inverse(x, y, t, p), cycles=3, dwell_s=0.5)


@pytest.fixture
def recorded(tmp_path):
    """A recorded campaign: results/rec/runs/{identification,validation_I}.nc and truth/identification.json."""
    runs = tmp_path / "results" / "rec" / "runs"
    rig = simulated_xytheta(seed=SEED, stream="identification")
    ident = acquire(id_plan(), rig, meta("simulated", "identification"))
    write_dataset(ident, runs / "identification.nc")
    write_json(rig.truth(), tmp_path / "results" / "rec" / "truth" / "identification.json")
    # push part of the validation off the pattern so the recording holds NaN readings
    rig = simulated_xytheta(seed=SEED, stream="validation_I", camera_x_um=-1500.0)
    val = acquire(val_plan(), rig, meta("simulated", "validation", "I"))
    write_dataset(val, runs / "validation_I.nc")
    return {"runs": runs, "identification": ident, "validation_I": val}


def assert_same_run(a, b):
    assert set(a.variables) == set(b.variables)
    for name in a.variables:
        x, y = a[name], b[name]
        assert x.dims == y.dims, name
        if x.dtype.kind in "OUS":  # label coordinates: object in memory, <U on file
            assert [str(v) for v in x.values] == [str(v) for v in y.values], name
            continue
        assert x.dtype == y.dtype, name
        if x.dtype.kind == "f":
            assert np.array_equal(x.values, y.values, equal_nan=True), name
        else:
            assert np.array_equal(x.values, y.values), name
        assert x.attrs == y.attrs, name


def test_replay_reproduces_identification_and_validation_runs(recorded):
    runs = recorded["runs"]
    assert np.isnan(recorded["validation_I"]["meas_x"].values).any()  # NaN positions are tested
    assert np.isfinite(recorded["validation_I"]["meas_x"].values).any()
    for run_id, plan, m in (
        ("identification", id_plan(), meta("replay", "identification")),
        ("validation_I", val_plan(), meta("replay", "validation", "I")),
    ):
        rig = replay(str(runs), stream=run_id, seed=123)
        assert isinstance(rig, Rig)
        assert rig.joints == ("x", "y", "theta")
        assert rig.sensors == ("meas_x", "meas_y", "meas_theta")
        assert rig.thermometers == ("T1",)
        ds = acquire(plan, rig, m)
        assert rig.exhausted
        rig.close()
        assert validate_dataset(ds) == []
        assert ds.attrs["source"] == "replay"
        # compare with the file as recorded (what analysis reads) and as acquired in memory
        assert_same_run(ds, open_dataset(runs / f"{run_id}.nc", kind="run"))
        assert_same_run(
            open_dataset(write_dataset(ds, runs.parent / f"{run_id}.replayed.nc")),
            open_dataset(runs / f"{run_id}.nc"),
        )
        for name in ("meas_x", "meas_y", "temperature", "time"):
            assert np.array_equal(ds[name].values, recorded[run_id][name].values, equal_nan=True)


def test_replay_from_a_mapping_and_truth(recorded, tmp_path):
    runs = recorded["runs"]
    rig = replay({"identification": str(runs / "identification.nc")}, stream="identification")
    truth = json.loads((runs.parent / "truth" / "identification.json").read_text())
    assert rig.truth() == truth and truth["rig"] == "simulated_xytheta"
    assert replay(str(runs), stream="validation_I").truth() == {"available": False}
    lone = tmp_path / "elsewhere" / "v.nc"
    write_dataset(recorded["validation_I"], lone)
    assert replay({"v": str(lone)}).truth() == {"available": False}  # a single recording needs no stream


def test_replay_with_a_different_plan_names_sample_and_joint(recorded):
    rig = replay(str(recorded["runs"]), stream="identification")
    with pytest.raises(RigError) as err:
        acquire(id_plan(seed=1), rig, meta("replay", "identification"))
    msg = str(err.value)
    assert "identification.nc" in msg and "sample 1" in msg and "joint 'x'" in msg
    assert "recorded command" in msg and "requested" in msg and "\n" not in msg
    # a validation commanded through another model differs in x from the first target on
    rig = replay(str(recorded["runs"]), stream="validation_I")
    with pytest.raises(RigError, match=r"validation_I\.nc: sample 1: joint 'x': recorded command"):
        acquire(val_plan(x_R=9600.0), rig, meta("replay", "validation", "I"))


def test_tolerance_bounds_accepted_commands(recorded):
    ds = recorded["identification"]
    x1 = float(ds["cmd_x"].values[1])
    row = {j: float(ds[f"cmd_{j}"].values[1]) for j in ("x", "y", "theta")}
    rig = replay(str(recorded["runs"]), stream="identification", tolerance_um=0.01)
    rig.move({"x": 0.0, "y": 0.0, "theta": 0.0})
    rig.move({**row, "x": x1 + 0.005})
    assert rig.read()["meas_x"] == float(ds["meas_x"].values[1])
    with pytest.raises(RigError, match=r"sample 2: joint 'y'"):
        rig.move(
            {
                "x": float(ds["cmd_x"].values[2]),
                "y": float(ds["cmd_y"].values[2]) + 1.0,
                "theta": float(ds["cmd_theta"].values[2]),
            }
        )


def test_past_the_end_read_before_move_and_bad_commands(recorded):
    ds = recorded["identification"]
    rig = replay(str(recorded["runs"]), stream="identification")
    with pytest.raises(RigError, match="read\\(\\) before the first move"):
        rig.read()
    with pytest.raises(RigError, match="lacks joint 'theta'"):
        rig.move({"x": 0.0, "y": 0.0})
    with pytest.raises(RigError, match=r"joint\(s\) \['z'\]"):
        rig.move({"x": 0.0, "y": 0.0, "theta": 0.0, "z": 0.0})
    t0 = None
    for i in range(ds.sizes["sample"]):
        rig.move({j: float(ds[f"cmd_{j}"].values[i]) for j in rig.joints})
        rig.wait(100.0)  # time comes from the recording
        r = rig.read()
        t0 = r["time"] if t0 is None else t0
        assert r["time"] == float(ds["time"].values[i])
    assert rig.exhausted and rig.served == ds.sizes["sample"]
    with pytest.raises(RigError, match="past the end of the recording"):
        rig.move({"x": 0.0, "y": 0.0, "theta": 0.0})
    rig.close()
    with pytest.raises(RigError, match="after close"):
        rig.read()


def test_missing_recordings_are_named(recorded, tmp_path):
    with pytest.raises(
        RigError,
        match=r"replay stream 'validation_IV': no recording; recorded run ids are "
        r"\['identification', 'validation_I'\]",
    ):
        replay(str(recorded["runs"]), stream="validation_IV")
    with pytest.raises(RigError, match="expected a run id"):
        replay(str(recorded["runs"]))
    with pytest.raises(RigError, match="expected a folder"):
        replay(str(tmp_path / "nope"), stream="identification")
    with pytest.raises(RigError, match="file not found"):
        replay({"identification": str(tmp_path / "gone.nc")}, stream="identification")
    with pytest.raises(RigError, match="tolerance_um"):
        replay(str(recorded["runs"]), stream="identification", tolerance_um=-1)


def test_replay_through_load_rig(recorded):
    from calflow.rigs import load_rig

    rig, source = load_rig(
        "calflow.rigs.replay:replay",
        "xytheta",
        {"recordings": str(recorded["runs"]), "stream": "identification", "seed": 7},
    )
    assert rig.joints == ("x", "y", "theta") and source == "plugin"  # the lead maps "replay" -> "replay"


# ------------------------------------------------- instruments' recordings (ISO 230-2 .dat, tracker CSV)

import yaml  # noqa: E402
from conftest import ROOT, snakemake  # noqa: E402

from calflow.cli import main  # noqa: E402
from calflow.data import ecmc_iso230  # noqa: E402

RECORDINGS = ROOT / "tests" / "data" / "recordings"
ISO_ENTRY = {"file": str(RECORDINGS / "axis1_ISO230.dat"), "format": "ecmc_iso230"}


def campaign(tmp_path, robot, recordings, name="rec"):
    path = tmp_path / f"{name}.yaml"
    rig = {"factory": "replay", "options": {"recordings": recordings}}
    path.write_text(yaml.safe_dump({"robot": robot, "rig": rig}))
    return str(path)


def test_acquire_replays_an_iso230_file_with_the_plan_it_recorded(tmp_path):
    out = tmp_path / "runs" / "metrology.nc"
    c = campaign(tmp_path, "stage1d", {"metrology": ISO_ENTRY})
    assert main(["acquire", "--campaign", c, "--plan", "metrology", "--out", str(out)]) == 0
    ds = open_dataset(out, kind="run")
    assert validate_dataset(ds) == []
    assert (
        ds.attrs["source"] == "replay" and ds.attrs["plan"] == "metrology" and ds.attrs["campaign"] == "rec"
    )
    assert ds.attrs["imported_from"] == "axis1_ISO230.dat"
    rows = ecmc_iso230.standard_cycle(ecmc_iso230.read(ISO_ENTRY["file"]))
    for var, key in (
        ("cmd_x", "target"),
        ("meas_x", "reading"),
        ("direction", "direction"),
        ("cycle", "cycle"),
    ):
        assert np.array_equal(ds[var].values, rows[key]), var
    assert not list(out.parent.glob("*.journal"))


def test_an_instrument_recording_is_refused_where_it_cannot_stand(tmp_path, capsys):
    out = tmp_path / "runs" / "x.nc"
    # an ISO 230-2 (1-DoF) recording in a 2-DoF campaign
    c = campaign(tmp_path, "stage2d", {"training": ISO_ENTRY}, "planar")
    assert main(["acquire", "--campaign", c, "--plan", "training", "--out", str(out)]) != 0
    line = capsys.readouterr().err.strip()
    assert "axis1_ISO230.dat: rig.options.recordings.training: holds a stage1d recording" in line
    assert "\n" not in line
    assert not out.exists() and not list(tmp_path.glob("runs/*"))
    # a validation run is commanded through the models at run time: no recording can replay it
    from calflow.commands.acquire import _recorded
    from calflow.plan import Acquisition

    rig = replay({"validation": ISO_ENTRY}, stream="validation")
    job = Acquisition(rig.recorded_plan, "validation", controller=object())
    with pytest.raises(
        RigError,
        match=r"recordings\.validation: is an instrument's recording, which cannot replay "
        r"a run commanded through the models",
    ):
        _recorded(job, rig, {"robot": "stage1d"})


def test_the_config_check_names_a_bad_recording_entry(tmp_path):
    from calflow.configuration.campaign import load as load_campaign
    from calflow.errors import ConfigError

    for recordings, key in (
        (
            {"metrology": {"file": str(tmp_path / "gone_ISO230.dat"), "format": "ecmc_iso230"}},
            "rig.options.recordings.metrology.file': expected an existing file",
        ),
        (
            {"metrology": {"file": ISO_ENTRY["file"], "format": "dat"}},
            "rig.options.recordings.metrology.format': expected one of",
        ),
        ({"metrology": "notes.txt"}, "rig.options.recordings.metrology': expected a .nc run file"),
    ):
        with pytest.raises(ConfigError) as err:
            load_campaign(campaign(tmp_path, "stage1d", recordings))
        assert key in str(err.value) and "rec.yaml" in str(err.value)


def test_both_recorded_campaigns_run_end_to_end(shipped_recordings_run):
    """The shipped recorded campaigns through the workflow (conftest ``shipped_recordings_run``):
    reports, and what the data do not support."""
    work = shipped_recordings_run
    # the CSV campaign (training with temperatures + ISO 230-2 metrology): planned, not run (its models cost time)
    dry = snakemake(work, "-n", "--config", 'campaigns=["recorded-csv"]')
    assert dry.returncode == 0, dry.stderr[-2000:]
    jobs = dry.stdout + dry.stderr
    assert "rule identify:" in jobs and "rule acquire:" in jobs and "acquire_validation" not in jobs
    iso = json.loads((work / "results" / "recorded-iso230" / "summary.json").read_text())
    rec = ecmc_iso230.read(RECORDINGS / "axis1_ISO230.dat")
    from calflow.metrics import iso230_2

    want = iso230_2(rec.targets * 1000, rec.forward * 1000, rec.backward * 1000)
    assert iso["iso230_2"]["run"] == "metrology"
    assert iso["iso230_2"]["B_nm"] == pytest.approx(float(want.B) * 1000)
    assert iso["intrinsic"]["accuracy_nm"] > 0 and iso["models"] == {} and iso["validation"] is None
    assert set(iso["unsupported"]) == {
        "models",
        "training",
        "validation",
        "robustness",
        "temperature",
        "budget",
    }
    tracker = json.loads((work / "results" / "recorded-tracker" / "summary.json").read_text())
    assert list(tracker["models"]) == ["two_dof"] and tracker["training"]["accuracy_nm"] > 0
    assert set(tracker["unsupported"]) == {"validation", "robustness", "temperature", "budget"}
    for name, summary in (("recorded-iso230", iso), ("recorded-tracker", tracker)):
        html = (work / "reports" / name / "report.html").read_text()
        assert (work / "reports" / name / "report.pdf").stat().st_size > 1000
        assert "What these data do not support" in html
        for reason in summary["unsupported"].values():
            assert f"Not supported by these data: {reason.replace(chr(39), '&#39;')}." in html


def test_a_tracker_clock_is_served_in_campaign_time():
    entry = {"file": str(RECORDINGS / "stage2d_tracker.csv"), "format": "laser_tracker"}
    own = replay({"training": entry}, stream="training")
    later = replay({"training": entry}, stream="training", campaign_start="2026-03-02T09:00:00+00:00")
    same = replay({"training": entry}, stream="training", campaign_start="2026-03-02T10:00:00Z")
    iso = replay({"metrology": ISO_ENTRY}, stream="metrology", campaign_start="2026-03-02T09:00:00+00:00")
    times = []
    for rig in (own, later, same, iso):
        rig.move(rig.recorded_plan.row(0))
        rig.move(rig.recorded_plan.row(1))
        times.append(rig.read()["time"])
    assert times == [10.0, 3610.0, 10.0, 0.0]  # the ISO 230-2 file has no clock to shift


def test_unsupported_sections_say_what_each_missing_run_costs():
    from calflow.nano.report.summary import unsupported_sections

    assert unsupported_sections("stage1d", {"training", "metrology", "validation"}, True) == {}
    assert set(unsupported_sections("stage2d", {"training"}, False, budget=False)) == {
        "validation",
        "robustness",
        "temperature",
        "budget",
    }
    only_metrology = unsupported_sections("stage1d", {"metrology"}, True)
    assert set(only_metrology) == {"models", "training", "validation", "robustness"}
    assert "Eq. 5.3-5.6" in only_metrology["models"]
    assert "Eq. 5.10" in unsupported_sections("stage2d", set(), True)["models"]
    assert "metrology" in unsupported_sections("stage1d", {"training", "validation"}, True)
    assert "metrology" not in unsupported_sections("stage2d", {"training", "validation"}, True)
