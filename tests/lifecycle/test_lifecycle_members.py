"""A stage's history from every campaign of the stage on disk, whichever run made them; the
campaigns that leave it say why (calflow.lifecycle.members, ``calflow history``)."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import pytest
import yaml
from conftest import SMALL_XYTHETA

from calflow.cli import main
from calflow.errors import ConfigError
from calflow.lifecycle.members import departed, on_disk, previous
from calflow.lifecycle.stages import stages_of

STAGE = "SN-1"


def calibration(start: str, stage: str = STAGE) -> dict:
    c = copy.deepcopy(SMALL_XYTHETA)
    c.update(stage=stage, start=start)
    return c


def cal_summary(x: float, ap: float) -> dict:
    """A calibration's summary as the XYΘ family writes the parts a history reads."""
    return {
        "robot": "xytheta",
        "models": {
            "II": {
                "free": ["x_R", "y_R"],
                "parameters": {"x_R_um": {"value": x, "std": 1.0}, "y_R_um": {"value": -4367.0, "std": 1.0}},
                "correlation": [[1.0, 0.0], [0.0, 1.0]],
                "accuracy_um": ap,
            }
        },
    }


def check_summary(start: str, ap: float, stage: str = STAGE) -> dict:
    """An interim check's summary: it records its stage and start."""
    return {
        "robot": "xytheta",
        "stage": stage,
        "start": start,
        "models": {},
        "interim_check": {"model": "II", "accuracy_um": ap, "decision": "within tolerance", "reference": "a"},
    }


@pytest.fixture
def lab(tmp_path, monkeypatch) -> Path:
    """A project folder after some runs: calibrations a and b of SN-1 with their campaign
    files, a check c whose campaign file is gone, d of no stage, e that failed before its
    summary."""
    monkeypatch.chdir(tmp_path)
    folder = tmp_path / "config" / "campaigns"
    folder.mkdir(parents=True)
    files = {
        "a": calibration("2026-01-05T08:00:00+00:00"),
        "b": calibration("2026-07-05T08:00:00+00:00"),
        "d": {**calibration("2026-02-05T08:00:00+00:00"), "stage": None},
        "e": calibration("2026-09-05T08:00:00+00:00"),
    }
    for name, body in files.items():
        (folder / f"{name}.yaml").write_text(yaml.safe_dump({k: v for k, v in body.items() if v is not None}))
    summaries = {
        "a": cal_summary(9572.0, 3.0),
        "b": cal_summary(9573.0, 3.2),
        "c": check_summary("2026-04-05T08:00:00+00:00", 2.0),
        "d": cal_summary(9574.0, 3.1),
    }
    for name, s in summaries.items():
        (tmp_path / "results" / name).mkdir(parents=True)
        (tmp_path / "results" / name / "summary.json").write_text(json.dumps(s))
    (tmp_path / "results" / "e" / "logs").mkdir(parents=True)
    (tmp_path / "results" / "e" / "logs" / "acquire.log").write_text("calflow: error: x\n")
    return tmp_path


def history(*names: str, stage: str = STAGE) -> dict:
    """``calflow history`` of ``stage`` from the summaries of ``names``, as the workflow runs it."""
    out = f"results/stages/{stage}/history.json"
    summaries = [f"results/{n}/summary.json" for n in names]
    assert main(["history", "--stage", stage, "--summaries", *summaries, "--out", out]) == 0
    return json.loads(Path(out).read_text())


def test_on_disk_finds_every_campaign_of_a_stage_whichever_run_made_it(lab):
    disk = on_disk("results", "config/campaigns")
    assert sorted(disk) == ["a", "b", "c"]  # d names no stage, e has no summary
    assert disk["a"] == {
        "stage": STAGE,
        "robot": "xytheta",
        "start": "2026-01-05T08:00:00+00:00",
        "tolerance_um": None,
        "note": None,
    }
    assert disk["c"]["start"] == "2026-04-05T08:00:00+00:00"
    assert (
        "no campaign file config/campaigns/c.yaml" in disk["c"]["note"]
        and "summary.json" in disk["c"]["note"]
    )
    assert sorted(on_disk("results", "config/campaigns", exclude=("a",))) == ["b", "c"]


def test_history_holds_every_member_in_time_order_and_notes_whence(lab):
    h = history("a", "b", "c")
    assert [c["campaign"] for c in h["campaigns"]] == ["a", "c", "b"]
    assert [c["kind"] for c in h["campaigns"]] == ["calibration", "interim", "calibration"]
    assert "note" not in h["campaigns"][0] and "summary.json recorded" in h["campaigns"][1]["note"]
    assert [(c["from"], c["to"]) for c in h["changes"]] == [("a", "b")]
    assert h["departed"] == []


def test_a_deleted_campaign_leaves_with_its_reason_and_stays_said(lab):
    first = history("a", "b", "c")
    for p in sorted((lab / "results" / "b").rglob("*"), reverse=True):
        p.unlink() if p.is_file() else p.rmdir()
    (lab / "results" / "b").rmdir()
    assert sorted(on_disk("results", "config/campaigns")) == ["a", "c"]
    h = history("a", "c")
    assert [c["campaign"] for c in h["campaigns"]] == ["a", "c"]
    assert h["departed"] == [
        {
            "campaign": "b",
            "start": first["campaigns"][2]["start"],
            "kind": "calibration",
            "reason": "results/b/summary.json is no longer on disk (its results were deleted)",
        }
    ]
    again = Path("results/stages/SN-1/history.json").read_bytes()
    history("a", "c")  # the rebuild the next run would make: the same bytes
    assert Path("results/stages/SN-1/history.json").read_bytes() == again


