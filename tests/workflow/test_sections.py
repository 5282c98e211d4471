"""Each job is handed the campaign sections its rule digests, and reads no other.

A rule that runs ``calflow <step> --campaign FILE`` passes ``--sections`` too (common.smk
``reads``): the job sees only those sections (calflow.configuration.campaign.Campaign.only,
any other read is an error naming it), and the rule's params digest covers the same
sections, so an edit to a section a job reads reruns it and an edit to another does not.
The runs of the default campaigns (conftest ``thesis_run``) then prove the jobs read
nothing more.
"""

import json
import re
import shlex
import shutil

import yaml
from conftest import ROOT, SMALL_XYTHETA, make_workdir, snakemake


def _shell_commands(out: str) -> list[list[str]]:
    """The ``calflow`` commands of a dry run's ``--printshellcmds`` output, as argument lists."""
    found = []
    for line in out.splitlines():
        line = line.strip().removeprefix("Shell command:").strip()
        if line.startswith("calflow "):
            found.append(shlex.split(line.split(" > ", 1)[0]))
    return found


def test_every_job_that_reads_a_campaign_is_handed_its_sections(tmp_path):
    """The default campaigns' jobs, all of them scheduled (a fresh project): each that takes
    ``--campaign`` takes ``--sections``, naming sections its campaign file has."""
    work = tmp_path / "project"
    work.mkdir()
    shutil.copy(ROOT / "Snakefile", work / "Snakefile")
    shutil.copytree(ROOT / "workflow", work / "workflow")
    shutil.copytree(ROOT / "config", work / "config")
    proc = snakemake(work, "-n", "--printshellcmds", "--config", "studies=[]")
    assert proc.returncode == 0, proc.stderr[-3000:]
    commands = _shell_commands(proc.stdout + proc.stderr)
    with_campaign = [c for c in commands if "--campaign" in c]
    steps = {c[1] for c in with_campaign}
    # the core's steps and every family's own (the hexapod plug-in's too) are among them
    # (the summary and the report read the whole campaign: handed '*', all of it)
    assert {"acquire", "identify", "metrics", "summarise", "report", "certificate"} <= steps
    assert {"characterise", "export", "error-budget", "hexapod-export"} <= steps
    for c in with_campaign:
        assert "--sections" in c, f"{c[1]} is not handed its sections: {' '.join(c)}"
        handed = c[c.index("--sections") + 1].split(",")
        assert "robot" in handed, c
        campaign = yaml.safe_load((work / c[c.index("--campaign") + 1]).read_text())
        # a section the file leaves out may be read as its schema default: only known names
        assert all(re.fullmatch(r"\*|[a-z_0-9]+(\.[A-Za-z_0-9]+)?", s) for s in handed), handed
        assert set(handed) & set(campaign), (c[1], handed)


def _run_step(work, target: str, *args: str):
    return snakemake(work, target, *args, env_extra={"SOURCE_DATE_EPOCH": "1767225600"})


def test_a_rule_reruns_when_a_section_its_job_reads_changes_and_only_then(tmp_path):
    """The observability study reads the seed, the identification ranges and its own section:
    an edit to one of them reruns it (its params digest changes), an edit to the validation,
    which it does not read, leaves it done."""
    campaign = json.loads(json.dumps(SMALL_XYTHETA))
    campaign["observability"] = {"min_poses": 10, "max_poses": 20, "steps": 2, "repeats": 1}
    work = make_workdir(tmp_path, {"c": campaign})
    target = "results/c/metrics/observability.nc"
    proc = _run_step(work, target)
    assert proc.returncode == 0, proc.stderr[-3000:]
    path = work / "config/campaigns/c.yaml"

    def dry_run_after(edit) -> str:
        edited = json.loads(json.dumps(campaign))
        edit(edited)
        path.write_text(yaml.safe_dump(edited))
        proc = _run_step(work, target, "-n", "--rerun-triggers", "params")
        assert proc.returncode == 0, proc.stderr[-3000:]
        return proc.stdout + proc.stderr

    assert "Nothing to be done" in dry_run_after(lambda c: None)
    unrelated = dry_run_after(lambda c: c["validation"].update(cycles=campaign["validation"]["cycles"] + 1))
    assert "Nothing to be done" in unrelated
    for edit in (
        lambda c: c["observability"].update(repeats=2),
        lambda c: c["identification"].update(x_um=[0, 3900]),
    ):
        out = dry_run_after(edit)
        assert "rule observability" in out and "Params have changed" in out, out[-2000:]
