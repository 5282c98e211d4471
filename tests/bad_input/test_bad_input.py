"""A catalogue of bad inputs (issue 18): each gives one line naming the file and the key,
and leaves nothing behind. Fast: the config check and the CLI in-process, two dry runs."""

from __future__ import annotations

import copy
import json
import math
import os
import stat

import pytest
import yaml
from conftest import SMALL_NANO1D, SMALL_XYTHETA, make_workdir, snakemake

from calflow.cli import main
from calflow.configuration.campaign import load as load_campaign
from calflow.errors import ConfigError

NAN, INF = float("nan"), float("inf")


def _set(path: str, value):
    """An edit of a campaign: set the dotted ``path`` (creating mappings) to ``value``."""

    def edit(c):
        *head, last = path.split(".")
        node = c
        for key in head:
            node = node.setdefault(key, {})
        node[last] = value

    return edit


GCS_XYTHETA = {
    **SMALL_XYTHETA,
    "rig": {
        "factory": "gcs",
        "options": {
            "axes": {"x": "1", "y": "2", "theta": "3"},
            "host": "127.0.0.1",
            "port": 50000,
            "scale": {"x": 1000.0, "y": 1000.0},
            "sensor": {"factory": "simulated_vision", "options": {}},
        },
    },
}

# (campaign, edit, expected substrings of the one line); every line also names the file.
CAMPAIGN_CASES = {
    "nan dwell": (
        SMALL_XYTHETA,
        _set("identification.dwell_s", NAN),
        ["key 'identification.dwell_s'", "finite"],
    ),
    "inf step": (
        SMALL_XYTHETA,
        _set("characterisation.step_um", INF),
        ["key 'characterisation.step_um'", "finite"],
    ),
    "nan in a target row": (
        SMALL_XYTHETA,
        _set("validation.targets", [[1.0, 2.0, NAN]]),
        ["key 'validation.targets.0.2'", "finite"],
    ),
    "reversed range": (
        SMALL_XYTHETA,
        _set("identification.x_um", [4000, 0]),
        ["key 'identification.x_um'", "low < high"],
    ),
    "empty range": (
        SMALL_XYTHETA,
        _set("identification.theta_deg", [2, 2]),
        ["key 'identification.theta_deg'"],
    ),
    "impossible date": (
        SMALL_XYTHETA,
        _set("start", "2026-02-31T08:00:00Z"),
        ["key 'start'", "real ISO 8601"],
    ),
    "negative noise": (
        SMALL_XYTHETA,
        _set("rig.options.sensor_noise_um", -1.0),
        ["key 'rig.options.sensor_noise_um'", ">= 0"],
    ),
    "noise 'loud'": (
        SMALL_XYTHETA,
        _set("rig.options.sensor_noise_um", "loud"),
        ["key 'rig.options.sensor_noise_um'", "got 'loud'"],
    ),
    "nan room temperature": (
        SMALL_XYTHETA,
        _set("rig.options.room_temperature_degC", NAN),
        ["key 'rig.options.room_temperature_degC'", "finite"],
    ),
    "nan rig seed": (SMALL_XYTHETA, _set("rig.options.seed", NAN), ["key 'rig.options.seed'"]),
    "float rig seed": (SMALL_XYTHETA, _set("rig.options.seed", 1.5), ["key 'rig.options.seed'", "integer"]),
    "zero velocity": (
        SMALL_XYTHETA,
        _set("rig.options.velocity_um_s", 0),
        ["key 'rig.options.velocity_um_s'", "> 0"],
    ),
    "zero pattern range": (
        SMALL_XYTHETA,
        _set("rig.options.pattern_range_um", [0, 4200]),
        ["key 'rig.options.pattern_range_um'"],
    ),
    "short tuple": (
        SMALL_XYTHETA,
        _set("rig.options.lead_fwd_um", [1.0]),
        ["key 'rig.options.lead_fwd_um'", "2"],
    ),
    "negative backlash in one run": (
        SMALL_XYTHETA,
        _set("rig.runs.identification", {"backlash_um": -2}),
        ["key 'rig.runs.identification.backlash_um'", ">= 0"],
    ),
    "zero resolution": (
        SMALL_XYTHETA,
        _set("rig.options.sensor_resolution_um", 0.0),
        ["key 'rig.options.sensor_resolution_um'"],
    ),
    "unknown rig option": (
        SMALL_XYTHETA,
        _set("rig.options.sensor_nosie_um", 1.0),
        ["unknown key 'rig.options.sensor_nosie_um'", "sensor_noise_um"],
    ),
    "plugin not allowed": (
        SMALL_XYTHETA,
        _set("rig", {"factory": "os:system", "options": {"command": "touch x"}}),
        ["key 'rig.factory'", "not allowed", "rig_plugins"],
    ),
    "not a factory name": (SMALL_XYTHETA, _set("rig.factory", "os.system"), ["key 'rig.factory'"]),
    "no callable": (
        SMALL_XYTHETA,
        _set("rig.factory", "toyrigs:nothing_here"),
        ["key 'rig.factory'", "no callable"],
    ),
    "no module": (
        SMALL_XYTHETA,
        _set("rig.factory", "toyrigs_not_there:make"),
        ["key 'rig.factory'", "cannot import"],
    ),
    "reversed stroke": (
        SMALL_NANO1D,
        _set("validation.stop_um", -10.0),
        ["key 'validation.stop_um'", "validation.start_um"],
    ),
    "average beyond dwell": (
        SMALL_NANO1D,
        _set("training.average_last_s", 20.0),
        ["key 'training.average_last_s'", "training.dwell_s"],
    ),
    "nano inf option": (
        SMALL_NANO1D,
        _set("rig.options.rise_time_s", INF),
        ["key 'rig.options.rise_time_s'"],
    ),
    "nano negative noise": (
        SMALL_NANO1D,
        _set("rig.options.interferometer_noise_nm", -3),
        ["key 'rig.options.interferometer_noise_nm'", ">= 0"],
    ),
    "nano unknown profile in a run": (
        SMALL_NANO1D,
        _set("rig.runs.metrology.profile", "sauna"),
        ["key 'rig.runs.metrology.profile'", "sauna"],
    ),
    "nano nan start": (SMALL_NANO1D, _set("validation.start_h", NAN), ["key 'validation.start_h'", "finite"]),
    "gcs port out of range": (
        GCS_XYTHETA,
        _set("rig.options.port", 99999),
        ["key 'rig.options.port'", "1-65535"],
    ),
    "gcs axis id with a space": (
        GCS_XYTHETA,
        _set("rig.options.axes.x", "1 2"),
        ["key 'rig.options.axes.x.axis'"],
    ),
    "gcs zero timeout": (GCS_XYTHETA, _set("rig.options.timeout", 0), ["key 'rig.options.timeout'", "> 0"]),
    "gcs scale of no joint": (
        GCS_XYTHETA,
        _set("rig.options.scale.z", 1000),
        ["key 'rig.options.scale.z'", "joints"],
    ),
    "gcs negative tries": (
        GCS_XYTHETA,
        _set("rig.options.reconnect.tries", -2),
        ["key 'rig.options.reconnect.tries'"],
    ),
    "gcs no sensor": (GCS_XYTHETA, _set("rig.options.sensor", None), ["key 'rig.options.sensor'"]),
    "gcs both host and serial": (
        GCS_XYTHETA,
        _set("rig.options.serial", "/dev/ttyUSB0"),
        ["key 'rig.options.axes.", "exactly one of 'host'"],
    ),
    "gcs misspelt option": (
        GCS_XYTHETA,
        _set("rig.options.time_scael", 10),
        ["unknown key 'rig.options.time_scael'"],
    ),
    "replay recordings not a path": (
        SMALL_XYTHETA,
        _set("rig", {"factory": "replay", "options": {"recordings": 3}}),
        ["key 'rig.options.recordings'"],
    ),
    "replay negative tolerance": (
        SMALL_XYTHETA,
        _set("rig", {"factory": "replay", "options": {"recordings": "results/x/runs", "tolerance_um": -1}}),
        ["key 'rig.options.tolerance_um'", ">= 0"],
    ),
}
ALLOWED = ["toyrigs", "toyrigs_not_there"]  # allowed, so what is checked is import and callable


