"""reports/index.html as the lab's catalogue: every campaign on disk, whichever run made it,
built by ``calflow index`` over small synthetic results trees (no workflow run)."""

from __future__ import annotations

import json
import os
import re
from pathlib import Path

import pytest

from calflow.cli import main
from calflow.nano.report.reference import STAGE1D
from calflow.report.catalogue import catalogue, error_line, listing_digest

T0 = 1_780_000_000.0  # a fixed epoch (s) for file times


def _summary(name: str, robot: str = "stage1d", reference: dict | None = None, ap: float = 245.5) -> dict:
    s = {
        "campaign": name,
        "robot": robot,
        "description": f"campaign {name}",
        "rig": "replay" if reference is None else "simulated",
        "seed": 1,
        "calflow_version": __import__("calflow").__version__,
        "reference": reference or {},
        "inputs": {},
    }
    if robot == "stage1d":
        s.update(intrinsic={"accuracy_nm": ap, "repeatability_nm": 30.0}, tests={})
    else:
        s.update(models={"II": {"accuracy_um": ap, "protocol": "heldout"}})
    return s


def _touch(path: Path, t: float) -> None:
    os.utime(path, (t, t))


def put(root: Path, name: str, t: float, **kw) -> dict:
    """results/<name>/summary.json made at ``t`` and its report a minute later."""
    s = _summary(name, **kw)
    folder = root / "results" / name
    (folder / "logs").mkdir(parents=True, exist_ok=True)
    (folder / "logs" / "summarise.log").write_text("")
    (folder / "summary.json").write_text(json.dumps(s))
    report = root / "reports" / name / "report.html"
    report.parent.mkdir(parents=True, exist_ok=True)
    report.write_text("<html></html>")
    _touch(folder / "logs" / "summarise.log", t)
    _touch(folder / "summary.json", t)
    _touch(report, t + 60)
    return s


def index(root: Path, monkeypatch) -> str:
    """``calflow index`` with its defaults, run from ``root`` as from the workflow's folder."""
    monkeypatch.chdir(root)
    assert main(["index"]) == 0
    return (root / "reports" / "index.html").read_text()


def rows(html: str) -> list[tuple[str, str]]:
    """(campaign, status) of the catalogue's rows, in page order."""
    return re.findall(r'<tr class="campaign \w+" data-campaign="([^"]+)" data-status="(\w+)"', html)


def test_lists_every_campaign_on_disk_newest_first(tmp_path, monkeypatch):
    put(tmp_path, "old-run", T0)
    put(tmp_path, "thesis", T0 + 3600, reference=STAGE1D)
    put(tmp_path, "latest", T0 + 7200)
    (tmp_path / "results" / "logs").mkdir()  # the workflow's own folders are no campaigns
    (tmp_path / "results" / "stages").mkdir()
    html = index(tmp_path, monkeypatch)
    assert rows(html) == [("latest", "done"), ("thesis", "done"), ("old-run", "done")]
    assert 'href="latest/report.html"' in html and 'href="old-run/report.pdf"' in html
    # date, robot, rig and the family's headline figure on each row
    line = html[html.index('data-campaign="old-run" data-status') :].split("</tr>")[0]
    assert "stage1d" in line and "replay" in line and "intrinsic AP" in line and ">245.500<" in line
    assert "2026-" in line and "UTC" in line


def test_a_deleted_campaign_disappears_from_the_rebuilt_index(tmp_path, monkeypatch):
    put(tmp_path, "kept", T0)
    put(tmp_path, "gone", T0 + 10)
    assert [c for c, _ in rows(index(tmp_path, monkeypatch))] == ["gone", "kept"]
    for p in sorted((tmp_path / "results" / "gone").rglob("*"), reverse=True):
        p.unlink() if p.is_file() else p.rmdir()
    (tmp_path / "results" / "gone").rmdir()
    html = index(tmp_path, monkeypatch)
    assert [c for c, _ in rows(html)] == ["kept"] and "gone" not in html


