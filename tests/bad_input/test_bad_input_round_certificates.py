"""Bad certificate settings (config ``stages.<id>``: ``specification``, ``decision_rule``,
``reliability``, ``fleet``), written as a new user writes them: each is refused by
``calflow check-config`` in one line naming the file, the key and what was expected
(:data:`CONFIGS`; the rest of the round: ``test_bad_input_round.py``)."""

from __future__ import annotations

import pytest
from test_bad_input_campaigns import _project, assert_refused_by_check_config

from calflow.cli import main

CAL = "demo-sn0042-2026-01"

# certificates: config stages.<id>
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


@pytest.mark.parametrize("text, expected", CONFIGS)
def test_a_bad_certificate_setting_is_refused_by_check_config(tmp_path, monkeypatch, capsys, text, expected):
    folder = _project(tmp_path, monkeypatch)
    for robot in ("nano1d", "nano2d"):  # a nano stage for each nano family's figures
        base = (folder / f"{robot}-thesis.yaml").read_text(encoding="utf-8")
        (folder / f"{robot}-stage.yaml").write_text(base + "stage: NX-1\n", encoding="utf-8")
    assert_refused_by_check_config(tmp_path, capsys, text, expected)


def test_the_default_certificate_settings_pass_check_config(tmp_path, monkeypatch, capsys):
    _project(tmp_path, monkeypatch)
    (tmp_path / "config" / "config.yaml").write_text(CONFIG + SPEC, encoding="utf-8")
    assert main(["check-config", "config/config.yaml"]) == 0, capsys.readouterr().err


def test_the_workflow_files_and_command_line_are_read_as_calflow_reads_them(tmp_path):
    """Snakemake's own YAML reads 1e-3 as text; the checked configuration has the number."""
    import yaml

    from calflow.configuration.workflow_config import load

    path = tmp_path / "config.yaml"
    path.write_text("campaigns: [x]\nstages: {S-1: {specification: {accuracy_um: 1e-3}}}\n", encoding="utf-8")
    snakemakes = yaml.safe_load(path.read_text(encoding="utf-8"))
    assert snakemakes["stages"]["S-1"]["specification"]["accuracy_um"] == "1e-3"
    cfg = load(snakemakes, [path], {})
    assert cfg["stages"]["S-1"]["specification"]["accuracy_um"] == 0.001
    cfg = load(snakemakes, [path], {"stages": {"S-1": {"tolerance_um": "2e0"}}})
    assert cfg["stages"]["S-1"]["tolerance_um"] == 2.0
