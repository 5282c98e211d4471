"""The workflow as a product: lint, formatting, a cluster executor giving the local result."""

import subprocess

import pytest
from conftest import BIN, ROOT

pytestmark = pytest.mark.process  # each test starts snakemake or snakefmt (2-6 s of CPU each)


def test_snakemake_lint_is_clean():
    proc = subprocess.run(
        [str(BIN / "snakemake"), "--lint"], cwd=ROOT, capture_output=True, text=True, timeout=300
    )
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert "Congratulations" in proc.stdout + proc.stderr


def test_snakefiles_are_snakefmt_formatted():
    from calflow.family import all_rules_files

    proc = subprocess.run(
        [str(BIN / "snakefmt"), "--check", "Snakefile", "workflow", *all_rules_files()],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]


def _jobs(*config: str) -> dict[str, int]:
    proc = subprocess.run(
        [str(BIN / "snakemake"), "-n", "--forceall", "--quiet", "rules", "--config", *config],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    import re

    return {k: int(v) for k, v in re.findall(r"^(\w+)\s+(\d+)\s*$", proc.stdout + proc.stderr, re.M)}


def test_choosing_campaigns_on_the_command_line_runs_no_study_unless_named():
    """`--config campaigns=[x]` schedules no Monte-Carlo job; naming the study schedules it."""
    jobs = _jobs('campaigns=["nano2d-thesis"]')
    assert jobs.get("summarise") == 1, jobs  # the campaign itself is scheduled
    assert not any(rule.startswith("mc_") for rule in jobs), jobs
    jobs = _jobs('campaigns=["nano2d-thesis"]', 'studies=["montecarlo-xytheta"]')
    assert jobs.get("mc_report") == 1 and jobs.get("mc_point", 0) > 0, jobs
