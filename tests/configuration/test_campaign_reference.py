"""Reference values belong to campaigns: the ``reference`` key (a family's named set or a file
of values with their source), its checks, and which shipped campaigns declare one."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from calflow.configuration.campaign import load as load_campaign
from calflow.configuration.config import campaign_digest
from calflow.configuration.reference import declared, files
from calflow.errors import ConfigError
from calflow.nano.report.ordering import ordering_block
from calflow.nano.report.reference import STAGE1D, STAGE2D
from calflow.xytheta.report.reference import XYTHETA

ROOT = Path(__file__).resolve().parents[2]


def _write(tmp_path, body: dict, name="c1") -> Path:
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(body))
    return path


@pytest.mark.parametrize(
    "name, expected",
    [("xytheta-thesis", XYTHETA), ("nano1d-thesis", STAGE1D), ("nano2d-thesis", STAGE2D)],
)
def test_the_thesis_campaigns_declare_their_thesis_values(name, expected):
    c = load_campaign(ROOT / "config" / "campaigns" / f"{name}.yaml")
    assert declared(c) == expected and declared(c)["source"].startswith("Tan, Calibration")


@pytest.mark.parametrize(
    "name", ["recorded-iso230", "recorded-tracker", "hexapod-demo", "demo-sn0042-2026-01"]
)
def test_a_labs_own_campaigns_carry_no_reference(name):
    assert declared(load_campaign(ROOT / "config" / "campaigns" / f"{name}.yaml")) == {}


def test_a_file_of_reference_values_with_its_source(tmp_path, small_campaign):
    values = {
        "source": "Smith 2024, Table 3",
        "models": {"II": {"accuracy_um": 30.5}},
        "lut_compensation_um": {"square": [22, 3.5]},
    }
    (tmp_path / "ref.yaml").write_text(yaml.safe_dump(values))
    small_campaign["reference"] = {"file": str(tmp_path / "ref.yaml")}
    c = load_campaign(_write(tmp_path, small_campaign))
    assert declared(c) == values and files(c) == [str(tmp_path / "ref.yaml")]


def test_the_reference_is_no_part_of_the_data_files_digest(tmp_path, small_campaign):
    plain = load_campaign(_write(tmp_path, small_campaign))
    small_campaign["reference"] = "thesis-ch4"
    named = load_campaign(_write(tmp_path, small_campaign))
    assert campaign_digest(named) == campaign_digest(plain)
    small_campaign["seed"] = 99
    assert campaign_digest(load_campaign(_write(tmp_path, small_campaign))) != campaign_digest(plain)


@pytest.mark.parametrize(
    "content, match",
    [
        (None, r"ref\.yaml: reference file: cannot be read"),
        ("a: [1, 2\n", r"ref\.yaml: reference file: line 2: not valid YAML"),
        ("- 1\n", r"ref\.yaml: <top level>: expected a mapping with 'source'"),
        (
            "models: {I: {accuracy_um: 1}}\n",
            r"ref\.yaml: key 'source': expected the text naming the publication",
        ),
        ("source: S\n", r"ref\.yaml: <top level>: expected reference values beside 'source'"),
        (
            "source: S\nmodels: {I: {accuracy_um: big}}\n",
            r"ref\.yaml: key 'models\.I\.accuracy_um': expected a finite number",
        ),
        (
            "source: S\nparameters: {x_R_um: [1, .nan]}\n",
            r"ref\.yaml: key 'parameters.x_R_um': expected a finite number",
        ),
    ],
)
def test_a_bad_reference_file_is_one_line_naming_file_key_and_expectation(
    tmp_path, small_campaign, content, match
):
    if content is not None:
        (tmp_path / "ref.yaml").write_text(content)
    small_campaign["reference"] = {"file": str(tmp_path / "ref.yaml")}
    with pytest.raises(ConfigError, match=match) as err:
        load_campaign(_write(tmp_path, small_campaign))
    assert "\n" not in str(err.value)


@pytest.mark.parametrize(
    "value, match",
    [
        (
            "thesis-sec5.3",
            r"c1\.yaml: key 'reference': expected one of the reference sets of a xytheta campaign \['thesis-ch4'\]",
        ),
        ("no such set", r"c1\.yaml: key 'reference'"),
        ({"path": "x.yaml"}, r"c1\.yaml: .*reference"),
        (3, r"c1\.yaml: .*reference"),
    ],
)
def test_a_reference_must_be_a_set_of_the_family_or_a_file(tmp_path, small_campaign, value, match):
    small_campaign["reference"] = value
    with pytest.raises(ConfigError, match=match):
        load_campaign(_write(tmp_path, small_campaign))


def test_the_ordering_compares_with_the_reference_only_when_there_is_one():
    tests = {"single": {"max_accuracy_nm": 150.0}, "no_calibration": {"max_accuracy_nm": 900.0}}
    none = ordering_block(tests, {}, {})
    assert (
        none["agrees"] is None and "thesis" not in none["statement"] and "reference" not in none["statement"]
    )
    thesis = ordering_block(tests, {}, STAGE1D)
    assert (
        "The thesis's order: the single model (about 400 nm), no calibration (about 1000 nm) — the same."
        in (thesis["statement"])
    )
    other = ordering_block(
        tests,
        {},
        {"tests": {"single": {"max_accuracy_nm": 990.0}, "no_calibration": {"max_accuracy_nm": 10.0}}},
        "The reference's",
    )
    assert "The reference's order:" in other["statement"] and "thesis" not in other["statement"]
    assert other["agrees"] is False
