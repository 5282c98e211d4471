"""The bad-input catalogue of campaign and workflow files, written as a new user writes them:
copy a default file of config/ and change one thing. Each must be refused when the files
are loaded — before any job — in one line naming the file, the key and what was expected.

:data:`CAMPAIGNS` and :data:`CONFIGS` are the tables (``benchmarks/bad_input_catalogue.py``
runs them in subprocesses and counts the share refused at load, with a time limit: the
alias bomb kept a loader busy ~45 minutes)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT, snakemake

from calflow.cli import main
from calflow.configuration.campaign import load as load_campaign
from calflow.errors import ConfigError

CHECK = "demo-sn0042-2026-04-check"  # an interim check of ...
CALIBRATION = "demo-sn0042-2026-01"  # ... this calibration of stage SN-0042

BOMB = "a: &a [lol, lol, lol, lol, lol, lol, lol, lol, lol, lol]\n" + "".join(
    f"{c}: &{c} [{', '.join([f'*{p}'] * 10)}]\n" for p, c in zip("abcdefgh", "bcdefghi")
)  # 10⁹ values in 370 bytes
ZERO_TRACKER = (
    "{tracker_adm_um: 0, tracker_adm_um_per_m: 0, tracker_transverse_um: 0, "
    "tracker_transverse_um_per_m: 0, tracker_angle_mdeg: 0, tracker_resolution_um: 0, leg_repeatability_um: 0}"
)


def case(name, base, old, new, *expected, files=None):
    """A bad file: ``base`` (a campaign of config/campaigns) with ``old`` replaced by ``new``
    (``old`` None: ``new`` appended); ``files``: other files the case writes (path → text)."""
    return pytest.param(base, old, new, expected, files or {}, id=name)


CAMPAIGNS = [
    # ---- YAML: aliases, duplicate keys, characters one cannot see
    case("alias bomb", CALIBRATION, None, BOMB, "aliases expand to more than"),
    case(
        "alias of itself",
        CALIBRATION,
        "  factory: simulated\n",
        "  factory: simulated\n  x: &s [*s]\n",
        "refers to itself",
    ),
    case(
        "a second stage line",
        CALIBRATION,
        "stage: SN-0042\n",
        "stage: SN-0042\nstage: SN-0043\n",
        "line 10",
        "key 'stage' appears twice (first at line 9)",
    ),
    case(
        "a key twice in a flow mapping",
        CALIBRATION,
        "{poses: 60, dwell_s: 0.5}",
        "{poses: 60, dwell_s: 0.5, poses: 600}",
        "key 'identification.poses' appears twice",
    ),
    case(
        "Cyrillic a in a key",
        CALIBRATION,
        "tolerance_um:",
        "toler\u0430nce_um:",
        "key 'toler\u0430nce_um' contains U+0430 CYRILLIC SMALL LETTER A",
    ),
    case(
        "Greek omicron in a key",
        CALIBRATION,
        "models:",
        "m\u03bfdels:",
        "contains U+03BF GREEK SMALL LETTER OMICRON",
    ),
    case(
        "Greek Iota model name",
        CALIBRATION,
        "  III: {free",
        "  \u0399\u0399\u0399: {free",
        "key 'models.\u0399\u0399\u0399' contains U+0399 GREEK CAPITAL LETTER IOTA",
    ),
    case(
        "Cyrillic a in a value",
        CALIBRATION,
        "factory: simulated",
        "factory: simul\u0430ted",
        "key 'rig.factory'",
        "contains U+0430 CYRILLIC SMALL LETTER A",
    ),
    case(
        "Cyrillic e in the robot",
        CALIBRATION,
        "robot: xytheta",
        "robot: xyth\u0435ta",
        "key 'robot'",
        "U+0435 CYRILLIC SMALL LETTER IE",
    ),
    case(
        "no-break space in a value",
        CALIBRATION,
        "stage: SN-0042",
        "stage: SN\u00a00042",
        "key 'stage'",
        "U+00A0 NO-BREAK SPACE",
    ),
    case(
        "no-break space after a key",
        CALIBRATION,
        "seed: 42",
        "seed\u00a0: 42",
        "contains U+00A0 NO-BREAK SPACE",
    ),
    case(
        "zero width space in a date",
        CALIBRATION,
        '+00:00"\nrig:',
        '+00:00\u200b"\nrig:',
        "key 'start'",
        "U+200B ZERO WIDTH SPACE",
    ),
    case(
        "right-to-left mark in a description",
        CALIBRATION,
        "(small plan)",
        "(small plan)\u200f",
        "key 'description'",
        "U+200F RIGHT-TO-LEFT MARK",
    ),
    # ---- stage ids
    case(
        "stage id with a slash",
        CALIBRATION,
        "stage: SN-0042",
        "stage: SN/0042",
        "key 'stage'",
        "letters, digits, '-' or '_'",
        "which contains '/'",
    ),
    case(
        "stage id '..'",
        CALIBRATION,
        "stage: SN-0042",
        "stage: ..",
        "key 'stage'",
        "letters, digits",
        "which contains '.'",
    ),
    case(
        "stage id with a non-breaking hyphen",
        CALIBRATION,
        "stage: SN-0042",
        "stage: SN\u20110042",
        "letters, digits",
        "U+2011 NON-BREAKING HYPHEN",
    ),
    case(
        "stage id with an en dash",
        CALIBRATION,
        "stage: SN-0042",
        "stage: SN\u20130042",
        "letters, digits",
        "U+2013 EN DASH",
    ),
    # ---- interim checks
    case(
        "interim check without a tolerance",
        CHECK,
        ", tolerance_um: 3.5",
        "",
        "key 'interim_check.tolerance_um': missing",
    ),
    case(
        "interim check of 10^7 cycles",
        CHECK,
        "cycles: 3",
        "cycles: 10000000",
        "key 'interim_check.cycles'",
        "within 5% of the reference's rig time",
    ),
    case(
        "interim check of 60 targets x 100 cycles",
        CHECK,
        "targets: 2, cycles: 3",
        "targets: 60, cycles: 100",
        "key 'interim_check.cycles'",
    ),
    case(
        "interim tolerance below the reference's error",
        CHECK,
        "tolerance_um: 3.5",
        "tolerance_um: 0.5",
        "key 'interim_check.tolerance_um'",
        "above the reference's own rms visit error",
        files={"EXPORT_RUN": ""},
    ),
    # ---- ageing
    case(
        "commissioning after the start",
        CALIBRATION,
        "      wear_per_year: 0.3\n",
        "      wear_per_year: 0.3\n      since: '2026-03-01T00:00:00+00:00'\n",
        "key 'rig.options.aging.since'",
        "at or before the campaign's start",
    ),
    case(
        "event before the commissioning",
        CALIBRATION,
        "2026-07-01T00:00:00+00:00",
        "2025-07-01T00:00:00+00:00",
        "key 'rig.options.aging.events.0.date'",
        "at or after the stage's commissioning",
    ),
    case(
        "nano event before the commissioning",
        "nano1d-thesis",
        "    profile: lab5day",
        "    aging: {events: [{date: '2026-01-01T00:00:00+00:00', offset_nm: 40}]}\n    profile: lab5day",
        "key 'rig.options.aging.events.0.date'",
    ),
    case(
        "nano ageing beyond the gain",
        "nano1d-thesis",
        "    profile: lab5day",
        "    aging: {events: [{date: '2026-01-05T08:00:00+00:00', gain_pct: -150}]}\n    profile: lab5day",
        "key 'rig.options.aging'",
        "'gain_pct'",
        "> -100 %",
    ),
    case(
        "nano piezo ageing of 500 %/decade",
        "nano1d-thesis",
        "    profile: lab5day",
        "    aging: {piezo_pct_per_decade: 500, since: '2016-01-05T08:00:00+00:00'}\n    profile: lab5day",
        "key 'rig.options.aging'",
        "gain_pct",
    ),
    case(
        "nano commissioning after the start",
        "nano2d-thesis",
        "    profile: lab5day\n",
        "    profile: lab5day\n    aging: {since: '2027-01-01T00:00:00+00:00'}\n",
        "key 'rig.options.aging.since'",
    ),
    case(
        "lights on at 25 h",
        "nano1d-thesis",
        "    profile: lab5day",
        "    lights_on_h: 25\n    profile: lab5day",
        "key 'rig.options.lights_on_h'",
        "0-24",
    ),
    case(
        "lights off before on",
        "nano1d-thesis",
        "    profile: lab5day",
        "    lights_off_h: 6\n    profile: lab5day",
        "key 'rig.options.lights_off_h'",
        "after lights_on_h",
    ),
    case(
        "nano more designed positions than candidates",
        "nano1d-thesis",
        "training: {start_um: 0,",
        "training: {plan: optimal, design: {positions: 800, candidate_step_um: 1.0}, start_um: 0,",
        "key 'training.design.positions'",
        "at most the 481 candidate positions",
    ),
    # ---- the hexapod plug-in
    case(
        "hexapod tracker without error",
        "hexapod-demo",
        "  factory: simulated\n",
        f"  factory: simulated\n  options: {ZERO_TRACKER}\n",
        "key 'rig.options'",
        "reading noise > 0",
    ),
    case(
        "hexapod design noise zero",
        "hexapod-demo",
        "candidates: 2000}",
        "candidates: 2000, noise: {position_um: 0, angle_deg: 0, leg_um: 0}}",
        "key 'identification.design.noise'",
    ),
    case(
        "hexapod ISO 9283 cube of the whole travel",
        "hexapod-demo",
        "  fraction: 0.5\n  cycles: 10",
        "  fraction: 1.0\n  cycles: 10",
        "key 'iso9283.fraction'",
        "smaller cube",
    ),
    case(
        "hexapod ISO 9283 poses tilted out",
        "hexapod-demo",
        "  fraction: 0.5\n  cycles: 10",
        "  fraction: 0.5\n  orientation_deg: [10, 10, 20]\n  cycles: 10",
        "key 'iso9283.orientation_deg'",
    ),
    case(
        "hexapod payload of 500 kg",
        "hexapod-demo",
        "  factory: simulated\n",
        "  factory: simulated\n  options: {payload_kg: 500}\n",
        "key 'rig.options.payload_kg'",
        "1000 µm",
    ),
    case(
        "hexapod unknown design key",
        "hexapod-demo",
        "candidates: 2000}",
        "candidates: 2000, critrion: A}",
        "unknown key 'identification.design.critrion'",
        "criterion",
    ),
    case(
        "hexapod model off the ladder",
        "hexapod-demo",
        "  geometric: {}\n",
        "  geometric: {}\n  VI: {}\n",
        "key 'models.VI'",
        "ladder",
    ),
    case(
        "hexapod design model off the ladder",
        "hexapod-demo",
        "model: geometric,",
        "model: VI,",
        "key 'identification.design.model'",
    ),
    case(
        "hexapod more poses than candidates",
        "hexapod-demo",
        "candidates: 2000}",
        "candidates: 100}",
        "key 'identification.poses'",
        "at most identification.design.candidates (100)",
    ),
    case(
        "hexapod tracker pivot of 2 numbers",
        "hexapod-demo-gcs",
        "      options: {}",
        "      options: {pivot_um: [1, 2]}",
        "key 'rig.options.sensor.options.pivot_um'",
        "3 finite numbers",
    ),
    case(
        "hexapod tracker pivot 500 m off the platform",
        "hexapod-demo-gcs",
        "      options: {}",
        "      options: {pivot_um: [0, 0, 5.0e8]}",
        "key 'rig.options.sensor.options.pivot_um'",
        "within ±1000000 µm",
    ),
    case(
        "hexapod tracker negative error",
        "hexapod-demo-gcs",
        "      options: {}",
        "      options: {tracker_adm_um: -1}",
        "key 'rig.options.sensor.options.tracker_adm_um'",
        ">= 0",
    ),
    case(
        "hexapod tracker unknown option",
        "hexapod-demo-gcs",
        "      options: {}",
        "      options: {tracker_admm_um: 1}",
        "unknown key 'rig.options.sensor.options.tracker_admm_um'",
    ),
    case(
        "gcs vision sensor negative noise",
        "xytheta-thesis",
        None,
        "",
        "key 'rig.options.sensor.options.sensor_noise_um'",
        files={"GCS_VISION": ""},
    ),
    # ---- a reference file
    case(
        "reference file with an unknown key",
        CALIBRATION,
        "stage: SN-0042\n",
        "stage: SN-0042\nreference: {file: ref.yaml}\n",
        "ref.yaml: unknown key 'lut'",
        "lut_compensation_um",
        files={"ref.yaml": "source: Smith 2024\nlut: [22, 3]\n"},
    ),
    case(
        "reference file with a misspelt model key",
        CALIBRATION,
        "stage: SN-0042\n",
        "stage: SN-0042\nreference: {file: ref.yaml}\n",
        "ref.yaml: unknown key 'models.III.acuracy_um'",
        files={"ref.yaml": "source: Smith 2024\nmodels: {III: {acuracy_um: 3}}\n"},
    ),
    case(
        "reference file with a duplicate key",
        CALIBRATION,
        "stage: SN-0042\n",
        "stage: SN-0042\nreference: {file: ref.yaml}\n",
        "ref.yaml: reference file: line 3: key 'models' appears twice",
        files={"ref.yaml": "source: S\nmodels: {III: {accuracy_um: 3}}\nmodels: {II: {accuracy_um: 4}}\n"},
    ),
]


def _export_run(path: Path, rms_um: float) -> None:
    """A closed-loop check run of the reference's bundle whose visit errors have rms ``rms_um``."""
    from calflow.data.io import write_dataset
    from calflow.data.runs import RunMetadata, run_dataset
    from calflow.plan import Plan
    from calflow.xytheta.evaluation import attained_points

    pose = np.array([0, 1, 2, 1, 2, 1, 2])
    x = np.array([0.0, 100, 300, 100, 300, 100, 300])
    y = np.array([0.0, 200, 100, 200, 100, 200, 100])
    plan = Plan(
        "validation_export",
        {"x": x, "y": y, "theta": np.zeros(7)},
        pose,
        np.array([0, 0, 0, 1, 1, 2, 2]),
        np.zeros(7, dtype=int),
        targets={"x": x, "y": y, "theta": np.zeros(7)},
    )
    readings = [{"time": float(i), "meas_x": -x[i], "meas_y": y[i], "meas_theta": 0.0} for i in range(7)]
    meta = RunMetadata("r", "xytheta", "simulated", "validation_export", "0" * 64)
    ds = run_dataset(readings, plan, ["meas_x", "meas_y", "meas_theta"], [], meta)
    ax, ay = attained_points(ds)
    e = np.where(pose > 0, rms_um / np.sqrt(2), 0.0)  # each visit off by rms_um
    ds["target_x"].values[:] = ax - e
    ds["target_y"].values[:] = ay - e
    path.parent.mkdir(parents=True, exist_ok=True)
    write_dataset(ds, path)