def _write(tmp_path, campaign, edit, name="bad"):
    c = copy.deepcopy(campaign)
    edit(c)
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(c))  # NaN and inf become .nan and .inf, as a user writes them
    return path


@pytest.mark.parametrize("case", list(CAMPAIGN_CASES))
def test_bad_campaign_is_refused_in_one_line_naming_file_and_key(tmp_path, case):
    campaign, edit, expected = CAMPAIGN_CASES[case]
    path = _write(tmp_path, campaign, edit)
    plugins = [] if case == "plugin not allowed" else ALLOWED
    with pytest.raises(ConfigError) as info:
        load_campaign(path, plugins)
    message = str(info.value)
    assert "\n" not in message and message.startswith(f"{path}: ")
    for part in expected:
        assert part in message, message


def test_good_campaigns_still_load_and_nan_is_caught_in_yaml_text(tmp_path):
    for campaign in (SMALL_XYTHETA, SMALL_NANO1D):
        load_campaign(_write(tmp_path, campaign, lambda c: None, "good"), [])
    path = tmp_path / "text.yaml"
    path.write_text(yaml.safe_dump(SMALL_XYTHETA).replace("dwell_s: 0.5", "dwell_s: .NaN", 1))
    with pytest.raises(ConfigError, match=r"dwell_s': expected a finite number, got nan"):
        load_campaign(path)


