"""Campaign files are validated against the schema with one-line errors."""

from pathlib import Path

import pytest
import yaml

from calflow.configuration.campaign import load as load_campaign
from calflow.configuration.config import check_campaign_name, load_workflow_config
from calflow.errors import ConfigError

ROOT = Path(__file__).resolve().parents[2]


def _write(tmp_path, body, name="c1"):
    path = tmp_path / f"{name}.yaml"
    path.write_text(body if isinstance(body, str) else yaml.safe_dump(body))
    return path


def test_shipped_campaigns_are_valid():
    for path in (ROOT / "config" / "campaigns").glob("*.yaml"):
        campaign = load_campaign(path)
        assert campaign["name"] == path.stem


def test_defaults_are_filled_in(tmp_path, small_campaign):
    del small_campaign["validation"]["cycles"]
    c = load_campaign(_write(tmp_path, small_campaign))
    assert c["validation"]["cycles"] == 30
    assert c["identification"]["x_um"] == [0, 4000]
    assert c["rig"]["factory"] == "simulated"


def test_unknown_key_names_file_key_and_expected(tmp_path, small_campaign):
    small_campaign["identification"]["posses"] = 10
    path = _write(tmp_path, small_campaign)
    with pytest.raises(ConfigError) as err:
        load_campaign(path)
    msg = str(err.value)
    assert "\n" not in msg
    assert str(path) in msg and "identification.posses" in msg and "poses" in msg


def test_wrong_type_names_file_key_and_expected(tmp_path, small_campaign):
    small_campaign["validation"]["cycles"] = "thirty"
    path = _write(tmp_path, small_campaign)
    with pytest.raises(ConfigError) as err:
        load_campaign(path)
    msg = str(err.value)
    assert "\n" not in msg
    assert str(path) in msg and "validation.cycles" in msg and "integer" in msg and "thirty" in msg


def test_missing_required_key(tmp_path, small_campaign):
    del small_campaign["robot"]
    with pytest.raises(ConfigError, match="'robot': missing"):
        load_campaign(_write(tmp_path, small_campaign))


def test_yaml_is_loaded_safely(tmp_path):
    path = _write(tmp_path, "robot: !!python/object/apply:os.system ['echo pwned']\nmodels: {}\n")
    with pytest.raises(ConfigError, match="not valid YAML"):
        load_campaign(path)


@pytest.mark.parametrize("name", ["../escape", "a/b", "..", "", ".hidden", "x" * 65, "name with space"])
def test_campaign_names_cannot_escape_results(name):
    with pytest.raises(ConfigError):
        check_campaign_name(name)


def test_workflow_config_rejects_path_like_campaign_names():
    with pytest.raises(ConfigError, match="campaigns.0"):
        load_workflow_config({"campaigns": ["../../etc"]})


def test_rig_factory_must_be_a_module_callable(tmp_path, small_campaign):
    small_campaign["rig"]["factory"] = "__import__('os').system('x')"
    with pytest.raises(ConfigError, match="rig.factory"):
        load_campaign(_write(tmp_path, small_campaign))


def test_defaults_are_independent_copies_and_follow_refs(monkeypatch):
    """The default-setting validator copies each default (two campaigns never share one)
    and fills defaults behind ``$ref`` and ``additionalProperties`` too."""
    from calflow.configuration import config

    sch = {
        "$defs": {"sweep": {"type": "object", "properties": {"x_um": {"type": "array", "default": [0, 1]}}}},
        "type": "object",
        "properties": {"a": {"$ref": "#/$defs/sweep"}, "b": {"type": "object", "default": {}}},
        "additionalProperties": {"type": "object", "properties": {"n": {"type": "integer", "default": 3}}},
    }
    monkeypatch.setattr(config, "schema", lambda name: sch)
    one = config.validate({"a": {}, "extra": {}}, "toy", "toy.yaml")
    two = config.validate({"a": {}}, "toy", "toy.yaml")
    assert one == {"a": {"x_um": [0, 1]}, "b": {}, "extra": {"n": 3}}
    one["a"]["x_um"].append(2)
    assert two["a"]["x_um"] == [0, 1]
    assert sch["$defs"]["sweep"]["properties"]["x_um"]["default"] == [0, 1]


def test_an_impossible_date_names_the_key_and_the_calendar(tmp_path, small_campaign):
    small_campaign["start"] = "2026-04-31T08:00:00+02:00"
    with pytest.raises(ConfigError) as err:
        load_campaign(_write(tmp_path, small_campaign))
    msg = str(err.value)
    assert "c1.yaml: key 'start': expected a real ISO 8601 date and time" in msg
    assert "2026-04-31" in msg and "day is out of range" in msg and "\n" not in msg
