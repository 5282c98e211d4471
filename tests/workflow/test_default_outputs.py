"""The default run's outputs: summaries and reports, the index, every netCDF file through the CF
checker, every PDF's text within its page, and every job's measured memory within its rule's
declaration (the run: tests/conftest.py, ``thesis_run``)."""

import json
import re

import pytest
from conftest import ROOT

CAMPAIGN = "xytheta-thesis"


def test_run_leaves_summary_and_reports(thesis_run):
    summary = json.loads((thesis_run / f"results/{CAMPAIGN}/summary.json").read_text())
    assert list(summary["models"]) == ["I", "II", "III", "IV", "V"]
    for name in ("I", "II", "III", "IV", "V"):
        m = summary["models"][name]
        assert m["accuracy_um"] > 0 and m["repeatability_um"] > 0
        for key in ("x_R_um", "y_R_um", "alpha_deg", "beta_deg"):
            assert set(m["parameters"][key]) == {"value", "std"}
    acc = [summary["models"][k]["accuracy_um"] for k in ("I", "II", "III")]
    assert acc[1] < acc[0] / 3 and acc[2] < acc[1]
    assert summary["models"]["III"]["position_table"] and summary["models"]["IV"]["angle_table"]
    assert summary["characterisation"]["periods_um"]["xx"] == pytest.approx(400, rel=0.05)
    xy = summary["xy_tests"]["random_points"]
    assert xy["linear"]["accuracy_um"] < xy["none"]["accuracy_um"] / 5
    assert summary["observability"]["poses"][0] == 3
    assert summary["models"]["I"]["parameters"]["alpha_deg"] == {"value": 180.0, "std": None}
    assert summary["reference"]["models"]["I"]["accuracy_um"] == pytest.approx(95.980)
    assert set(summary["truth"]["parameters"]) == {"x_R_um", "y_R_um", "alpha_deg", "beta_deg"}
    html = (thesis_run / f"reports/{CAMPAIGN}/report.html").read_text()
    assert (thesis_run / f"reports/{CAMPAIGN}/report.pdf").read_bytes()[:5] == b"%PDF-"
    assert "95.980" in html and "Model II" in html
    index = (thesis_run / "reports/index.html").read_text()
    assert all(name in index for name in (CAMPAIGN, "nano1d-thesis", "nano2d-thesis"))


def test_report_headline_equals_summary(thesis_run):
    summary = json.loads((thesis_run / f"results/{CAMPAIGN}/summary.json").read_text())
    html = (thesis_run / f"reports/{CAMPAIGN}/report.html").read_text()
    cells = dict(re.findall(r'data-key="([^"]+)">([^<]+)<', html))
    assert cells, "the headline table carries data-key cells"
    for key, text in cells.items():
        value = summary
        for part in key.split("."):
            value = value[part]
        assert float(text) == pytest.approx(value, abs=5e-4), key


def test_every_netcdf_output_passes_the_cf_checker(thesis_run):
    """The IOOS compliance-checker finds no CF-1.11 error or warning in any netCDF output (XYΘ)."""
    from conftest import cf_problems

    files = sorted((thesis_run / "results" / CAMPAIGN).rglob("*.nc"))  # nano: above
    assert len(files) > 30
    assert cf_problems(files) == []


# ------------------------------------------------ stage SN-0042's year, one campaign at a time
# The lab's way (docs/lifecycle.md): after the default run, campaigns of the stage are run one


def test_no_job_uses_more_memory_than_its_rule_declares(thesis_run):
    """Every job of the default campaigns measured its own peak (calflow.footprint): each is
    within 1 GB and within its rule's declared mem_mb (and its CPU time within the declared
    runtime), so `--resources mem_mb=…` and a SLURM site that enforces memory schedule by true
    numbers (docs/cluster.md, "Job sizes")."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("job_sizes", ROOT / "benchmarks" / "job_sizes.py")
    job_sizes = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(job_sizes)
    rules = job_sizes.rule_patterns(job_sizes.rule_files())
    runs = job_sizes.measured(thesis_run / "results", rules)
    jobs = [r for rows in runs.values() for r in rows if r["source"] == "footprint"]
    assert len(jobs) > 100, "the run's jobs left no footprint records"
    assert all("mem_mb" in rules[rule] for rule in runs), [r for r in runs if "mem_mb" not in rules[r]]
    assert job_sizes.short_of(runs, rules) == []
    assert max(r["peak_mb"] for r in jobs) <= 1000


def test_no_text_of_any_default_pdf_lies_outside_its_page(thesis_run):
    """Every PDF of the default run (reports, certificates, histories), read back by
    pdfminer.six: no character past the page's edge (a wide table wraps instead)."""
    from pdf_check import outside

    pdfs = sorted(thesis_run.glob("reports/**/*.pdf"))
    assert len(pdfs) >= 21  # a report and a certificate per campaign, and the stage history
    past = {str(p.relative_to(thesis_run)): o[:3] for p in pdfs if (o := outside(p))}
    assert past == {}


def test_the_index_states_julys_as_found_and_as_left_decisions_apart(thesis_run):
    """July's recalibration of SN-0042 decided as found and as left, each labelled in its
    summary and on the index; what the stage leaves the lab with is the as-left decision."""
    s = json.loads((thesis_run / "results/demo-sn0042-2026-07/summary.json").read_text())
    cert = s["certificate"]
    assert set(cert["decisions"]) == {"as_found", "as_left"} and all(cert["decisions"].values())
    assert cert["decision"] == cert["decisions"]["as_left"]
    index = (thesis_run / "reports/index.html").read_text()
    row = index[index.index('data-campaign="demo-sn0042-2026-07"') - 400 :]
    found = re.search(r'data-key="certificate.decisions.as_found">([^<]+)<', row).group(1)
    left = re.search(
        r'data-campaign="demo-sn0042-2026-07" data-key="certificate.decision">([^<]+)<', row
    ).group(1)
    assert (found, left) == (cert["decisions"]["as_found"], cert["decisions"]["as_left"])
