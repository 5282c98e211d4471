"""A fourth family, defined in the tests (``tests/toystage``: a simulated 1-axis linear stage),
registered through an entry point as a distribution of its own would be, with no edit to
calflow's core: it keeps the contract, and a campaign of it runs acquire → identify → metrics
→ summarise → report through the same commands and the family's FamilyWorkflow."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

import calflow.family as registry
from calflow.cli import main
from calflow.configuration import layout
from calflow.configuration.campaign import load as load_campaign
from calflow.data.io import open_dataset
from calflow.family_contract import check_family
from calflow.family_workflow import hooks

TESTS = Path(__file__).resolve().parents[1]


@pytest.fixture
def linear_family(tmp_path, monkeypatch):
    """The toy family installed: its ``.dist-info`` with the ``calflow.families`` entry point."""
    site = tmp_path / "site"
    dist = site / "calflow_toystage-0.1.dist-info"
    dist.mkdir(parents=True)
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: calflow-toystage\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text("[calflow.families]\nlinear = toystage.family:FAMILY\n")
    monkeypatch.syspath_prepend(str(site))
    monkeypatch.syspath_prepend(str(TESTS))
    registry.families.cache_clear()
    yield registry.family_of("linear1d")
    monkeypatch.undo()
    registry.families.cache_clear()


def _campaign(folder: Path, **sections) -> Path:
    data = {
        "robot": "linear1d",
        "seed": 7,
        "rig": {"factory": "simulated", "options": {"scale_ppm": 200.0, "offset_um": 1.5, "noise_um": 0.02}},
        "identification": {"stroke_um": 1000.0, "poses": 6},
        "validation": {"stroke_um": 800.0, "poses": 4, "cycles": 5},
        **sections,
    }
    path = folder / "linear-demo.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_the_linear_family_registers_like_a_plugin(linear_family):
    assert linear_family.name == "linear" and linear_family.robots == ("linear1d",)
    check_family(linear_family)
    assert "linear1d" in registry.robots() and registry.joints("linear1d") == ("x",)


def test_its_campaign_is_checked_by_its_schema_and_its_check_hook(linear_family, tmp_path):
    from calflow.errors import ConfigError

    with pytest.raises(ConfigError, match="validation.stroke_um"):
        load_campaign(_campaign(tmp_path, validation={"stroke_um": 5000.0, "poses": 4, "cycles": 5}))
    with pytest.raises(ConfigError, match="identification"):
        load_campaign(_campaign(tmp_path, identification={"stroke_um": 1000.0}))


def test_a_campaign_runs_end_to_end(linear_family, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    path = str(_campaign(tmp_path))
    c = load_campaign(path)
    flow = hooks(c)
    assert list(flow.open_loop_runs) == ["identification", "validation"] and flow.models(c) == ["linear"]
    for run in flow.open_loop_runs:  # the core acquire rule's runs
        out = layout.run(c["name"], run)
        truth = layout.truth(c["name"], run)
        assert main(["acquire", "--campaign", path, "--plan", run, "--out", out, "--truth", truth]) == 0
    for model in flow.models(c):  # the core identify rule, with the family's inputs
        inputs = [a for k, v in flow.identify_inputs(c, model).items() for a in (f"--{k}", v)]
        out = layout.model(c["name"], model)
        assert main(["identify", "--campaign", path, "--model-name", model, *inputs, "--out", out]) == 0
    out = layout.metrics(c["name"], "validation")
    assert (
        main(["metrics", "--campaign", path, "--run", layout.run(c["name"], "validation"), "--out", out]) == 0
    )
    files = flow.results_of(c)
    assert main(["validate", *files]) == 0
    summary = layout.summary(c["name"]) if hasattr(layout, "summary") else f"results/{c['name']}/summary.json"
    truth = layout.truth(c["name"], "validation")
    assert main(["summarise", "--campaign", path, "--files", *files, "--truth", truth, "--out", summary]) == 0
    s = json.loads(Path(summary).read_text())
    # identification recovers the stage's scale and offset within 4 σ of the fit (noise 0.02 µm)
    x = open_dataset(layout.run(c["name"], "identification"))["cmd_x"].values
    sigma_scale_ppm = 1e6 * 0.02 / (x.std() * len(x) ** 0.5)
    assert s["model"]["scale_ppm"] == pytest.approx(200.0, abs=4 * sigma_scale_ppm)
    assert s["model"]["offset_um"] == pytest.approx(
        1.5, abs=4 * 0.02 * (1 / len(x) + x.mean() ** 2 / (len(x) * x.var())) ** 0.5
    )
    assert 0 < s["repeatability_um"] < 0.2 and s["accuracy_um"] == pytest.approx(1.5 + 200e-6 * 800, abs=0.1)
    assert open_dataset(files[0]).attrs["robot"] == "linear1d"
    html = tmp_path / "report.html"
    assert (
        main(["report", "--campaign", path, "--summary", summary, "--files", *files, "--html", str(html)])
        == 0
    )
    assert "AP" in html.read_text()
