"""The bad-input catalogue of the newest keys, written as a new user writes them: as-found
runs (``as_found:``) and the YAML and numbers around them; the simulated rig's
``sensor: images`` and recorded camera frames (``format: frames``) are in
``test_bad_input_round_images.py``, certificates (config ``stages.<id>``) in
``test_bad_input_round_certificates.py``. Each is refused when the files are loaded — before
any job — in one line naming the file, the key and what was expected; the loaders run
in-process (a dry run of the workflow calls the same ones).

:data:`CAMPAIGNS` is the table; ``ACCEPTED`` lists what looks odd but is valid and must keep
loading."""

from __future__ import annotations

import functools
import json
from pathlib import Path

import pytest
from test_bad_input_campaigns import _project, case, write_case

from calflow.configuration.campaign import load as load_campaign
from calflow.errors import ConfigError

CAL = "demo-sn0042-2026-01"
JUL = "demo-sn0042-2026-07"  # a recalibration with as_found through January's Model III
AF = "as_found: {reference: demo-sn0042-2026-01, model: III}"

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

# valid, if unusual: each still loads
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


@functools.cache
def pattern_file_text() -> str:
    """A pattern file of 1.5 mm (its windows unchecked: nothing is decoded at load)."""
    from calflow.instruments.pattern import Pattern

    return json.dumps(Pattern.make(range_um=(1500.0, 1500.0), check=False).to_dict())


@pytest.fixture(scope="module")
def rendered():
    return {"pattern": pattern_file_text()}


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


def assert_refused_at_load(path: Path, expected) -> None:
    """The campaign file is refused in one line naming it, with every part of ``expected``."""
    with pytest.raises(ConfigError) as info:
        load_campaign(path, [])
    message = str(info.value)
    assert "\n" not in message and message.startswith(("config/campaigns/", str(path))), message
    for part in expected:
        assert part in message, message


@pytest.mark.parametrize("base, old, new, expected, files", CAMPAIGNS)
def test_a_bad_campaign_of_the_new_keys_is_refused_at_load(
    tmp_path, monkeypatch, rendered, base, old, new, expected, files
):
    assert_refused_at_load(_campaign(tmp_path, monkeypatch, base, old, new, files, rendered), expected)


@pytest.mark.parametrize("base, old, new, expected, files", ACCEPTED)
def test_odd_but_valid_campaigns_still_load(tmp_path, monkeypatch, rendered, base, old, new, expected, files):
    path = _campaign(tmp_path, monkeypatch, base, old, new, files, rendered)
    assert load_campaign(path, [])["robot"] == "xytheta"


def catalogue_counts() -> dict[str, int]:
    """The catalogue's size over the three files of this round (docs/reliability.md)."""
    from test_bad_input_round_certificates import CONFIGS
    from test_bad_input_round_images import FRAMES, IMAGE_CAMPAIGNS

    return {
        "campaign files": len(CAMPAIGNS) + len(IMAGE_CAMPAIGNS),
        "frame recordings": len(FRAMES),
        "stage settings": len(CONFIGS),
    }
