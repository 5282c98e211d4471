"""The bad-input catalogue of the newest keys, written as a new user writes them: as-found
runs (``as_found:``), certificates (config ``stages.<id>``: ``specification``,
``decision_rule``, ``reliability``, ``fleet``), recorded camera frames (``format: frames``),
the simulated rig's ``sensor: images``, and the YAML and numbers around them. Each is refused
when the files are loaded — before any job — in one line naming the file, the key and what
was expected; the loaders run in-process (a dry run of the workflow calls the same ones).

:data:`CAMPAIGNS`, :data:`FRAMES` and :data:`CONFIGS` are the tables; ``ACCEPTED`` lists what
looks odd but is valid and must keep loading."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from test_bad_input_campaigns import _project, case, write_case

from calflow.campaign import load as load_campaign
from calflow.cli import main
from calflow.errors import ConfigError

CAL = "demo-sn0042-2026-01"
JUL = "demo-sn0042-2026-07"  # a recalibration with as_found through January's Model III
AF = "as_found: {reference: demo-sn0042-2026-01, model: III}"
IMAGES = "xytheta-images"

CAMPAIGNS = [
    # ---- as found
    case(
        "as_found: a model the reference does not identify",
        JUL,
        AF,
        AF.replace("III", "V"),
        "key 'as_found.model'",
        "exports (one of ['III'])",
        "got 'V'",
    ),
    case(
        "as_found: on a nano campaign",
        "nano1d-thesis",
        None,
        "stage: NX-1\nas_found: {reference: nano2d-thesis, model: III}\n",
        "unknown key 'as_found'",
    ),
    case(
        "as_found: on a hexapod",
        "hexapod-demo",
        None,
        "as_found: {reference: hexapod-demo-gcs, model: geometric}\n",
        "unknown key 'as_found'",
    ),
    case(
        "as_found: reference of no stage",
        JUL,
        AF,
        AF.replace(CAL, "xytheta-thesis"),
        "key 'as_found.reference'",
        "expected a calibration of stage 'SN-0042'",
    ),
    case(
        "as_found: reference an interim check",
        JUL,
        AF,
        AF.replace(CAL, "demo-sn0042-2026-10-check"),
        "key 'as_found.reference'",
        "itself an interim check",
    ),
    case(
        "as_found: reference starting later",
        CAL,
        "stage: SN-0042\n",
        "stage: SN-0042\nas_found: {reference: demo-sn0042-2026-07, model: III}\n",
        "key 'start'",
        "after that of its reference 'demo-sn0042-2026-07'",
    ),
    case(
        "as_found: reference itself",
        JUL,
        AF,
        AF.replace(CAL, "bad"),
        "key 'as_found.reference'",
        "this campaign itself",
    ),
    case(
        "as_found: A -> B -> A",
        JUL,
        AF,
        AF.replace(CAL, "loopb"),
        "key 'start'",
        "after that of its reference 'loopb'",
        files={"config/campaigns/loopb.yaml": "LOOP"},
    ),
    case(
        "as_found: without model",
        JUL,
        AF,
        "as_found: {reference: demo-sn0042-2026-01}",
        "key 'as_found.model': missing",
    ),
    case("as_found: a string", JUL, AF, f"as_found: {CAL}", "key 'as_found': expected a mapping"),
    case(
        "as_found: reference with a space",
        JUL,
        AF,
        AF.replace(CAL, "demo sn0042"),
        "key 'as_found.reference'",
        "U+0020 SPACE",
    ),
    case(
        "as_found: reference with '..'",
        JUL,
        AF,
        AF.replace(CAL, "../campaigns/" + CAL),
        "key 'as_found.reference'",
        "which contains '.'",
    ),
    case(
        "as_found: campaign without a stage",
        JUL,
        "stage: SN-0042\n",
        "",
        "key 'as_found': expected a campaign of a stage",
    ),
    case(
        "as_found: on an interim check",
        "demo-sn0042-2026-04-check",
        None,
        AF + "\n",
        "key 'as_found': an interim check",
    ),
    case(
        "as_found: reference not valid YAML",
        JUL,
        AF,
        AF.replace(CAL, "broken"),
        "key 'as_found.reference'",
        "broken.yaml: line 3: not valid YAML",
        files={"config/campaigns/broken.yaml": "robot: xytheta\nstage: [\n"},
    ),
    case(
        "as_found: model twice",
        JUL,
        AF,
        AF.replace("III}", "III, model: V}"),
        "key 'as_found.model' appears twice",
    ),
    # ---- the images sensor
    case(
        "images: sensor misspelt",
        IMAGES,
        "    sensor: images",
        "    sensor: image",
        "key 'rig.options.sensor'",
        "['model', 'images']",
    ),
    case(
        "images: camera a string",
        IMAGES,
        "camera: {width: 512, height: 384, magnification: 5.0}",
        "camera: basler",
        "key 'rig.options.camera'",
        "a mapping of camera-model fields",
    ),
    case(
        "images: unknown camera field",
        IMAGES,
        "magnification: 5.0}",
        "magnification: 5.0, zoom: 2}",
        "key 'rig.options.camera'",
        "camera.zoom: unknown camera-model field",
    ),
    case(
        "images: camera width 0",
        IMAGES,
        "width: 512",
        "width: 0",
        "key 'rig.options.camera'",
        "Camera.width: expected a positive integer, got 0",
    ),
    case(
        "images: camera width 512.5",
        IMAGES,
        "width: 512",
        "width: 512.5",
        "key 'rig.options.camera'",
        "got 512.5",
    ),
    case(
        "images: camera width as text",
        IMAGES,
        "width: 512",
        "width: '512'",
        "key 'rig.options.camera'",
        "got '512'",
    ),
    case(
        "images: camera width 1e308",
        IMAGES,
        "width: 512",
        "width: 1e308",
        "key 'rig.options.camera'",
        "Camera.width: expected a positive integer",
    ),
    case(
        "images: camera width true",
        IMAGES,
        "width: 512",
        "width: true",
        "key 'rig.options.camera'",
        "got True",
    ),
    case(
        "images: magnification NaN",
        IMAGES,
        "magnification: 5.0",
        "magnification: .nan",
        "key 'rig.options.camera.magnification'",
        "a finite number",
    ),
    case(
        "images: pattern file missing",
        IMAGES,
        "    camera_x_um: 300.0",
        "    camera_x_um: 300.0\n    pattern: data/nope.json",
        "key 'rig.options.pattern'",
        "an existing pattern file",
    ),
    case(
        "images: pattern file not one",
        IMAGES,
        "    camera_x_um: 300.0",
        "    camera_x_um: 300.0\n    pattern: data/p.json",
        "key 'rig.options.pattern'",
        "data/p.json: format: expected 'calflow-pattern'",
        files={"data/p.json": "{}"},
    ),
    case(
        "images: pattern file not JSON",
        IMAGES,
        "    camera_x_um: 300.0",
        "    camera_x_um: 300.0\n    pattern: data/p.json",
        "key 'rig.options.pattern'",
        "not a calflow pattern file",
        files={"data/p.json": "{no"},
    ),
    case(
        "images: pattern smaller than the rig's range",
        IMAGES,
        "    camera_x_um: 300.0",
        "    camera_x_um: 300.0\n    pattern: data/pattern.json",
        "key 'rig.options.pattern'",
        "covers the rig's pattern_range_um [9500.0, 4200.0]",
        files={"data/pattern.json": "PATTERN"},
    ),
    case(
        "images: camera too small for the pattern file",
        IMAGES,
        "    camera_x_um: 300.0",
        "    camera_x_um: 300.0\n    pattern_range_um: [1500, 1500]\n    pattern: data/pattern.json",
        "key 'rig.options.camera'",
        "needs a field of view",
        files={"data/pattern.json": "PATTERN", "SMALL_CAMERA": ""},
    ),
    case(
        "images: camera too small for the default pattern",
        IMAGES,
        "width: 512, height: 384",
        "width: 32, height: 24",
        "key 'rig.options.camera'",
        "the default pattern",
        "needs a field of view",
    ),
    # ---- YAML and numbers
    case(
        "a tab for indentation",
        CAL,
        "  factory: simulated",
        "\tfactory: simulated",
        "line 14: not valid YAML",
    ),
    case(
        "a list at the top",
        CAL,
        None,
        "",
        "<top level>: expected a mapping of keys, got list",
        files={"RAW": "- robot: xytheta\n"},
    ),
    case("an empty file", CAL, None, "", "<top level>: expected a mapping", files={"RAW": ""}),
    case(
        "a count as text",
        CAL,
        "poses: 60",
        "poses: '60'",
        "key 'identification.poses': expected an integer, got '60'",
    ),
    case(
        "a count of 1e308",
        CAL,
        "poses: 60",
        "poses: 1e308",
        "key 'identification.poses': expected an integer, got 1e+308",
    ),
    case(
        "a count of 60.0",
        CAL,
        "poses: 60",
        "poses: 60.0",
        "key 'identification.poses': expected an integer, got 60.0",
    ),
    case(
        "cycles 1e308",
        CAL,
        "  cycles: 2\n",
        "  cycles: 1e308\n",
        "key 'validation.cycles': expected an integer",
    ),
    case(
        "held-out targets 1e308",
        CAL,
        "heldout: {targets: 8",
        "heldout: {targets: 1e308",
        "key 'validation.heldout.targets': expected an integer",
    ),
    case("a seed of 1e308", CAL, "seed: 42", "seed: 1e308", "key 'seed': expected an integer"),
    case(
        "a tolerance of 1e-3 is a number",
        CAL,
        "tolerance_um: 3.5",
        "tolerance_um: -1e-3",
        "key 'tolerance_um'",
        "got -0.001",
    ),
    case("a stage id with a space", CAL, "stage: SN-0042", "stage: SN 0042", "key 'stage'", "U+0020 SPACE"),
    case(
        "a stage id with a trailing space",
        CAL,
        "stage: SN-0042",
        "stage: 'SN-0042 '",
        "key 'stage'",
        "U+0020 SPACE",
    ),
    case(
        "a stage id as a number", CAL, "stage: SN-0042", "stage: 42", "key 'stage': expected a string, got 42"
    ),
]

# ---- recorded camera frames: a replay of the images campaign's identification run
FRAMES_RIG = (
    "rig:\n  factory: replay\n  options:\n    recordings:\n      identification:\n"
    "        file: data/ident.tif\n        format: frames\n        table: data/ident.csv\n"
    "        pattern: data/pattern.json\n        camera: {width: 352, height: 272, magnification: 5.0}\n"
)
TABLE = "frame,time,cmd_x,cmd_y,cmd_theta,T1\n" + "".join(
    f"{k},{2.0 * k},{100.0 * k},{50.0 * k},{0.5 * k},21.0\n" for k in range(4)
)


def frames(name, old, new, *expected, table=TABLE, stack=4, folder=None, pattern=None):
    """A frame recording with one thing changed: the campaign's text, the table, the stack's
    page count (None: no stack), a folder of frames (file names), the pattern file's text."""
    return pytest.param(old, new, expected, table, stack, folder, pattern, id=name)


