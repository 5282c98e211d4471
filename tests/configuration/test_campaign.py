"""The typed, immutable Campaign: one parse per file and process, validation resolving without
changing anything, no way to change a loaded campaign."""

from __future__ import annotations

import copy
import json
import pickle
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from calflow.configuration import campaign as campaigns
from calflow.configuration.campaign import Campaign, FrozenDict, FrozenList, Interim, freeze, load, thaw

ROOT = Path(__file__).resolve().parents[2]
FOLDER = ROOT / "config" / "campaigns"
CHECK, REFERENCE = "demo-sn0042-2026-04-check", "demo-sn0042-2026-01"


@pytest.fixture
def fresh(monkeypatch):
    """An empty cache and parse count, as in a new process."""
    monkeypatch.setattr(campaigns, "_RAW", {})
    monkeypatch.setattr(campaigns, "_LOADED", {})
    monkeypatch.setattr(campaigns, "PARSES", campaigns.Counter())
    return campaigns.PARSES


def test_an_interim_checks_job_parses_each_campaign_file_once(fresh, monkeypatch):
    """What an interim check's acquisition reads (the command's campaign with the rig
    plug-ins, its reference, its plan's files), then every check a workflow makes before any
    job (check-config: all default campaigns, stages, stage settings, certificates): each
    campaign file parsed once."""
    from calflow.cli import main
    from calflow.commands.common import campaign as command_campaign
    from calflow.family_workflow import hooks

    c = command_campaign(str(FOLDER / f"{CHECK}.yaml"), [])
    assert fresh[str((FOLDER / f"{CHECK}.yaml").resolve())] == 1
    assert fresh[str((FOLDER / f"{REFERENCE}.yaml").resolve())] == 1
    hooks(c).acquire_inputs(c, "interim_check")
    hooks(c).results_of(c)
    assert load(FOLDER / f"{CHECK}.yaml") is load(FOLDER / f"{CHECK}.yaml")
    monkeypatch.chdir(ROOT)
    assert main(["check-config", "config/config.yaml"]) in (0, None)
    assert fresh and max(fresh.values()) == 1, fresh
    assert fresh[str((FOLDER / f"{CHECK}.yaml").resolve())] == 1


def test_an_edited_file_is_parsed_again(fresh, tmp_path):
    path = tmp_path / "c.yaml"
    text = (FOLDER / "nano1d-thesis.yaml").read_text()
    path.write_text(text)
    first = load(path)
    assert load(path) is first and fresh[str(path.resolve())] == 1
    path.write_text(text + "\n# edited\n")
    second = load(path)
    assert second is not first and fresh[str(path.resolve())] == 2
    assert second.sha256 != first.sha256


def test_what_validation_resolves_is_its_own_fields():
    c = load(FOLDER / f"{CHECK}.yaml")
    assert isinstance(c, Campaign) and c.name == CHECK and c.robot == "xytheta"
    assert isinstance(c.interim, Interim) and c.interim.reference == REFERENCE
    assert c.reference is load(FOLDER / f"{REFERENCE}.yaml")
    assert c.models == {} and "models" not in c.sections  # an interim check identifies none
    assert "resolved" not in c.sections["interim_check"]  # the file's section, as written
    assert c["interim_check"]["resolved"]["runs"] == list(c.interim.runs)
    # ageing: the file's options keep `aging`, the resolved rig has the aged stage
    assert "aging" in c.sections["rig"]["options"] and "aging" not in c.rig["options"]
    assert c.rig["options"] != c.sections["rig"]["options"]
    ref = c.reference
    assert ref.interim is None and ref.reference is None and set(ref.models) == set(ref.sections["models"])


def _mutations(c):
    yield lambda: c.__setitem__("robot", "nano1d")
    yield lambda: c.__delitem__("robot")
    yield lambda: c.update(robot="x")
    yield lambda: c.setdefault("new", 1)
    yield lambda: c.pop("robot")
    yield lambda: c.clear()
    yield lambda: c["rig"].__setitem__("factory", "replay")
    yield lambda: c["rig"]["options"].update(seed=3)
    yield lambda: c["interim_check"]["resolved"]["runs"].append("x")
    yield lambda: c["interim_check"]["resolved"]["workspace"]["x_um"].__setitem__(0, 1.0)
    yield lambda: c.sections["rig"]["options"]["aging"].clear()
    yield lambda: c.interim.workspace["x_um"].append(1.0)
    yield lambda: setattr(c, "name", "other")
    yield lambda: setattr(c.interim, "model", "I")


def test_nothing_can_change_a_campaign():
    c = load(FOLDER / f"{CHECK}.yaml")
    before = json.dumps(c, sort_keys=True)
    for change in _mutations(c):
        with pytest.raises((TypeError, AttributeError)):
            change()
    assert json.dumps(c, sort_keys=True) == before
    # a copy for a variant is plain and mutable, and the campaign stays as it was
    variant = copy.deepcopy(c)
    assert type(variant) is dict and type(variant["rig"]["options"]) is dict
    variant["rig"]["options"]["seed"] = 99
    assert json.dumps(c, sort_keys=True) == before
    assert pickle.loads(pickle.dumps(c)) is c  # a worker process gets the same campaign


def test_the_families_checks_receive_a_frozen_campaign_and_return_what_they_resolve():
    from calflow.xytheta.checks import check_campaign

    c = load(FOLDER / f"{CHECK}.yaml")
    resolution = check_campaign(c.sections, c.path)
    assert resolution.interim == c.interim and resolution.models == {}


jsonish = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats(allow_nan=False) | st.text(max_size=5),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=5), inner, max_size=4),
    max_leaves=20,
)


@settings(max_examples=50, suppress_health_check=[HealthCheck.too_slow])
@given(jsonish)
def test_freeze_keeps_the_data_and_thaw_gives_it_back(value):
    frozen = freeze(value)
    assert frozen == value and thaw(frozen) == value
    assert json.dumps(frozen, sort_keys=True) == json.dumps(value, sort_keys=True)
    assert yaml.safe_dump(thaw(frozen)) == yaml.safe_dump(value)
    if isinstance(value, (dict, list)):
        assert isinstance(frozen, (FrozenDict, FrozenList))
        with pytest.raises(TypeError):
            frozen.clear()


def test_a_built_in_rig_is_validated_once_with_or_without_the_plug_ins(fresh):
    path = FOLDER / "nano1d-thesis.yaml"
    assert load(path, []) is load(path) is load(path, ["some.module"])