def _project(tmp_path: Path, monkeypatch) -> Path:
    """A copy of the project's campaign files; the working folder is the project."""
    folder = tmp_path / "config" / "campaigns"
    shutil.copytree(ROOT / "config" / "campaigns", folder)
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("CALFLOW_RIG_PLUGINS", raising=False)
    return folder


def write_case(folder: Path, base: str, old, new: str, files: dict) -> Path:
    """Write the bad campaign ``folder/bad.yaml`` (and the case's other files)."""
    text = (folder / f"{base}.yaml").read_text(encoding="utf-8")
    if "GCS_VISION" in files:  # the thesis campaign on a gcs rig, its sensor's noise negative
        text = _gcs_vision(folder, base)
    elif old is None:
        text += new
    else:
        assert old in text, f"{old!r} not in {base}.yaml"
        text = text.replace(old, new, 1)
    for name, content in files.items():
        if name == "EXPORT_RUN":
            _export_run(folder.parent.parent / "results" / CALIBRATION / "runs" / "export_III.nc", 2.0)
        elif name != "GCS_VISION":
            (folder.parent.parent / name).write_text(content, encoding="utf-8")
    path = folder / "bad.yaml"
    path.write_text(text, encoding="utf-8")
    return path


def _gcs_vision(folder: Path, base: str) -> str:
    """``base`` with its rig replaced by a gcs rig whose vision sensor has a negative noise."""
    import yaml

    data = yaml.safe_load((folder / f"{base}.yaml").read_text(encoding="utf-8"))
    data["rig"] = {
        "factory": "gcs",
        "options": {
            "axes": {"x": "1", "y": "2", "theta": "3"},
            "host": "127.0.0.1",
            "port": 50000,
            "scale": {"x": 1000.0, "y": 1000.0},
            "sensor": {"factory": "simulated_vision", "options": {"sensor_noise_um": -1}},
        },
    }
    return yaml.safe_dump(data, allow_unicode=True)