FRAMES = [
    frames(
        "frames: table missing",
        None,
        None,
        "key 'rig.options.recordings.identification.table'",
        "an existing file",
        table=None,
    ),
    frames(
        "frames: table without cmd_theta",
        None,
        None,
        "key 'rig.options.recordings.identification'",
        "data/ident.csv: joints table: column 'cmd_theta' missing",
        table=TABLE.replace("cmd_theta", "theta"),
    ),
    frames(
        "frames: table without time",
        None,
        None,
        "joints table: column 'time' missing",
        table=TABLE.replace(",time,", ",t,"),
    ),
    frames("frames: table empty", None, None, "joints table: expected a header row", table=""),
    frames(
        "frames: table of a header only",
        None,
        None,
        "expected one row per frame, got none",
        table=TABLE.splitlines()[0] + "\n",
    ),
    frames(
        "frames: a thermometer cell not a number",
        None,
        None,
        "data/ident.csv: row 2, column 'T1'",
        "expected a number, got 'warm'",
        table=TABLE.replace(",21.0\n", ",warm\n", 1),
    ),
    frames(
        "frames: 5 rows for a stack of 4",
        None,
        None,
        "data/ident.tif: TIFF stack of 4 frames",
        "the joints table has 5 rows",
        table=TABLE + "4,8.0,400,200,2.0,21.0\n",
    ),
    frames(
        "frames: stack not a TIFF", None, None, "data/ident.tif: frames: not a readable TIFF stack", stack=-1
    ),
    frames(
        "frames: stack truncated", None, None, "data/ident.tif: frames: not a readable TIFF stack", stack=-2
    ),
    frames(
        "frames: an empty folder",
        "data/ident.tif",
        "data/frames",
        "data/frames: frame 'f0.png' (table row 2): expected an image file in the folder",
        folder=[],
        table=TABLE.replace("\n0,", "\nf0.png,"),
    ),
    frames(
        "frames: a folder frame named '../x.png'",
        "data/ident.tif",
        "data/frames",
        "frame '../x.png' (table row 2): expected an image file in the folder",
        folder=["x.png"],
        table=TABLE.replace("\n0,", "\n../x.png,"),
    ),
    frames(
        "frames: pattern file missing",
        None,
        None,
        "key 'rig.options.recordings.identification.pattern'",
        "an existing file",
        pattern="",
    ),
    frames(
        "frames: pattern not JSON",
        None,
        None,
        "data/pattern.json: not a calflow pattern file",
        pattern="{not json",
    ),
    frames(
        "frames: pattern of another format",
        None,
        None,
        "data/pattern.json: format: expected 'calflow-pattern'",
        pattern='{"format": "other"}',
    ),
    frames(
        "frames: unknown camera field",
        "magnification: 5.0}",
        "magnification: 5.0, zoom: 2}",
        "camera.zoom: unknown camera-model field",
    ),
    frames("frames: camera width 0", "width: 352", "width: 0", "Camera.width: expected a positive integer"),
    frames("frames: camera width as text", "width: 352", "width: '352'", "got '352'"),
    frames(
        "frames: camera of another size than the frames",
        "width: 352",
        "width: 400",
        "data/ident.tif: page 0: expected 400 × 272 pixels",
        "got 352 × 272",
    ),
    frames(
        "frames: camera too small for the pattern",
        "width: 352, height: 272",
        "width: 64, height: 64",
        "key 'rig.options.recordings.identification'",
        "needs a field of view",
    ),
    frames(
        "frames: format misspelt",
        "format: frames",
        "format: frame",
        "key 'rig.options.recordings.identification.format'",
        "expected one of",
        "got 'frame'",
    ),
    frames(
        "frames: run id misspelt",
        "      identification:",
        "      identificaton:",
        "key 'rig.options.recordings.identificaton': expected a run this campaign acquires",
    ),
    frames(
        "frames: run id with '..'",
        "      identification:",
        "      ../identification:",
        "key 'rig.options.recordings'",
        "run ids of letters, digits",
        "got '../identification'",
    ),
]

