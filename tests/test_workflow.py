"""End to end: small campaigns through Snakemake, config errors, rerun semantics."""

import json
import re

import pytest

from conftest import make_workdir, snakemake


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """A small simulated campaign run to the end once for the module."""
    from conftest import SMALL_XYTHETA

    work = make_workdir(tmp_path_factory.mktemp("wf"), {"small": SMALL_XYTHETA})  # XYΘ only: fast
    proc = snakemake(work)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return work


def test_run_leaves_summary_and_reports(finished):
    summary = json.loads((finished / "results/small/summary.json").read_text())
    assert list(summary["models"]) == ["I", "II", "III", "IV"]
    for name in ("I", "II", "III", "IV"):
        m = summary["models"][name]
        assert m["accuracy_um"] > 0 and m["repeatability_um"] > 0
        for key in ("x_R_um", "y_R_um", "alpha_deg", "beta_deg"):
            assert set(m["parameters"][key]) == {"value", "std"}
    acc = [summary["models"][k]["accuracy_um"] for k in ("I", "II", "IV")]
    assert acc[1] < acc[0] / 3 and acc[2] < acc[1]
    assert summary["models"]["III"]["position_table"] and summary["models"]["IV"]["angle_table"]
    assert summary["characterisation"]["periods_um"]["xx"] == pytest.approx(400, rel=0.05)
    xy = summary["xy_tests"]["random_points"]
    assert xy["linear"]["accuracy_um"] < xy["none"]["accuracy_um"] / 5
    assert summary["observability"]["poses"][0] == 3
    assert summary["models"]["I"]["parameters"]["alpha_deg"] == {"value": 180.0, "std": None}
    assert summary["reference"]["models"]["I"]["accuracy_um"] == pytest.approx(95.980)
    assert set(summary["truth"]["parameters"]) == {"x_R_um", "y_R_um", "alpha_deg", "beta_deg"}
    html = (finished / "reports/small/report.html").read_text()
    assert (finished / "reports/small/report.pdf").read_bytes()[:5] == b"%PDF-"
    assert "95.980" in html and "Model II" in html
    assert "small" in (finished / "reports/index.html").read_text()


def test_report_headline_equals_summary(finished):
    summary = json.loads((finished / "results/small/summary.json").read_text())
    html = (finished / "reports/small/report.html").read_text()
    cells = dict(re.findall(r'data-key="([^"]+)">([^<]+)<', html))
    assert cells, "the headline table carries data-key cells"
    for key, text in cells.items():
        value = summary
        for part in key.split("."):
            value = value[part]
        assert float(text) == pytest.approx(value, abs=5e-4), key


def test_rerun_has_nothing_to_do(finished):
    proc = snakemake(finished, "-n")
    assert proc.returncode == 0
    assert "Nothing to be done" in proc.stdout + proc.stderr


def test_validation_change_reruns_only_validation_metrics_and_report(finished, tmp_path):
    from conftest import SMALL_XYTHETA

    import shutil

    import yaml

    work = tmp_path / "copy"
    shutil.copytree(finished, work, symlinks=True)
    path = work / "config/campaigns/small.yaml"
    c = yaml.safe_load(path.read_text())
    c["validation"]["cycles"] = 5
    path.write_text(yaml.safe_dump(c))
    proc = snakemake(work, "-n", "--quiet", "rules")
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout + proc.stderr
    jobs = dict(re.findall(r"^(\w+)\s+(\d+)\s*$", out, re.M))
    n = len(SMALL_XYTHETA["models"])
    assert jobs.pop("acquire_validation_model") == str(n) and jobs.pop("metrics") == str(n)
    assert jobs.pop("summarise") == "1" and jobs.pop("report") == "1" and jobs.pop("index") == "1"
    jobs.pop("total", None), jobs.pop("all", None)
    assert jobs == {}, f"only validation, its metrics and the report rerun, not {jobs}"


