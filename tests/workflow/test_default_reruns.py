"""What the default run does again: nothing after itself, only validation's jobs after a validation
change, a recalibration's as-found run after its reference changes; and `snakemake --report`
packs it (the run: tests/conftest.py, ``thesis_run``)."""

import re

from conftest import snakemake

CAMPAIGN = "xytheta-thesis"


def test_rerun_has_nothing_to_do(thesis_run):
    proc = snakemake(thesis_run, "-n", "--config", "studies=[]")
    assert proc.returncode == 0
    assert "Nothing to be done" in proc.stdout + proc.stderr


def test_validation_change_reruns_only_validation_metrics_and_report(thesis_run, tmp_path):
    import shutil

    import yaml

    work = tmp_path / "copy"
    shutil.copytree(thesis_run, work, symlinks=True)
    path = work / f"config/campaigns/{CAMPAIGN}.yaml"
    c = yaml.safe_load(path.read_text())
    c["validation"]["cycles"] = 5
    path.write_text(yaml.safe_dump(c))
    proc = snakemake(work, "-n", "--quiet", "rules", "--config", "studies=[]")
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout + proc.stderr
    jobs = dict(re.findall(r"^(\w+)\s+(\d+)\s*$", out, re.M))
    n = len(c["models"])
    assert jobs.pop("acquire_validation_model") == str(n) and jobs.pop("metrics") == str(n)
    assert jobs.pop("summarise") == "1" and jobs.pop("report") == "1" and jobs.pop("index") == "1"
    assert jobs.pop("certificate") == "1"  # the certificate is made from the summary
    jobs.pop("total", None), jobs.pop("all", None)
    assert jobs == {}, f"only validation, its metrics and the report rerun, not {jobs}"


def test_a_new_calibration_reruns_the_recalibrations_as_found_run(thesis_run, tmp_path):
    """The as-found run of a recalibration reads its reference's export: changing the
    reference's identification reruns it and what reads it, not the recalibration's own
    open-loop runs, and the DAG builds (an order-only input of those runs made Snakemake
    refuse it: a group job waiting on a job outside that waits on one inside)."""
    import shutil

    import yaml

    work = tmp_path / "copy"
    shutil.copytree(thesis_run, work, symlinks=True)
    recal = next(
        p
        for p in sorted((work / "config/campaigns").glob("*.yaml"))
        if "as_found" in yaml.safe_load(p.read_text())
    )
    reference = yaml.safe_load(recal.read_text())["as_found"]["reference"]
    path = work / f"config/campaigns/{reference}.yaml"
    c = yaml.safe_load(path.read_text())
    c["identification"]["poses"] += 1
    path.write_text(yaml.safe_dump(c))
    proc = snakemake(work, "-n", "--config", "studies=[]")
    assert proc.returncode == 0, proc.stderr[-2000:]
    out = proc.stdout + proc.stderr
    made = set(re.findall(r"^\s*output: (.*)$", out, re.M))
    made = {f for line in made for f in line.split(", ")}
    assert f"results/{recal.stem}/runs/as_found.nc" in made
    assert any(f.startswith(f"results/{reference}/models/") for f in made)
    assert f"results/{recal.stem}/runs/identification.nc" not in made  # it reads nothing of it


def test_snakemake_report_packs_the_campaign_reports(thesis_run, tmp_path):
    """`snakemake --report` gives a self-contained report with each campaign's outputs and captions."""
    import zipfile

    out = tmp_path / "report.zip"
    proc = snakemake(thesis_run, "--report", str(out), "--config", "studies=[]")
    assert proc.returncode == 0, proc.stderr[-3000:]
    with zipfile.ZipFile(out) as z:
        names = z.namelist()
        main = z.read(next(n for n in names if n.endswith("/report.html") and "/data/" not in n)).decode()
    packed = {n.rsplit("/", 1)[-1] for n in names if "/data/raw/" in n}
    assert {"report.html", "report.pdf", "summary.json", "index.html"} <= packed
    assert "Campaign reports" in main and "Summaries" in main
    assert "machine-readable" in main  # a caption from workflow/report/