# ---- certificates: config stages.<id>
SPEC = "stages:\n  SN-0042:\n    specification: {accuracy_um: 3.5}\n    decision_rule: non-binary\n"
CONFIG = f"campaigns: [{CAL}]\nstudies: []\n"


def stage(text: str, stage_id: str = "SN-0042") -> str:
    return CONFIG + f"stages:\n  {stage_id}:\n" + "".join(f"    {line}\n" for line in text.splitlines())


def config(name, text, *expected, campaigns=None):
    return pytest.param(text if campaigns is None else text.replace(CAL, campaigns), expected, id=name)


CONFIGS = [
    config(
        "rule unknown",
        stage("specification: {accuracy_um: 3.5}\ndecision_rule: strict"),
        "key 'stages.SN-0042.decision_rule'",
        "expected one of simple, guarded, non-binary",
        "'strict'",
    ),
    config(
        "rule capitalised",
        stage("specification: {accuracy_um: 3.5}\ndecision_rule: Guarded"),
        "key 'stages.SN-0042.decision_rule'",
        "'Guarded'",
    ),
    config(
        "rule a number",
        stage("specification: {accuracy_um: 3.5}\ndecision_rule: 1"),
        "key 'stages.SN-0042.decision_rule': expected a string",
    ),
    config(
        "guarded on a figure without U",
        stage("specification: {cv_rms_um: 3.5}\ndecision_rule: guarded"),
        "key 'stages.SN-0042.specification.cv_rms_um'",
        "computes no U",
    ),
    config(
        "xytheta: a figure in nm",
        stage("specification: {accuracy_nm: 3.5}"),
        "key 'stages.SN-0042.specification.accuracy_nm'",
        "the family does not compute",
    ),
    config("tolerance 0", stage("specification: {accuracy_um: 0}"), "expected a tolerance > 0, got 0"),
    config("tolerance negative", stage("specification: {accuracy_um: -1}"), "expected a tolerance > 0"),
    config(
        "tolerance NaN",
        stage("specification: {accuracy_um: .nan}"),
        "key 'stages.SN-0042.specification.accuracy_um': expected a finite number",
    ),
    config("tolerance inf", stage("specification: {accuracy_um: .inf}"), "expected a finite number"),
    config("tolerance as text", stage("specification: {accuracy_um: '3.5'}"), "got '3.5'"),
    config("tolerance true", stage("specification: {accuracy_um: true}"), "got True"),
    config("tolerance a list", stage("specification: {accuracy_um: [3.5]}"), "got [3.5]"),
    config(
        "specification empty",
        stage("specification: {}\ndecision_rule: guarded"),
        "key 'stages.SN-0042.specification': expected a tolerance per metric",
    ),
    config("specification a number", stage("specification: 3.5"), "specification': expected a mapping"),
    config(
        "rule without specification",
        stage("decision_rule: guarded"),
        "key 'stages.SN-0042.specification': expected a tolerance per metric",
    ),
    config(
        "reliability 1", stage("reliability: 1"), "key 'stages.SN-0042.reliability': expected a value < 1"
    ),
    config("reliability 0", stage("reliability: 0"), "key 'stages.SN-0042.reliability'"),
    config("reliability 95 (a percentage)", stage("reliability: 95"), "expected a value < 1, got 95"),
    config("reliability as text", stage("reliability: '0.95'"), "expected a number, got '0.95'"),
    config("fleet with a space", stage("fleet: XYT 200"), "key 'stages.SN-0042.fleet'", "U+0020 SPACE"),
    config("fleet with '..'", stage("fleet: ../x"), "key 'stages.SN-0042.fleet'", "which contains '/'"),
    config("fleet a number", stage("fleet: 200"), "key 'stages.SN-0042.fleet': expected a string"),
    config(
        "min_pairs 1e308", stage("min_pairs: 1e308"), "key 'stages.SN-0042.min_pairs': expected an integer"
    ),
    config("min_pairs 3.0", stage("min_pairs: 3.0"), "key 'stages.SN-0042.min_pairs': expected an integer"),
    config(
        "decision_rule twice",
        stage("specification: {accuracy_um: 3.5}\ndecision_rule: simple\ndecision_rule: guarded"),
        "key 'stages.SN-0042.decision_rule' appears twice",
    ),
    config(
        "stage id with a space",
        stage("specification: {accuracy_um: 3.5}", "SN 0042"),
        "key 'stages'",
        "U+0020 SPACE",
    ),
    config(
        "stage1d: a figure in um",
        stage("specification: {accuracy_um: 0.05}", "NX-1"),
        "key 'stages.NX-1.specification.accuracy_um'",
        "accuracy_nm",
        campaigns="nano1d-stage",
    ),
    config(
        "stage1d: guarded max_accuracy_nm",
        stage("specification: {max_accuracy_nm: 50}\ndecision_rule: guarded", "NX-1"),
        "key 'stages.NX-1.specification.max_accuracy_nm'",
        "computes no U",
        campaigns="nano1d-stage",
    ),
    config(
        "stage2d: accuracy_nm",
        stage("specification: {accuracy_nm: 50}", "NX-1"),
        "the family does not compute 'accuracy_nm'; expected one of max_accuracy_nm",
        campaigns="nano2d-stage",
    ),
    config(
        "stage2d: non-binary on max_accuracy_nm",
        stage("specification: {max_accuracy_nm: 50}\ndecision_rule: non-binary", "NX-1"),
        "the non-binary rule puts a guard band",
        campaigns="nano2d-stage",
    ),
]

