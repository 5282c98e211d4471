"""Campaign files are validated against the schema with one-line errors."""

from pathlib import Path

import pytest
import yaml

from calflow.config import check_campaign_name, load_campaign, load_workflow_config
from calflow.errors import ConfigError

ROOT = Path(__file__).resolve().parents[1]


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
