"""What the core asks the calflow.families registry: a robot's joints and axes, a missing
family's one-line error naming its distribution, summary routing by plan, studies."""

import dataclasses

import numpy as np
import pytest
import xarray as xr
import yaml

import calflow.family as registry
from calflow.cli import main
from calflow.configuration.campaign import load as load_campaign
from calflow.data.conventions import run_variables
from calflow.errors import CalflowError, ConfigError, DataError
from calflow.family_workflow import load_study
from calflow.summary_routing import route, section_of


def _campaign(tmp_path, name="arm-demo", **keys):
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump({"robot": "tripod", **keys}))
    return path


def test_an_uninstalled_family_names_the_distribution_to_install(tmp_path):
    path = _campaign(tmp_path, distribution="calflow-tripod")
    with pytest.raises(ConfigError) as err:
        load_campaign(path)
    line = str(err.value)
    assert "\n" not in line
    assert str(path) in line and "calflow-tripod" in line and "pip install calflow-tripod" in line


def test_without_a_distribution_the_error_lists_the_installed_robots(tmp_path):
    path = _campaign(tmp_path)
    with pytest.raises(ConfigError, match=r"key 'robot': expected one of \[") as err:
        load_campaign(path)
    for robot in registry.robots():
        assert repr(robot) in str(err.value)


def test_check_config_stops_with_one_line(tmp_path, capsys):
    _campaign(tmp_path, distribution="calflow-tripod")
    config = tmp_path / "config.yaml"
    config.write_text(yaml.safe_dump({"campaigns": ["arm-demo"], "campaign_dir": str(tmp_path)}))
    assert main(["check-config", str(config)]) != 0
    err = capsys.readouterr().err.strip()
    assert "calflow-tripod" in err and len(err.splitlines()) == 1


def test_family_of_says_which_distribution_is_missing():
    with pytest.raises(CalflowError, match="'calflow-tripod' is not installed"):
        registry.family_of("tripod", "calflow-tripod")


def test_a_family_adds_its_own_axes_to_the_data_contract(monkeypatch):
    """A family's joint beyond x, y, z, theta gets cmd_/meas_/target_ variables with its units."""
    base = registry.families()[0]
    extra = dataclasses.replace(base, name="tripod", robots=("tripod",), axes={"q": ("degree", "knee angle")})
    installed = registry.families()
    monkeypatch.setattr(registry, "families", lambda: (*installed, extra))
    variables = run_variables()
    assert variables["cmd_q"][0] == "degree" and "knee angle" in variables["meas_q"][1]
    assert variables["cmd_x"][0] == "um"  # the core's own axes are unchanged


def test_section_of_prefers_the_plan_over_the_kind():
    sections = {"metrics": "all_metrics", "metrics:validation": "validation"}
    assert section_of("metrics", "validation", sections) == "validation"
    assert section_of("metrics", "training", sections) == "all_metrics"
    assert section_of("run", "training", sections) is None


def _result(path, kind, plan):
    ds = xr.Dataset({"v": ("n", np.arange(2.0))}, attrs={"calflow_kind": kind, "plan": plan})
    ds.to_netcdf(path, engine="netcdf4")
    return str(path)


def test_route_groups_files_by_section_in_order(tmp_path):
    files = [
        _result(tmp_path / f"{i}.nc", kind, plan)
        for i, (kind, plan) in enumerate([("metrics", "b"), ("model", "identification"), ("metrics", "a")])
    ]
    out = route(files, {"metrics": "metrics", "model": "models"})
    assert [p for p, _ in out["metrics"]] == [files[0], files[2]]
    assert [p for p, _ in out["models"]] == [files[1]]


def test_within_one_job_route_opens_each_file_once(tmp_path, monkeypatch):
    """The summary job's family summary and its certificate route the same files: opened once,
    each reader its own copy; outside opened_once(), every route opens again."""
    import calflow.data.io as io
    from calflow.summary_routing import already_open, opened_once

    files = [_result(tmp_path / f"{i}.nc", "metrics", "a") for i in range(2)]
    opened = []
    real = io.open_dataset
    monkeypatch.setattr(io, "open_dataset", lambda path, *a, **k: opened.append(path) or real(path, *a, **k))
    sections = {"metrics": "metrics"}
    with opened_once():
        first = route(files, sections)
        first["metrics"][0][1]["w"] = ("n", np.zeros(2))  # one reader adds a variable
        second = route(files, sections)
        assert already_open(files[1]) is not None
    assert sorted(opened) == sorted(files)
    assert "w" not in second["metrics"][0][1]  # the other reader does not see it
    assert already_open(files[1]) is None
    route(files, sections)
    assert len(opened) == 2 * len(files)


def test_route_refuses_a_file_no_section_takes(tmp_path):
    f = _result(tmp_path / "x.nc", "luts", "characterisation")
    with pytest.raises(DataError) as err:
        route([f], {"metrics": "metrics"}, "test family")
    assert f in str(err.value) and "'luts'" in str(err.value) and "\n" not in str(err.value)


def test_a_study_needs_its_base_campaign(tmp_path):
    study = tmp_path / "s.yaml"
    study.write_text(yaml.safe_dump({"seeds": 2}))
    with pytest.raises(ConfigError, match="key 'campaign'"):
        load_study(study, tmp_path)
    study.write_text(yaml.safe_dump({"campaign": "absent"}))
    with pytest.raises(ConfigError, match="expected a campaign of"):
        load_study(study, tmp_path)


def test_a_removed_name_says_what_replaced_it():
    """A family written for the argparse hooks imports calflow.family.Command: it fails
    naming the Step that replaced it, not with a bare AttributeError."""
    import calflow.family as family

    with pytest.raises(AttributeError, match=r"calflow\.step\.Step"):
        family.Command  # noqa: B018
    with pytest.raises(AttributeError, match="no attribute 'Nope'"):
        family.Nope  # noqa: B018