# valid, if unusual: each still loads
ACCEPTED = [
    case("a byte-order mark", CAL, None, "", files={"BOM": ""}),
    case("a tolerance of 1e1", CAL, "tolerance_um: 3.5", "tolerance_um: 1e1"),
]


def _write_files(root: Path, files: dict, rendered: dict) -> None:
    for name, content in files.items():
        if name in ("RAW", "BOM", "SMALL_CAMERA"):
            continue
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        if content == "PATTERN":
            path.write_text(rendered["pattern"], encoding="utf-8")
        elif content == "LOOP":  # the other half of a cycle: July's calibration through bad.yaml
            text = (root / "config" / "campaigns" / f"{JUL}.yaml").read_text(encoding="utf-8")
            path.write_text(text.replace(AF, AF.replace(CAL, "bad")), encoding="utf-8")
        else:
            path.write_text(content, encoding="utf-8")


@pytest.fixture(scope="module")
def rendered():
    """A pattern file of 1.5 mm (its windows unchecked: nothing is decoded at load)."""
    from calflow.instruments.pattern import Pattern

    return {"pattern": json.dumps(Pattern.make(range_um=(1500.0, 1500.0), check=False).to_dict())}


def _campaign(tmp_path, monkeypatch, base, old, new, files, rendered) -> Path:
    folder = _project(tmp_path, monkeypatch)
    _write_files(tmp_path, files, rendered)
    path = write_case(folder, base, old, new, {})
    if "RAW" in files:
        path.write_text(files["RAW"], encoding="utf-8")
    if "BOM" in files:
        path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
    if "SMALL_CAMERA" in files:
        text = path.read_text(encoding="utf-8")
        path.write_text(text.replace("width: 512, height: 384", "width: 64, height: 64"), encoding="utf-8")
    return path