def test_plugin_rig_campaign_runs_end_to_end(tmp_path):
    """A rig defined in the tests, named by rig.factory, runs through the whole workflow."""
    from conftest import SMALL_XYTHETA

    campaign = json.loads(json.dumps(SMALL_XYTHETA))
    campaign["rig"] = {"factory": "toyrigs:open_toy",
                       "options": {"x_R": 5000.0, "y_R": 3000.0, "alpha": 178.0, "beta": 0.2}}
    campaign["identification"]["initial"] = {"x_R": 5500.0, "y_R": 2500.0}
    campaign["models"] = {k: v for k, v in campaign["models"].items() if k in ("I", "II")}
    campaign["xy_tests"] = {"compensation": []}
    work = make_workdir(tmp_path, {"toy": campaign})
    proc = snakemake(work)
    assert proc.returncode == 0, proc.stderr[-3000:]
    summary = json.loads((work / "results/toy/summary.json").read_text())
    p = summary["models"]["II"]["parameters"]
    assert p["x_R_um"]["value"] == pytest.approx(5000.0, rel=1e-6)  # noise-free: exact recovery
    assert p["alpha_deg"]["value"] == pytest.approx(178.0, rel=1e-6)
    assert summary["models"]["II"]["accuracy_um"] < 1e-3
    assert "truth" not in summary


@pytest.mark.parametrize("edit,key", [
    (lambda c: c["validation"].update(cyclez=3), "validation.cyclez"),
    (lambda c: c["identification"].update(poses="many"), "identification.poses"),
])
def test_bad_campaign_stops_before_any_job(tmp_path, edit, key):
    from conftest import SMALL_XYTHETA

    campaign = json.loads(json.dumps(SMALL_XYTHETA))
    edit(campaign)
    work = make_workdir(tmp_path, {"broken": campaign})
    proc = snakemake(work)
    assert proc.returncode != 0
    lines = [line for line in proc.stderr.splitlines() if "calflow: error" in line]
    assert len(lines) == 1
    assert "config/campaigns/broken.yaml" in lines[0] and key in lines[0]
    assert not (work / "results").exists()


def test_replay_campaign_reproduces_the_recorded_analysis(finished):
    """A campaign replaying another's recordings gets the same models and metrics."""
    import shutil

    import yaml

    from conftest import SMALL_XYTHETA

    recorded = finished / "results/small/runs"
    campaign = json.loads(json.dumps(SMALL_XYTHETA))
    campaign["rig"] = {"factory": "replay", "options": {"recordings": str(recorded)}}
    path = finished / "config/campaigns/again.yaml"
    path.write_text(yaml.safe_dump(campaign))
    try:
        proc = snakemake(finished, "--config", 'campaigns=["again"]')
        assert proc.returncode == 0, proc.stderr[-3000:]
        a = json.loads((finished / "results/small/summary.json").read_text())
        b = json.loads((finished / "results/again/summary.json").read_text())
        assert a["models"] == b["models"]
        assert a["truth"] == b["truth"]
    finally:
        path.unlink()
        shutil.rmtree(finished / "results/again", ignore_errors=True)
        shutil.rmtree(finished / "reports/again", ignore_errors=True)


def test_snakemake_report_packs_the_campaign_reports(finished, tmp_path):
    """`snakemake --report` gives a self-contained report with each campaign's outputs and captions."""
    import zipfile

    out = tmp_path / "report.zip"
    proc = snakemake(finished, "--report", str(out))
    assert proc.returncode == 0, proc.stderr[-3000:]
    with zipfile.ZipFile(out) as z:
        names = z.namelist()
        main = z.read(next(n for n in names if n.endswith("/report.html") and "/data/" not in n)).decode()
    packed = {n.rsplit("/", 1)[-1] for n in names if "/data/raw/" in n}
    assert {"report.html", "report.pdf", "summary.json", "index.html"} <= packed
    assert "Campaign reports" in main and "Summaries" in main
    assert "machine-readable" in main  # a caption from workflow/report/


def test_every_netcdf_output_passes_the_cf_checker(finished):
    """The IOOS compliance-checker finds no CF-1.11 error or warning in any netCDF output (XYΘ)."""
    from conftest import cf_problems

    files = sorted((finished / "results").rglob("*.nc"))
    assert len(files) > 20
    assert cf_problems(files) == []