@pytest.mark.parametrize("base, old, new, expected, files", CAMPAIGNS)
def test_a_bad_campaign_file_is_refused_at_load_in_one_line(
    tmp_path, monkeypatch, base, old, new, expected, files
):
    folder = _project(tmp_path, monkeypatch)
    path = write_case(folder, base, old, new, files)
    with pytest.raises(ConfigError) as info:
        load_campaign(path, [])
    message = str(info.value)
    assert "\n" not in message and message.startswith(
        str(path) if "ref.yaml" not in expected[0] else "ref.yaml"
    )
    for part in expected:
        assert part in message, message


@pytest.mark.parametrize("tolerance", ["3.5", "2.5"])
def test_an_interim_tolerance_above_the_reference_error_is_accepted(tmp_path, monkeypatch, tolerance):
    folder = _project(tmp_path, monkeypatch)
    _export_run(tmp_path / "results" / CALIBRATION / "runs" / "export_III.nc", 2.0)
    path = write_case(folder, CHECK, "tolerance_um: 3.5", f"tolerance_um: {tolerance}", {})
    assert load_campaign(path, [])["interim_check"]["tolerance_um"] == float(tolerance)


def test_a_check_that_ran_is_not_checked_against_files_at_load(tmp_path, monkeypatch):
    """Once the check's own run is on disk, loading reads no netCDF file (no-op runs stay
    cheap); a rerun's acquisition checks the tolerance again before the rig moves."""
    import sys

    folder = _project(tmp_path, monkeypatch)
    _export_run(tmp_path / "results" / CALIBRATION / "runs" / "export_III.nc", 2.0)
    path = write_case(folder, CHECK, "tolerance_um: 3.5", "tolerance_um: 0.5", {})
    (tmp_path / "results" / "bad" / "runs").mkdir(parents=True)
    (tmp_path / "results" / "bad" / "runs" / "interim_check.nc").write_bytes(b"")
    monkeypatch.setitem(sys.modules, "calflow.data.io", None)  # importing it would raise
    assert load_campaign(path, [])["interim_check"]["tolerance_um"] == 0.5


