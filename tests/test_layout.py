"""The layout of results/ and reports/ (calflow.layout): one place, names kept inside."""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import ROOT

from calflow import layout
from calflow.config import load_campaign
from calflow.family_workflow import hooks


def test_paths_are_the_documented_ones():
    assert layout.run("c", "identification") == "results/c/runs/identification.nc"
    assert layout.truth("c", "validation") == "results/c/truth/validation.json"
    assert layout.model("c", "II") == "results/c/models/II.nc"
    assert layout.metrics("c", "validation_heldout_I") == "results/c/metrics/validation_heldout_I.nc"
    assert layout.luts("c") == "results/c/luts/position.nc"
    assert layout.summary("c") == "results/c/summary.json"
    assert (
        layout.report("c") == "reports/c/report.html" and layout.report("c", "pdf") == "reports/c/report.pdf"
    )
    assert layout.stage_history("SN-0042") == "reports/stages/SN-0042/history.html"
    assert layout.study_point("mc", "1-4", "0.5", 12) == "results/studies/mc/points/1-4_0.5_12.json"
    assert layout.study_page("mc") == "reports/studies/mc.html"
    # a rule's wildcard pattern is a name like another
    assert layout.run("{campaign}", "{run}") == "results/{campaign}/runs/{run}.nc"


@pytest.mark.parametrize("bad", ["", "..", "../x", "a/b", "a\\b", ".hidden", "a..b"])
def test_a_name_cannot_leave_its_folder(bad):
    for make in (lambda: layout.run(bad, "r"), lambda: layout.run("c", bad), lambda: layout.report(bad)):
        with pytest.raises(ValueError, match="one path component"):
            make()


@pytest.mark.parametrize("path", sorted((ROOT / "config" / "campaigns").glob("*.yaml")), ids=lambda p: p.stem)
def test_every_file_a_family_names_is_in_the_layout(path: Path):
    """What the families' workflows name for a campaign (results, inputs, truth) lies in
    the results folder of that campaign, or of the calibration it checks."""
    c = load_campaign(path)
    h = hooks(c)
    named = list(h.results_of(c)) + list(h.report_files(c)) + list(h.budget_files(c))
    truth = h.summary_truth(c)
    named += [truth] if isinstance(truth, str) else list(truth)
    for model in h.models(c):
        named += list(h.identify_inputs(c, model).values())
    folders = {layout.campaign(c["name"])}
    if "interim_check" in c:
        folders.add(layout.campaign(c["interim_check"]["reference"]))
    assert named
    for f in named:
        assert any(f.startswith(folder + "/") for folder in folders), f
        assert ".." not in f.split("/")