def test_a_failed_campaign_shows_failed_with_its_error_line(tmp_path, monkeypatch):
    put(tmp_path, "fine", T0)
    bad = tmp_path / "results" / "broken" / "logs"
    bad.mkdir(parents=True)
    line = "calflow: error: tests/data/axis.dat: key 'recordings.metrology': expected an ISO230.dat table"
    (bad / "acquire_metrology.log").write_text(f"reading...\n{line}\n")
    _touch(bad / "acquire_metrology.log", T0 + 100)
    # a campaign that had results, then a later run of it failed: failed, with the newer error
    put(tmp_path, "rerun", T0 + 50)
    log = tmp_path / "results" / "rerun" / "logs" / "identify.log"
    log.write_text("Traceback (most recent call last):\n  File x\nValueError: singular matrix\n")
    _touch(log, T0 + 200)
    html = index(tmp_path, monkeypatch)
    assert rows(html) == [("rerun", "failed"), ("broken", "failed"), ("fine", "done")]
    assert line.replace("'", "&#39;") in html
    assert "identify.log: ValueError: singular matrix" in html
    # a log older than the summary is history, not a failure
    _touch(log, T0 + 10)
    assert ("rerun", "done") in rows(index(tmp_path, monkeypatch))


def test_error_line_is_the_one_line_calflow_writes(tmp_path):
    log = tmp_path / "x.log"
    log.write_text(
        "calflow: error: a.yaml: key 'x': expected 1\nmore\ncalflow: error: b.yaml: key 'y': expected 2\n"
    )
    assert error_line(log) == "calflow: error: b.yaml: key 'y': expected 2"
    log.write_text("all went well\n")
    assert error_line(log) is None


def test_a_report_whose_inputs_changed_says_so(tmp_path, monkeypatch):
    put(tmp_path, "steady", T0)
    s = put(tmp_path, "edited", T0 + 10)
    html = index(tmp_path, monkeypatch)
    assert html.count('class="current"') == 2 and "not current" not in html
    campaigns = tmp_path / "config" / "campaigns"
    campaigns.mkdir(parents=True)
    (campaigns / "edited.yaml").write_text("robot: stage1d\n")
    _touch(campaigns / "edited.yaml", T0 + 500)  # after its report
    (campaigns / "steady.yaml").write_text("robot: stage1d\n")
    _touch(campaigns / "steady.yaml", T0 - 500)  # before its report
    # a result file the summary was made from, changed after the report
    data = tmp_path / "results" / "edited" / "metrics.nc"
    data.write_bytes(b"old")
    s["inputs"] = {"results/edited/metrics.nc": "0" * 64}
    (tmp_path / "results" / "edited" / "summary.json").write_text(json.dumps(s))
    _touch(tmp_path / "results" / "edited" / "summary.json", T0 + 10)
    _touch(data, T0 + 600)
    html = index(tmp_path, monkeypatch)
    line = html[html.index('data-campaign="edited" data-status') :].split("</tr>")[0]
    assert "not current" in line and "edited.yaml was edited after the report" in line
    assert "results/edited/metrics.nc changed" in line
    steady = html[html.index('data-campaign="steady" data-status') :].split("</tr>")[0]
    assert 'class="current"' in steady


def test_campaigns_group_by_stage_with_their_history_link(tmp_path, monkeypatch):
    put(tmp_path, "sn1-jan", T0, robot="xytheta")
    put(tmp_path, "sn1-jul", T0 + 100, robot="xytheta")
    put(tmp_path, "loose", T0 + 50)
    hist = tmp_path / "results" / "stages" / "SN-1" / "history.json"
    hist.parent.mkdir(parents=True)
    hist.write_text(
        json.dumps(
            {
                "stage": "SN-1",
                "robot": "xytheta",
                "campaigns": [{"campaign": "sn1-jan"}, {"campaign": "sn1-jul"}],
                "changes": [],
                "due": {"date": None, "statement": "not due"},
            }
        )
    )
    html = index(tmp_path, monkeypatch)
    assert rows(html) == [("sn1-jul", "done"), ("sn1-jan", "done"), ("loose", "done")]
    assert html.index('data-stage="SN-1"') < html.index('data-campaign="sn1-jul"')
    assert 'href="stages/SN-1/history.html"' in html
    assert "Model II AP, held-out" in html


def test_only_a_campaign_that_declares_a_reference_shows_one_labelled_with_its_source(tmp_path, monkeypatch):
    put(tmp_path, "recorded-iso230", T0)
    put(tmp_path, "nano1d-thesis", T0 + 10, reference=STAGE1D)
    html = index(tmp_path, monkeypatch)
    mine = html[html.index('<section id="c-recorded-iso230"') :].split("</section>")[0]
    theirs = html[html.index('<section id="c-nano1d-thesis"') :].split("</section>")[0]
    assert 'class="ref"' not in mine and "num ref" not in mine and "Tan" not in mine and "350" not in mine
    assert STAGE1D["source"] in theirs and "≈ 350" in theirs and 'class="ref"' in theirs
    row = html[html.index('data-campaign="nano1d-thesis" data-status') :].split("</tr>")[0]
    assert STAGE1D["source"] + ": 350.000 nm" in row
    row = html[html.index('data-campaign="recorded-iso230" data-status') :].split("</tr>")[0]
    assert "Tan" not in row and 'class="ref"' not in row