@pytest.mark.parametrize("tolerance,refused", [("0.5", True), ("2.0", True), ("2.5", False)])
def test_a_check_that_ran_is_checked_against_the_error_its_summary_recorded(
    tmp_path, monkeypatch, tolerance, refused
):
    """Edited after it ran, a check's tolerance is still held against the reference's own error
    before any job: r0 as the check's summary recorded it from the reference run on disk (a JSON
    read, no netCDF); a summary older than that run says nothing and the acquisition checks."""
    import os
    import sys

    folder = _project(tmp_path, monkeypatch)
    export = tmp_path / "results" / CALIBRATION / "runs" / "export_III.nc"
    _export_run(export, 2.0)
    path = write_case(folder, CHECK, "tolerance_um: 3.5", f"tolerance_um: {tolerance}", {})
    (tmp_path / "results" / "bad" / "runs").mkdir(parents=True)
    (tmp_path / "results" / "bad" / "runs" / "interim_check.nc").write_bytes(b"")
    summary = tmp_path / "results" / "bad" / "summary.json"
    summary.write_text(json.dumps({"interim_check": {"reference_rms_um": 2.0}}))
    monkeypatch.setitem(sys.modules, "calflow.data.io", None)  # importing it would raise
    if refused:
        with pytest.raises(ConfigError) as exc:
            load_campaign(path, [])
        message = str(exc.value)
        assert "\n" not in message and str(path) in message
        assert "key 'interim_check.tolerance_um'" in message and "2 µm" in message
    else:
        assert load_campaign(path, [])["interim_check"]["tolerance_um"] == float(tolerance)
    stale = export.stat().st_mtime - 10
    os.utime(summary, (stale, stale))  # the reference ran again after the check: unknown here
    assert load_campaign(path, [])["interim_check"]["tolerance_um"] == float(tolerance)


