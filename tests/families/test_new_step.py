"""A new step needs one declaration and one function: a family written here (over the test
family of tests/toystage) declares ``calflow hello`` — its option, the campaign key it reads,
the file it writes — and a rule that runs it; the command line runs it, and so does the
workflow, its job handed exactly the sections the step declares, with no edit to calflow."""

from __future__ import annotations

import json
import os
import textwrap
from pathlib import Path

import pytest
import yaml
from conftest import make_workdir, snakemake

import calflow.family as registry
import calflow.steps
from calflow.cli import main
from calflow.configuration.campaign import SectionNotHanded

TESTS = Path(__file__).resolve().parents[1]

FAMILY = """
import dataclasses

from calflow.step import Option, Step
from toystage.family import FAMILY as LINEAR

HELLO = Step(
    "hello",
    "write the campaign's seed and a greeting",
    "hellostep.run:hello",
    (
        Option("--campaign", required=True, kind="path"),
        Option("--greeting", "what to write", default="hello"),
        Option("--out", required=True, kind="path"),
    ),
    reads=("seed",),
    writes=("campaign",),
)
FAMILY = dataclasses.replace(LINEAR, commands=(HELLO,), rules=("hellostep", "hello.smk"))
"""

RUN = """
from calflow.configuration.handed import campaign_of
from calflow.data.io import write_json


def hello(args):
    c = campaign_of(args)
    write_json({"campaign": c["name"], "seed": c["seed"], "greeting": args.greeting}, args.out)
"""

RULE = """
rule hello:
    output:
        layout.campaign("{campaign}", "hello.json"),
    log:
        layout.log("{campaign}", "hello"),
    params:
        **reads("hello"),
        campaign=campaign_file,
    shell:
        "calflow hello --campaign {params.campaign} --sections {params.sections:q}"
        " --out {output} > {log} 2>&1"
"""

CAMPAIGN = {
    "robot": "linear1d",
    "seed": 11,
    "rig": {"factory": "simulated", "options": {"scale_ppm": 200.0, "offset_um": 1.5, "noise_um": 0.02}},
    "identification": {"stroke_um": 1000.0, "poses": 6},
    "validation": {"stroke_um": 800.0, "poses": 4, "cycles": 5},
}


@pytest.fixture
def hello_family(tmp_path, monkeypatch):
    """The family installed as a distribution would be: its package and its entry point."""
    site = tmp_path / "site"
    package = site / "hellostep"
    package.mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (package / "family.py").write_text(textwrap.dedent(FAMILY))
    (package / "run.py").write_text(textwrap.dedent(RUN))
    (package / "hello.smk").write_text(RULE)
    dist = site / "hellostep-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: hellostep\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text("[calflow.families]\nlinear = hellostep.family:FAMILY\n")
    monkeypatch.syspath_prepend(str(site))
    monkeypatch.syspath_prepend(str(TESTS))
    registry.families.cache_clear()
    calflow.steps.steps.cache_clear()
    yield site
    monkeypatch.undo()
    registry.families.cache_clear()
    calflow.steps.steps.cache_clear()


def test_the_command_line_runs_the_new_step(hello_family, tmp_path, capsys):
    campaign = tmp_path / "lin.yaml"
    campaign.write_text(yaml.safe_dump(CAMPAIGN))
    out = tmp_path / "hello.json"
    with pytest.raises(SystemExit):
        main(["hello", "--help"])
    assert "what to write" in capsys.readouterr().out
    assert main(["hello", "--campaign", str(campaign), "--greeting", "hi", "--out", str(out)]) == 0
    assert json.loads(out.read_text()) == {"campaign": "lin", "seed": 11, "greeting": "hi"}
    # handed only what its rule would hand it, it cannot read another section
    assert calflow.steps.step("hello").sections() == ["robot", "start", "seed"]
    out.unlink()
    assert main(["hello", "--campaign", str(campaign), "--sections", "robot,start", "--out", str(out)]) != 0
    err = capsys.readouterr().err.strip()  # one line, no traceback, nothing written
    assert err.startswith(f"calflow: error: {campaign}: calflow hello read section 'seed'"), err
    assert len(err.splitlines()) == 1 and not out.exists()
    assert issubclass(SectionNotHanded, KeyError)  # still a mapping's missing key to code that reads it


def test_a_rule_runs_the_new_step(hello_family, tmp_path):
    work = make_workdir(tmp_path, {"lin": CAMPAIGN})
    paths = [str(hello_family), str(TESTS), os.environ.get("PYTHONPATH")]
    done = snakemake(
        work,
        "results/lin/hello.json",
        env_extra={"PYTHONPATH": os.pathsep.join(filter(None, paths))},
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert json.loads((work / "results/lin/hello.json").read_text())["seed"] == 11
    # the job was handed the sections the step declares, and its digest covers them
    done = snakemake(
        work, "results/lin/hello.json", "-n", "-p", "--forceall",
        env_extra={"PYTHONPATH": os.pathsep.join(filter(None, paths))},
    )  # fmt: skip
    assert "--sections robot,start,seed " in done.stdout, done.stdout[-2000:]


def test_a_step_named_like_another_is_refused(hello_family, monkeypatch):
    import dataclasses

    from calflow.errors import CalflowError

    fam = registry.family_of("linear1d")
    clash = dataclasses.replace(fam.commands[0], name="metrics")
    monkeypatch.setattr(registry, "families", lambda: (dataclasses.replace(fam, commands=(clash,)),))
    calflow.steps.steps.cache_clear()
    with pytest.raises(
        CalflowError, match="family 'linear': step 'metrics': expected a name no other step has"
    ):
        calflow.steps.steps()
    calflow.steps.steps.cache_clear()