def test_the_listing_digest_moves_only_with_other_campaigns_on_disk(tmp_path):
    put(tmp_path, "mine", T0)
    put(tmp_path, "other", T0 + 10)
    results = tmp_path / "results"
    before = listing_digest(results, ("mine",))
    assert [name for name, *_ in before] == ["other"]
    assert listing_digest(results, ("mine",)) == before  # nothing changed: a no-op stays one
    _touch(results / "mine" / "summary.json", T0 + 999)  # the run's own campaign: an input, not here
    assert listing_digest(results, ("mine",)) == before
    _touch(results / "other" / "logs" / "summarise.log", T0 + 999)  # another run's job, e.g. failed
    assert listing_digest(results, ("mine",)) != before
    (results / "third" / "logs").mkdir(parents=True)
    (results / "third" / "logs" / "acquire.log").write_text("")
    assert "third" in [name for name, *_ in listing_digest(results, ("mine",))]


def test_an_empty_results_folder_gives_an_empty_index(tmp_path):
    assert catalogue(tmp_path / "results", tmp_path / "reports")["groups"] == []
    out = tmp_path / "reports" / "index.html"
    assert main(["index", "--results", str(tmp_path / "results"), "--out", str(out)]) == 0
    assert "Campaigns on disk (0)" in out.read_text()


@pytest.mark.parametrize("bad", ["{not json", "[]"])
def test_a_broken_summary_shows_as_failed(tmp_path, monkeypatch, bad):
    put(tmp_path, "c", T0)
    (tmp_path / "results" / "c" / "summary.json").write_text(bad)
    html = index(tmp_path, monkeypatch)
    assert rows(html) == [("c", "failed")] and "summary.json" in html


def test_a_second_run_of_another_campaign_joins_the_index_and_a_no_op_stays_one(
    shipped_recordings_run, tmp_path
):
    """The workflow end to end on two recorded campaigns run one after the other (conftest
    ``shipped_recordings_run``): the second run's index lists the first run's campaign too, a dry run
    after it has nothing to do, and a campaign whose results are deleted leaves the index
    rebuilt by hand (in a copy of the project)."""
    import shutil
    import subprocess

    from conftest import BIN, RECORDED, snakemake

    names = RECORDED
    work = shipped_recordings_run
    html = (work / "reports" / "index.html").read_text()
    assert sorted(c for c, _ in rows(html)) == sorted(names) and all(s == "done" for _, s in rows(html))
    assert "Tan," not in html and 'class="ref"' not in html  # a lab's own axes: no thesis beside them
    for name in names:
        report = (work / "reports" / name / "report.html").read_text()
        assert 'class="num ref"' not in report and "Fig. 5.18, Table 5.2" not in report
    dry = snakemake(work, "--config", f'campaigns=["{names[1]}"]', "-n")
    assert "Nothing to be done" in dry.stdout + dry.stderr
    copy = tmp_path / "project"
    shutil.copytree(work, copy, ignore=shutil.ignore_patterns(".snakemake"))
    shutil.rmtree(copy / "results" / names[0])
    subprocess.run([str(BIN / "calflow"), "index"], cwd=copy, check=True, capture_output=True)
    assert [c for c, _ in rows((copy / "reports" / "index.html").read_text())] == [names[1]]


def test_a_stage_reads_in_the_order_of_its_campaigns_starts(tmp_path, monkeypatch):
    """Rows are dated by the campaign's start on the rig, newest first, whatever order the
    results were written in (a lab reruns an old calibration's report, a demo year is
    simulated in one afternoon); a campaign without a start is dated by its results."""
    for name, start, written in (
        ("jan", "2026-01-05T08:00:00+00:00", T0 + 300),
        ("jul", "2026-07-05T08:00:00+00:00", T0),
        ("apr", "2026-04-05T08:00:00Z", T0 + 600),
    ):
        s = put(tmp_path, name, written)
        s.update(start=start, stage="SN-1")
        (tmp_path / "results" / name / "summary.json").write_text(json.dumps(s))
        _touch(tmp_path / "results" / name / "summary.json", written)
    html = index(tmp_path, monkeypatch)
    assert [c for c, _ in rows(html)] == ["jul", "apr", "jan"]
    assert ">2026-04-05</td>" in html