def test_a_campaign_filed_under_another_stage_leaves_and_one_back_rejoins(lab):
    history("a", "b", "c")
    moved = yaml.safe_load(Path("config/campaigns/b.yaml").read_text())
    Path("config/campaigns/b.yaml").write_text(yaml.safe_dump({**moved, "stage": "SN-2"}))
    assert on_disk("results", "config/campaigns")["b"]["stage"] == "SN-2"
    h = history("a", "c")
    assert (
        h["departed"][0]["campaign"] == "b" and "b.yaml now names stage 'SN-2'" in h["departed"][0]["reason"]
    )
    Path("config/campaigns/b.yaml").write_text(yaml.safe_dump(moved))
    h = history("a", "b", "c")
    assert h["departed"] == [] and len(h["campaigns"]) == 3


def test_a_campaign_without_its_file_keeps_what_the_earlier_history_knew(lab):
    history("a", "b", "c")
    Path("config/campaigns/a.yaml").unlink()
    disk = on_disk("results", "config/campaigns")
    assert disk["a"]["start"] == "2026-01-05T08:00:00+00:00" and "earlier history" in disk["a"]["note"]
    h = history("a", "b", "c")
    assert [c["campaign"] for c in h["campaigns"]] == ["a", "c", "b"]
    assert "no campaign file config/campaigns/a.yaml" in h["campaigns"][0]["note"]
    assert h["changes"][0]["models"]["II"]["dof"] == 2  # its numbers still count


def test_a_broken_member_summary_fails_in_one_line_naming_it(lab, capsys):
    Path("results/b/summary.json").write_text('{"broken')
    assert main(["history", "--stage", STAGE, "--summaries", "results/a/summary.json",
                 "results/b/summary.json", "--out", "results/stages/SN-1/history.json"]) == 2  # fmt: skip
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(
        "calflow: error: results/b/summary.json: expected a campaign's summary"
    )


def test_departed_is_a_fixed_point_of_the_history_it_writes():
    """The campaigns that left are those of the earlier history (its campaigns and those it
    said had left) that are not members now: writing the history again moves nothing."""
    earlier = {
        "campaigns": [{"campaign": "a", "start": "s1", "kind": "calibration"}],
        "departed": [{"campaign": "z", "start": "s0", "kind": "interim", "reason": "old"}],
    }
    gone = departed(STAGE, [], "nowhere", "nowhere", earlier)
    assert [g["campaign"] for g in gone] == ["z", "a"]
    assert departed(STAGE, [], "nowhere", "nowhere", {"campaigns": [], "departed": gone}) == gone
    assert departed(STAGE, ["z"], "nowhere", "nowhere", {"campaigns": [], "departed": gone}) == gone[1:]
    assert previous("nowhere/history.json") == {}


def test_the_stage_rules_cover_the_campaigns_on_disk(lab):
    run = {"n": {"name": "n", "robot": "stage1d", "stage": STAGE, "start": "2027-01-05T08:00:00+00:00"}}
    disk = on_disk("results", "config/campaigns")
    with pytest.raises(
        ConfigError, match=r"n\.yaml: key 'robot': expected 'xytheta' .*\(a, on disk\), got 'stage1d'"
    ):
        stages_of(run, "config/campaigns", disk)
    run = {"n": {"name": "n", "robot": "xytheta", "stage": STAGE, "start": "2026-07-05T09:00:00+01:00"}}
    with pytest.raises(ConfigError, match=r"n\.yaml: key 'start': .* as b, on disk"):
        stages_of(run, "config/campaigns", disk)
    run["n"]["start"] = "2027-01-05T08:00:00+00:00"
    assert stages_of(run, "config/campaigns", disk) == {STAGE: ["n"]}


def test_the_page_says_whence_a_campaign_came_and_why_one_left(lab):
    history("a", "b", "c")
    Path("config/campaigns/a.yaml").unlink()
    Path("results/b/summary.json").unlink()
    h = history("a", "c")
    assert (
        main(["history-report", "--history", "results/stages/SN-1/history.json", "--html", "page.html"]) == 0
    )
    page = Path("page.html").read_text()
    assert 'id="departed"' in page and h["departed"][0]["reason"] in page
    assert "a: no campaign file config/campaigns/a.yaml: its start and stage are those of the stage" in page
    assert "whichever run made them" in page


def test_a_stage_whose_campaigns_all_went_keeps_its_history_and_says_why(lab):
    """Every run keeps every stage's history current, as the index: the stages of campaigns
    on disk and of histories on disk; a history with no campaign left lists them as gone."""
    from calflow.lifecycle.members import histories_on_disk

    history("a", "b", "c")
    assert histories_on_disk("results", on_disk("results", "config/campaigns")) == {STAGE: "xytheta"}
    for name in ("a", "b", "c"):
        Path(f"results/{name}/summary.json").unlink()
    assert on_disk("results", "config/campaigns") == {}
    assert histories_on_disk("results", {}) == {STAGE: "xytheta"}  # from its history
    assert (
        main(["history", "--stage", STAGE, "--summaries", "--out", "results/stages/SN-1/history.json"]) == 0
    )
    h = json.loads(Path("results/stages/SN-1/history.json").read_text())
    assert h["campaigns"] == [] and h["robot"] == "xytheta"
    assert [d["campaign"] for d in h["departed"]] == ["a", "c", "b"]
    assert main(["history-report", "--history", "results/stages/SN-1/history.json", "--html", "p.html"]) == 0
    assert "no longer on disk" in Path("p.html").read_text()