def test_the_default_campaigns_and_free_text_still_load(tmp_path, monkeypatch):
    folder = _project(tmp_path, monkeypatch)
    shutil.copytree(ROOT / "tests" / "data", tmp_path / "tests" / "data")
    for path in sorted(folder.glob("*.yaml")):
        load_campaign(path, [])
    text = (folder / CALIBRATION).with_suffix(".yaml").read_text(encoding="utf-8")
    free = text.replace("(small plan)", "(petit plan, réglé à 20 °C — XYΘ, Москва)")
    anchors = free.replace("  heldout: {targets: 8", "  heldout: &h {targets: 8")
    (folder / "free.yaml").write_text(
        anchors + "# a comment with a no-break space\u00a0is fine\n", encoding="utf-8"
    )
    c = load_campaign(folder / "free.yaml", [])
    assert "Москва" in c["description"] and c["validation"]["heldout"]["targets"] == 8


# ------------------------------------------------------------------ the workflow configuration
CONFIG = "campaigns: [demo-sn0042-2026-01, demo-sn0042-2026-04-check]\nstudies: []\n"


def config_case(name, text, *expected):
    return pytest.param(text, expected, id=name)


CONFIGS = [
    config_case(
        "config: campaigns twice",
        CONFIG + "campaigns: [xytheta-thesis]\n",
        "line 3",
        "key 'campaigns' appears twice",
    ),
    config_case("config: alias bomb", CONFIG + BOMB, "aliases expand to more than"),
    config_case(
        "config: look-alike key",
        CONFIG.replace("studies", "stud\u0456es"),
        "U+0456 CYRILLIC SMALL LETTER BYELORUSSIAN-UKRAINIAN I",
    ),
    config_case(
        "config: stage settings of no stage",
        CONFIG + "stages: {SN-0O42: {tolerance_um: 3}}\n",
        "key 'stages.SN-0O42'",
        "did you mean 'SN-0042'",
    ),
    config_case(
        "config: watched model VI",
        CONFIG + "stages: {SN-0042: {model: VI}}\n",
        "key 'stages.SN-0042.model'",
        "['III']",
        "got 'VI'",
    ),
    config_case(
        "config: stage id with a slash",
        CONFIG + "stages: {SN/0042: {tolerance_um: 3}}\n",
        "key 'stages'",
        "which contains '/'",
    ),
    config_case(
        "config: stage id with an en dash",
        CONFIG + "stages: {SN\u20130042: {tolerance_um: 3}}\n",
        "key 'stages.SN\u20130042'",
        "U+2013 EN DASH",
    ),
    config_case(
        "config: tolerance as text",
        CONFIG + "stages: {SN-0042: {tolerance_um: three}}\n",
        "key 'stages.SN-0042.tolerance_um'",
        "a number",
    ),
]


