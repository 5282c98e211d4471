"""The layout of results/ and reports/ (calflow.configuration.layout): one place, names kept inside."""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import ROOT

from calflow.configuration import layout
from calflow.configuration.campaign import load as load_campaign
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


def _path_literals(path: Path, root: Path = ROOT):
    """The string literals of a .py or .smk file that spell a path of results/ or reports/ (or
    the folders themselves): ``"results/..."``, ``f"reports/..."``, ``"results"``."""
    import io
    import re
    import tokenize

    spelled = re.compile(r"""^[rRbBfFuU]*('''|\"\"\"|'|")(results|reports)(/|\1)""")
    for tok in tokenize.generate_tokens(io.StringIO(path.read_text()).readline):
        if tok.type == tokenize.STRING and spelled.match(tok.string):
            yield f"{path.relative_to(root)}:{tok.start[0]}: {tok.string[:60]}"


CODE = sorted(
    p
    for pattern in (
        "src/**/*.py",
        "src/**/*.smk",
        "plugins/*/src/**/*.py",
        "plugins/*/src/**/*.smk",
        "workflow/**/*.smk",
    )
    for p in ROOT.glob(pattern)
) + [ROOT / "Snakefile"]


def test_no_results_or_reports_path_is_spelled_outside_layout():
    """The rules (the core's, the families', the hexapod plug-in's) and the Python code name
    results/ and reports/ paths through calflow.configuration.layout only; docs, tests, comments and
    docstrings may spell them (a docstring or comment is no literal path here)."""
    assert len(CODE) > 100 and any(p.suffix == ".smk" for p in CODE)
    found = [hit for p in CODE if p.name != "layout.py" for hit in _path_literals(p)]
    assert found == []


def test_the_path_check_finds_a_spelled_path(tmp_path):
    bad = tmp_path / "rules.smk"
    bad.write_text(
        'rule x:\n    output:\n        f"results/{w.campaign}/x.nc",\n    log:\n        "reports/a"\n'
        '    params:\n        r="results",\n        ok=layout.log("{campaign}", "x"),  # not "results/x"\n'
    )
    assert len(list(_path_literals(bad, tmp_path))) == 3
