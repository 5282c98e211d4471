"""The workflow as a product: lint, formatting, a cluster executor giving the local result."""

import json
import shutil
import subprocess

from conftest import BIN, ROOT, SMALL_XYTHETA, make_workdir, snakemake


def test_snakemake_lint_is_clean():
    proc = subprocess.run([str(BIN / "snakemake"), "--lint"], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert "Congratulations" in proc.stdout + proc.stderr


def test_snakefiles_are_snakefmt_formatted():
    proc = subprocess.run([str(BIN / "snakefmt"), "--check", "Snakefile", "workflow"], cwd=ROOT,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]


def test_cluster_generic_run_gives_the_local_summary(tmp_path):
    """Each job its own process through a submit script: the same summary.json, byte for byte."""
    campaign = json.loads(json.dumps(SMALL_XYTHETA))
    campaign["models"] = {k: v for k, v in campaign["models"].items() if k in ("I", "II")}
    campaign["xy_tests"] = {"compensation": []}
    env = {"SOURCE_DATE_EPOCH": "1767225600"}  # reproducible `created` attributes
    (tmp_path / "local").mkdir()
    (tmp_path / "cluster").mkdir()
    local = make_workdir(tmp_path / "local", {"c": campaign})
    cluster = make_workdir(tmp_path / "cluster", {"c": campaign})
    shutil.copytree(ROOT / "workflow" / "profiles", cluster / "workflow" / "profiles", dirs_exist_ok=True)
    a = snakemake(local, "results/c/summary.json", env_extra=env)
    assert a.returncode == 0, a.stderr[-2000:]
    b = snakemake(cluster, "results/c/summary.json", "--workflow-profile", "workflow/profiles/local-cluster",
                  env_extra=env)
    assert b.returncode == 0, b.stderr[-3000:]
    assert "cluster-generic" in b.stdout + b.stderr or (cluster / ".snakemake/local-cluster").exists()
    assert (local / "results/c/summary.json").read_bytes() == (cluster / "results/c/summary.json").read_bytes()


def _jobs(*config: str) -> dict[str, int]:
    proc = subprocess.run([str(BIN / "snakemake"), "-n", "--forceall", "--quiet", "rules", "--config", *config], cwd=ROOT,
                          capture_output=True, text=True, timeout=300)
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