@pytest.mark.parametrize("text, expected", CONFIGS)
def test_a_bad_workflow_config_is_refused_by_check_config_in_one_line(
    tmp_path, monkeypatch, capsys, text, expected
):
    _project(tmp_path, monkeypatch)
    assert_refused_by_check_config(tmp_path, capsys, text, expected)


def assert_refused_by_check_config(tmp_path, capsys, text: str, expected) -> None:
    """``calflow check-config`` of ``text`` as config/config.yaml fails in one line naming the
    file, with every part of ``expected``."""
    (tmp_path / "config" / "config.yaml").write_text(text, encoding="utf-8")
    status = main(["check-config", "config/config.yaml"])
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert status != 0 and len(err) == 1 and "config/config.yaml" in err[0], err
    for part in expected:
        assert part in err[0], err[0]


def test_a_stage_of_a_campaign_on_disk_only_may_have_settings(tmp_path, monkeypatch, capsys):
    _project(tmp_path, monkeypatch)  # SN-0042's campaigns are in the folder, none in the run
    (tmp_path / "config" / "config.yaml").write_text(
        "campaigns: [xytheta-thesis]\nstages: {SN-0042: {tolerance_um: 3, model: III}}\n", encoding="utf-8"
    )
    assert main(["check-config", "config/config.yaml"]) == 0, capsys.readouterr().err


def _workdir(tmp_path: Path) -> Path:
    work = tmp_path / "project"
    work.mkdir()
    shutil.copy(ROOT / "Snakefile", work / "Snakefile")
    shutil.copytree(ROOT / "workflow", work / "workflow")
    shutil.copytree(ROOT / "config" / "campaigns", work / "config" / "campaigns")
    (work / "config" / "config.yaml").write_text(CONFIG, encoding="utf-8")
    return work


def test_stage_settings_on_the_command_line_through_snakemake(tmp_path):
    """Snakemake hands nested --config values over as text: valid ones are accepted, a
    model off the stage's ladder is refused in one line, before any job."""
    work = _workdir(tmp_path)
    ok = snakemake(
        work, "-n", "--config", 'stages={"SN-0042": {"tolerance_um": 3, "model": "III", "alpha": 0.1}}'
    )
    assert ok.returncode == 0, ok.stderr[-2000:]
    bad = snakemake(work, "-n", "--config", 'stages={"SN-0042": {"tolerance_um": 3, "model": "VI"}}')
    lines = [line for line in bad.stderr.splitlines() if "calflow: error" in line]
    assert bad.returncode != 0 and len(lines) == 1, bad.stderr[-2000:]
    assert "--config stages: key 'stages.SN-0042.model'" in lines[0] and "got 'VI'" in lines[0]
    assert not (work / "results").exists()


def catalogue_counts() -> dict[str, int]:
    """The catalogue's size (docs/reliability.md)."""
    return {"campaign files": len(CAMPAIGNS), "workflow configuration": len(CONFIGS)}