@pytest.mark.parametrize("base, old, new, expected, files", CAMPAIGNS)
def test_a_bad_campaign_of_the_new_keys_is_refused_at_load(
    tmp_path, monkeypatch, rendered, base, old, new, expected, files
):
    path = _campaign(tmp_path, monkeypatch, base, old, new, files, rendered)
    with pytest.raises(ConfigError) as info:
        load_campaign(path, [])
    message = str(info.value)
    assert "\n" not in message and message.startswith(("config/campaigns/", str(path))), message
    for part in expected:
        assert part in message, message


@pytest.mark.parametrize("base, old, new, expected, files", ACCEPTED)
def test_odd_but_valid_campaigns_still_load(tmp_path, monkeypatch, rendered, base, old, new, expected, files):
    path = _campaign(tmp_path, monkeypatch, base, old, new, files, rendered)
    assert load_campaign(path, [])["robot"] == "xytheta"


def _frames_project(tmp_path, monkeypatch, rendered, table, stack, folder, pattern) -> Path:
    import tifffile

    _project(tmp_path, monkeypatch)
    data = tmp_path / "data"
    data.mkdir()
    if table is not None:
        (data / "ident.csv").write_text(table, encoding="utf-8")
    if pattern != "":
        (data / "pattern.json").write_text(
            rendered["pattern"] if pattern is None else pattern, encoding="utf-8"
        )
    if stack == -1:
        (data / "ident.tif").write_text("hello\n")
    elif stack:
        tifffile.imwrite(data / "ident.tif", np.zeros((4, 272, 352), np.uint16), photometric="minisblack")
        if stack == -2:
            raw = (data / "ident.tif").read_bytes()
            (data / "ident.tif").write_bytes(raw[: len(raw) // 2])
    if folder is not None:
        (data / "frames").mkdir()
        for name in folder:
            (data / name).write_bytes(b"")  # beside the folder, not in it
    return tmp_path / "config" / "campaigns"


@pytest.mark.parametrize("old, new, expected, table, stack, folder, pattern", FRAMES)
def test_a_bad_frame_recording_is_refused_at_load(
    tmp_path, monkeypatch, rendered, old, new, expected, table, stack, folder, pattern
):
    campaigns = _frames_project(tmp_path, monkeypatch, rendered, table, stack, folder, pattern)
    text = (campaigns / f"{IMAGES}.yaml").read_text(encoding="utf-8")
    text = text[: text.index("rig:\n")] + FRAMES_RIG + text[text.index("characterisation:") :]
    if old is not None:
        assert old in text
        text = text.replace(old, new, 1)
    path = campaigns / "bad.yaml"
    path.write_text(text, encoding="utf-8")
    before = sorted(tmp_path.rglob("*"))
    with pytest.raises(ConfigError) as info:
        load_campaign(path, [])
    message = str(info.value)
    assert "\n" not in message and message.startswith(str(path)), message
    for part in expected:
        assert part in message, message
    assert sorted(tmp_path.rglob("*")) == before  # nothing written


def test_a_good_frame_recording_loads_reading_one_frame(tmp_path, monkeypatch, rendered):
    campaigns = _frames_project(tmp_path, monkeypatch, rendered, TABLE, 4, None, None)
    text = (campaigns / f"{IMAGES}.yaml").read_text(encoding="utf-8")
    text = text[: text.index("rig:\n")] + FRAMES_RIG + text[text.index("characterisation:") :]
    (campaigns / "rec.yaml").write_text(text, encoding="utf-8")
    assert load_campaign(campaigns / "rec.yaml", [])["rig"]["factory"] == "replay"


@pytest.mark.parametrize("text, expected", CONFIGS)
def test_a_bad_certificate_setting_is_refused_by_check_config(tmp_path, monkeypatch, capsys, text, expected):
    folder = _project(tmp_path, monkeypatch)
    for robot in ("nano1d", "nano2d"):  # a nano stage for each nano family's figures
        base = (folder / f"{robot}-thesis.yaml").read_text(encoding="utf-8")
        (folder / f"{robot}-stage.yaml").write_text(base + "stage: NX-1\n", encoding="utf-8")
    (tmp_path / "config" / "config.yaml").write_text(text, encoding="utf-8")
    status = main(["check-config", "config/config.yaml"])
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert status != 0 and len(err) == 1 and "config/config.yaml" in err[0], err
    for part in expected:
        assert part in err[0], err[0]


def test_the_default_certificate_settings_pass_check_config(tmp_path, monkeypatch, capsys):
    _project(tmp_path, monkeypatch)
    (tmp_path / "config" / "config.yaml").write_text(CONFIG + SPEC, encoding="utf-8")
    assert main(["check-config", "config/config.yaml"]) == 0, capsys.readouterr().err


def catalogue_counts() -> dict[str, int]:
    """The catalogue's size (docs/reliability.md)."""
    return {"campaign files": len(CAMPAIGNS), "frame recordings": len(FRAMES), "stage settings": len(CONFIGS)}


def test_the_workflow_files_and_command_line_are_read_as_calflow_reads_them(tmp_path):
    """Snakemake's own YAML reads 1e-3 as text; the checked configuration has the number."""
    import yaml

    from calflow.workflow_config import load

    path = tmp_path / "config.yaml"
    path.write_text("campaigns: [x]\nstages: {S-1: {specification: {accuracy_um: 1e-3}}}\n", encoding="utf-8")
    snakemakes = yaml.safe_load(path.read_text(encoding="utf-8"))
    assert snakemakes["stages"]["S-1"]["specification"]["accuracy_um"] == "1e-3"
    cfg = load(snakemakes, [path], {})
    assert cfg["stages"]["S-1"]["specification"]["accuracy_um"] == 0.001
    cfg = load(snakemakes, [path], {"stages": {"S-1": {"tolerance_um": "2e0"}}})
    assert cfg["stages"]["S-1"]["tolerance_um"] == 2.0


def test_a_decoded_recording_is_not_read_again_at_load(tmp_path, monkeypatch, rendered):
    """Once decoded, a no-op run reads no table nor frame (the decoding job checks changes)."""
    campaigns = _frames_project(tmp_path, monkeypatch, rendered, "", 4, None, None)  # an empty table
    text = (campaigns / f"{IMAGES}.yaml").read_text(encoding="utf-8")
    text = text[: text.index("rig:\n")] + FRAMES_RIG + text[text.index("characterisation:") :]
    (campaigns / "rec.yaml").write_text(text, encoding="utf-8")
    with pytest.raises(ConfigError, match="joints table"):
        load_campaign(campaigns / "rec.yaml", [])
    (tmp_path / "results" / "rec" / "decoded").mkdir(parents=True)
    (tmp_path / "results" / "rec" / "decoded" / "identification.nc").write_bytes(b"")
    assert load_campaign(campaigns / "rec.yaml", [])["rig"]["factory"] == "replay"