def _cli(capsys, *argv) -> tuple[int, list[str]]:
    status = main([str(a) for a in argv])
    return status, [line for line in capsys.readouterr().err.splitlines() if line.strip()]


@pytest.mark.parametrize("case", ["plugin not allowed", "negative noise", "nan dwell"])
def test_acquire_refuses_before_anything_is_written(tmp_path, capsys, monkeypatch, case):
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("CALFLOW_RIG_PLUGINS", raising=False)
    campaign, edit, expected = CAMPAIGN_CASES[case]
    path = _write(tmp_path, campaign, edit)
    out = tmp_path / "results" / "run.nc"
    status, err = _cli(capsys, "acquire", "--campaign", path, "--plan", "identification", "--out", out)
    assert status == 2 and len(err) == 1 and err[0].startswith(f"calflow: error: {path}: ")
    assert all(part in err[0] for part in expected)
    assert (
        not (tmp_path / "results").exists() and not (tmp_path / "x").exists()
    )  # no output, no journal, no command


def test_acquire_out_under_a_file_is_one_line(tmp_path, capsys):
    (tmp_path / "afile").write_text("")
    path = _write(tmp_path, SMALL_XYTHETA, lambda c: None, "ok")
    status, err = _cli(
        capsys,
        "acquire",
        "--campaign",
        path,
        "--plan",
        "identification",
        "--out",
        tmp_path / "afile" / "run.nc",
    )
    assert status == 2 and len(err) == 1 and "afile is a file" in err[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile", "ok.yaml"]


@pytest.mark.parametrize(
    "argv,expected",
    [
        (["--port", "99999"], "--port: expected a TCP port 0-65535"),
        (["--port", "-1"], "--port: expected a TCP port 0-65535"),
        (["--time-scale", "nan"], "--time-scale: expected a value > 0"),
    ],
)
def test_emulator_arguments_are_one_line(tmp_path, capsys, argv, expected):
    path = _write(tmp_path, SMALL_XYTHETA, lambda c: None, "ok")
    status, err = _cli(capsys, "emulate", "gcs", "--campaign", path, *argv)
    assert status == 2 and len(err) == 1 and expected in err[0]


def test_error_line_also_goes_to_the_descriptor_the_workflow_passes(tmp_path, capsys, monkeypatch):
    read, write = os.pipe()
    monkeypatch.setenv("CALFLOW_ERROR_FD", str(write))
    status, err = _cli(
        capsys, "acquire", "--campaign", tmp_path / "missing.yaml", "--plan", "x", "--out", "o.nc"
    )
    os.close(write)
    with os.fdopen(read) as f:
        assert status == 2 and f.read().strip() == err[0] and "missing.yaml" in err[0]


# ------------------------------------------------------------------ nothing left behind
def test_stale_partials_are_removed_and_outputs_respect_the_umask(tmp_path):
    from calflow.data.io import write_json

    stale = tmp_path / ".summary.json.k1ll3d.partial"
    stale.write_text("half")
    other = tmp_path / ".other.json.k1ll3d.partial"  # another output's: not ours to remove
    other.write_text("half")
    old = os.umask(0o022)
    try:
        write_json({"a": 1}, tmp_path / "summary.json")
        assert stat.S_IMODE((tmp_path / "summary.json").stat().st_mode) == 0o644
        os.umask(0o027)
        write_json({"a": 1}, tmp_path / "summary.json")
        assert stat.S_IMODE((tmp_path / "summary.json").stat().st_mode) == 0o640
    finally:
        os.umask(old)
    assert not stale.exists() and other.exists()


def test_journal_appears_with_the_first_sample_only(tmp_path):
    from calflow.acquisition.checkpoint import Journal

    journal = Journal(tmp_path / "run.nc.journal", "digest")
    journal.open([])
    journal.close()
    assert not journal.path.exists()  # opened and failed before a reading: nothing left
    journal.open([])
    journal.append({"time": 0.0, "meas_x": NAN})
    journal.close()
    assert math.isnan(journal.load()[0]["meas_x"])  # the sample, NaN kept
    assert len(journal.path.read_text().splitlines()) == 2


@pytest.fixture
def run():
    from calflow.acquisition.runner import acquire
    from calflow.data.runs import RunMetadata
    from calflow.xytheta.plans import poses as plans
    from calflow.xytheta.stage.rig import simulated_xytheta

    meta = RunMetadata(
        campaign="t", robot="xytheta", source="simulated", plan="identification", config_sha256="0" * 64
    )
    return acquire(plans.identification(6, seed=3), simulated_xytheta(seed=1, stream="id"), meta)


def _all_nan(ds):
    ds["meas_x"][:] = NAN


def _nan_time(ds):
    ds["time"][:] = NAN


def _backwards_time(ds):
    ds["time"][2] = -1.0


def _kind_model(ds):
    ds.attrs["calflow_kind"] = "model"


def _mm(ds):
    ds["meas_y"].attrs["units"] = "mm"


def _no_meas_y(ds):
    del ds["meas_y"]


RECORDING_CASES = {
    "all-NaN measurements": (_all_nan, "variable 'meas_x': expected measurements, every value is NaN"),
    "NaN time": (_nan_time, "variable 'time': expected finite values"),
    "time going backwards": (_backwards_time, "variable 'time': expected non-decreasing values"),
    "a run labelled model": (_kind_model, "global attribute 'calflow_kind': expected 'run'"),
    "millimetres": (_mm, "variable 'meas_y': units expected 'um', got 'mm'"),
    "no meas_y": (_no_meas_y, "variable 'meas_y': missing"),
}


@pytest.mark.parametrize("case", list(RECORDING_CASES))
def test_validate_and_replay_refuse_a_broken_recording(run, tmp_path, capsys, case):
    from calflow.data.io import write_dataset
    from calflow.errors import RigError
    from calflow.rigs.replay import replay

    edit, expected = RECORDING_CASES[case]
    ds = run.copy(deep=True)
    edit(ds)
    path = write_dataset(ds, tmp_path / "runs" / "identification.nc")
    status, err = _cli(capsys, "validate", path)
    assert status == 1 and any(line.startswith(f"{path}: ") and expected in line for line in err), err
    with pytest.raises(RigError) as info:
        replay(tmp_path / "runs", stream="identification")
    name = expected.split("'")[1]  # the variable or attribute
    assert str(path) in str(info.value) and "replay" in str(info.value) and name in str(info.value)


def test_a_good_recording_still_validates_and_replays(run, tmp_path, capsys):
    from calflow.data.io import write_dataset
    from calflow.rigs.replay import replay

    path = write_dataset(run, tmp_path / "runs" / "identification.nc")
    assert _cli(capsys, "validate", path)[0] == 0
    assert replay(tmp_path / "runs", stream="identification").n == run.sizes["sample"]


# ------------------------------------------------------------------ through Snakemake -n
def test_dry_run_refuses_a_plugin_the_config_does_not_allow(tmp_path):
    campaign = json.loads(json.dumps(SMALL_XYTHETA))
    campaign["rig"] = {"factory": "os:system", "options": {"command": "touch PWNED"}}
    work = make_workdir(tmp_path, {"shared": campaign})
    proc = snakemake(work, "-n")
    lines = [line for line in proc.stderr.splitlines() if "calflow: error" in line]
    assert proc.returncode != 0 and len(lines) == 1, proc.stderr[-2000:]
    assert "config/campaigns/shared.yaml: key 'rig.factory'" in lines[0] and "rig_plugins" in lines[0]
    assert not (work / "results").exists() and not (work / "PWNED").exists()


def test_dry_run_accepts_a_plugin_allowed_on_the_command_line(tmp_path):
    campaign = json.loads(json.dumps(SMALL_XYTHETA))
    campaign["rig"] = {"factory": "toyrigs:open_toy", "options": {}}
    work = make_workdir(tmp_path, {"toy": campaign})
    proc = snakemake(work, "-n", "results/toy/runs/identification.nc", "--config", 'rig_plugins=["toyrigs"]')
    assert proc.returncode == 0, proc.stderr[-2000:]


# ------------------------------------------------------------------ GCS replies
class Canned:
    """A transport that answers every command line with the next canned reply."""

    def __init__(self, replies):
        self.replies = list(replies)
        self.pending = b""

    def write(self, data):
        if data.endswith(b"\n") or len(data) == 1:
            self.pending += self.replies.pop(0) if self.replies else b""

    def read(self, timeout):
        from calflow.gcs.wire.protocol import GCSTimeout

        if not self.pending:
            raise GCSTimeout("no reply")
        data, self.pending = self.pending, b""
        return data

    def close(self):
        pass


def _sai(*rest):
    return [b"1 \n2\n", *rest]


GCS_REPLY_CASES = {  # (call, replies, expected part of the one line)
    "POS? not a number": (lambda c: c.position(["1"]), _sai(b"1=abc\n"), "cannot parse reply line '1=abc'"),
    "POS? another axis": (lambda c: c.position(["1"]), _sai(b"2=1.0\n"), "names axes ['2'], expected ['1']"),
    "POS? no '='": (lambda c: c.position(["1"]), _sai(b"1 1.0\n"), "no '='"),
    "binary garbage": (lambda c: c.on_target(["1"]), _sai(b"\x00\x1b#~\x7f\n"), "garbage in reply to 'ONT?'"),
    "ERR? not an integer": (lambda c: c.servo_on("1"), [b"x\n"], "expected one integer in reply to 'ERR?'"),
    "#7 not B0/B1": (lambda c: c.ready(), [b"7\n"], "unexpected reply to #7"),
    "ONT? not 0/1": (lambda c: c.on_target(["1"]), _sai(b"1=2\n"), "expected 0 or 1"),
    "SPA? another parameter": (
        lambda c: c.parameter("1", 0x36),
        [b"1 0x3F=2\n"],
        "unexpected reply to 'SPA? 1 0x36'",
    ),
    "DRR? rows of the wrong width": (
        lambda c: c.read_recorder([1], 1, 2),
        [b"# DIM = 1 \n# END_HEADER \n1 2 \n3\n"],
        "rows must have DIM = 1 columns",
    ),
    "DRR? without END_HEADER": (
        lambda c: c.read_recorder([1], 1, 2),
        [b"# DIM = 1 \n# NDATA = 1\n"],
        "no '# END_HEADER'",
    ),
    "no reply at all": (lambda c: c.idn(), [], "no reply to '*IDN?' within"),
}


@pytest.mark.parametrize("case", list(GCS_REPLY_CASES))
def test_a_bad_gcs_reply_is_one_line_naming_the_command(case):
    from calflow.gcs.wire.client import GCSController
    from calflow.gcs.wire.protocol import GCSError

    call, replies, expected = GCS_REPLY_CASES[case]
    ctl = GCSController(lambda: Canned(replies), timeout=0.05)
    with pytest.raises(GCSError) as info:
        call(ctl)
    assert "\n" not in str(info.value) and expected in str(info.value), str(info.value)


# ------------------------------------------------------------------ CSV recordings and CLI arguments
CSV_HEADER = "t_s,X,Y,T,xv,yv,tv"
CSV_ROWS = ["0.0,0,0,0,1.0,2.0,0.0", "1.0,1,1,1,2.0,3.0,1.0"]
CSV_MAPPING = {
    "robot": "xytheta",
    "plan": "identification",
    "columns": {
        "time": {"column": "t_s"},
        "cmd_x": {"column": "X"},
        "cmd_y": {"column": "Y"},
        "cmd_theta": {"column": "T"},
        "meas_x": {"column": "xv"},
        "meas_y": {"column": "yv"},
        "meas_theta": {"column": "tv"},
    },
}
CSV_CASES = {  # (csv lines, mapping edit, expected part of the one line)
    "csv: a column missing": (
        [CSV_HEADER.replace("yv", "yy"), *CSV_ROWS],
        None,
        "column 'yv' (for meas_y) missing",
    ),
    "csv: text in a command": (
        [CSV_HEADER, CSV_ROWS[0], "1.0,one,1,1,2.0,3.0,1.0"],
        None,
        "expected a number, got 'one'",
    ),
    "csv: empty file": ([], None, "the file is empty"),
    "csv: time going backwards": (
        [CSV_HEADER, CSV_ROWS[1], CSV_ROWS[0]],
        None,
        "expected non-decreasing time",
    ),
    "csv: wrong delimiter": ([line.replace(",", ";") for line in (CSV_HEADER, *CSV_ROWS)], None, "row 1"),
    "mapping: unknown key": ([CSV_HEADER, *CSV_ROWS], {"colums": {}}, "colums"),
}


@pytest.mark.parametrize("case", list(CSV_CASES))
def test_import_csv_refuses_a_bad_recording_in_one_line_and_writes_nothing(tmp_path, capsys, case):
    lines, extra, expected = CSV_CASES[case]
    csv_path = tmp_path / "bench.csv"
    csv_path.write_text("\n".join(lines) + ("\n" if lines else ""))
    mapping = tmp_path / "mapping.yaml"
    mapping.write_text(yaml.safe_dump({**CSV_MAPPING, **(extra or {})}))
    campaign = _write(tmp_path, SMALL_XYTHETA, lambda c: None, "ok")
    out = tmp_path / "runs" / "identification.nc"
    status, err = _cli(
        capsys, "import-csv", csv_path, "--mapping", mapping, "--campaign", campaign, "--out", out
    )
    assert status == 2 and len(err) == 1 and expected in err[0], err
    assert not (tmp_path / "runs").exists()


CLI_CASES = {  # argv (after ``calflow``), expected part of the one line
    "acquire: unknown plan": (
        ["acquire", "--campaign", "{ok}", "--plan", "nosuch", "--out", "{tmp}/r.nc"],
        "--plan 'nosuch' is not a plan",
    ),
    "acquire: missing campaign": (
        ["acquire", "--campaign", "{tmp}/gone.yaml", "--plan", "identification", "--out", "{tmp}/r.nc"],
        "gone.yaml",
    ),
    "validate: missing file": (["validate", "{tmp}/gone.nc"], "gone.nc"),
    "emulate: zero time scale": (
        ["emulate", "gcs", "--campaign", "{ok}", "--time-scale", "0"],
        "--time-scale: expected a value > 0",
    ),
}


@pytest.mark.parametrize("case", list(CLI_CASES))
def test_bad_cli_arguments_are_one_line(tmp_path, capsys, case):
    argv, expected = CLI_CASES[case]
    ok = _write(tmp_path, SMALL_XYTHETA, lambda c: None, "ok")
    status, err = _cli(capsys, *(a.format(ok=ok, tmp=tmp_path) for a in argv))
    assert status in (1, 2) and len(err) == 1 and expected in err[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ok.yaml"]


def test_the_catalogue_holds_at_least_40_bad_inputs():
    """Issue 18: >= 40 bad inputs over campaign files, CLI arguments, netCDF and CSV
    recordings and GCS replies (docs/reliability.md gives the count)."""
    counts = catalogue_counts()
    assert all(counts.values()) and sum(counts.values()) >= 40, counts


def catalogue_counts() -> dict[str, int]:
    return {
        "campaign files": len(CAMPAIGN_CASES) + 2,  # + the NaN written as YAML text, --out under a file
        "CLI arguments": len(CLI_CASES) + 3,  # + the emulator's --port/--time-scale cases above
        "netCDF recordings": len(RECORDING_CASES),
        "CSV recordings and mappings": len(CSV_CASES),
        "GCS replies": len(GCS_REPLY_CASES),
    }
