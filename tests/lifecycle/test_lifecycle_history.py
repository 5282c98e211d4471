"""A stage's history from campaign summaries, its report, and one small workflow run."""

from __future__ import annotations

import copy
import json
import re

import numpy as np
import pytest
import yaml
from conftest import SMALL_XYTHETA, make_workdir, snakemake

from calflow.lifecycle.history import build
from calflow.xytheta.report.history import history_entry as xy_entry

CORR = [[1.0, 0.0, 0.06, -0.03], [0.0, 1.0, 0.0, 0.02], [0.06, 0.0, 1.0, -0.45], [-0.03, 0.02, -0.45, 1.0]]


def xy_summary(x_R, alpha, ap):
    """The parts of an XYΘ summary.json a history reads (the names the summary writes)."""
    p = {
        "alpha_deg": {"value": alpha, "std": 0.001},
        "beta_deg": {"value": -0.13, "std": 0.002},
        "x_R_um": {"value": x_R, "std": 0.7},
        "y_R_um": {"value": 7795.8, "std": 0.7},
    }
    return {
        "robot": "xytheta",
        "models": {
            "II": {
                "parameters": p,
                "free": ["x_R", "y_R", "alpha", "beta"],
                "correlation": CORR,
                "accuracy_um": ap,
            }
        },
    }


def camp(name, start, **extra):
    return {"name": name, "robot": "xytheta", "stage": "S1", "start": start, **extra}


def test_xytheta_entry_orders_free_parameters_first():
    s = xy_summary(9572.9, 177.689, 2.0)
    s["models"]["I"] = {
        "parameters": {
            "alpha_deg": {"value": 180.0, "std": None},
            "x_R_um": {"value": 1.0, "std": 2.0},
            "y_R_um": {"value": 2.0, "std": 2.0},
        },
        "free": ["x_R", "y_R"],
        "correlation": [[1, 0], [0, 1]],
        "accuracy_um": 90.0,
    }
    e = xy_entry(s)
    assert list(e["I"]["parameters"])[:2] == ["x_R_um", "y_R_um"]
    assert list(e["II"]["parameters"]) == ["x_R_um", "y_R_um", "alpha_deg", "beta_deg"]


def test_history_flags_the_remount_not_the_recalibration():
    pairs = [
        (camp("c", "2026-07-05T08:00:00+00:00"), xy_summary(9592.9, 177.709, 2.6)),
        (camp("a", "2026-01-05T08:00:00+00:00", tolerance_um=5.0), xy_summary(9572.9, 177.689, 2.0)),
        (camp("b", "2026-04-05T08:00:00+00:00"), xy_summary(9573.3, 177.6905, 2.2)),
    ]
    h = build("S1", pairs)
    assert [c["campaign"] for c in h["campaigns"]] == ["a", "b", "c"]  # sorted by start
    assert [c["to"] for c in h["changes"]] == ["b", "c"]
    assert not h["changes"][0]["models"]["II"]["significant"]
    assert h["changes"][1]["models"]["II"]["significant"]
    assert h["segments"] == [0, 0, 1]
    assert h["due"]["tolerance_um"] == 5.0 and h["due"]["model"] == "II"
    assert h["due"]["date"] is None and "not enough history" in h["due"]["statement"]
    json.dumps(h)  # plain JSON


def check(name, start, decision, ap, reference="a"):
    return (
        camp(name, start),
        {"interim_check": {"model": "II", "accuracy_um": ap, "decision": decision, "reference": reference}},
    )


def test_segment_starts_at_the_recalibrate_check_the_next_calibration_confirms():
    """A re-mount seen first by an interim check: the new level starts at that check, not at
    the calibration that confirmed it; the charts' limits are the calibrations' alone."""
    pairs = [
        (camp("a", "2026-01-05T08:00:00+00:00"), xy_summary(9572.9, 177.689, 2.0)),
        check("a-apr", "2026-04-05T08:00:00+00:00", "within tolerance", 2.4),
        check("a-jul", "2026-07-02T08:00:00+00:00", "recalibrate", 9.0),
        (camp("c", "2026-07-05T08:00:00+00:00"), xy_summary(9592.9, 177.709, 2.6)),
    ]
    h = build("S1", pairs)
    assert h["changes"][0]["models"]["II"]["significant"]
    assert h["segments"] == [0, 0, 1, 1]
    assert h["charts"]["accuracy_um"]["II"]["campaigns"] == ["a", "c"]


def test_unconfirmed_recalibrate_check_stays_on_the_trend():
    pairs = [
        (camp("a", "2026-01-05T08:00:00+00:00"), xy_summary(9572.9, 177.689, 2.0)),
        check("a-jul", "2026-07-02T08:00:00+00:00", "recalibrate", 5.0),
        (camp("b", "2026-07-05T08:00:00+00:00"), xy_summary(9573.3, 177.6905, 2.1)),
        check("b-oct", "2026-10-02T08:00:00+00:00", "recalibrate", 5.0, reference="b"),
    ]
    h = build("S1", pairs)
    assert not h["changes"][0]["models"]["II"]["significant"]
    assert h["segments"] == [0, 0, 0, 0]


def test_history_report_ties_numbers_to_history(tmp_path):
    from calflow.data.io import jsonable
    from calflow.lifecycle.report import render

    days = ["2026-01-05", "2026-03-05", "2026-05-05", "2026-07-05", "2026-09-05"]
    pairs = [
        (camp(f"c{i}", f"{d}T08:00:00+00:00"), xy_summary(9572.9 + 0.3 * i, 177.689, 2.0 + 0.3 * i))
        for i, d in enumerate(days)
    ]
    h = jsonable(build("S1", pairs, {"tolerance_um": 4.0}))
    assert h["due"]["date"] is not None
    html, _ = render(h, "snakemake", pdf=False)
    assert f'data-key="due.date">{h["due"]["date"]}<' in html
    ap = h["campaigns"][3]["models"]["II"]["accuracy_um"]
    assert f'data-key="campaigns.3.models.II.accuracy_um">{ap:.2f}<' in html
    assert "What this history cannot tell" in html and html.count("<figure") == 3


def test_workflow_builds_a_history_from_three_campaigns(tmp_path):
    """Three tiny campaigns of one stage (the third on a re-mounted rig) through the workflow."""
    base = copy.deepcopy(SMALL_XYTHETA)
    base["models"] = {"II": base["models"]["II"]}  # one model keeps the three campaigns small
    base["validation"] = {
        **base["validation"],
        "cycles": 2,
        "heldout": {"targets": 6, "cycles": 2, "error_budget": False},
    }
    base["validation"]["targets"] = []  # the held-out validation alone: as found and as left are held out
    base["observability"] = {**base["observability"], "study": False}  # a history reads no observability
    base["xy_tests"]["compensation"] = []
    base["stage"] = "SN-7"
    base["tolerance_um"] = 50.0
    campaigns = {}
    for i, start in enumerate(["2026-01-05", "2026-04-05", "2026-07-05"]):
        c = copy.deepcopy(base)
        c["seed"] = 11 + i
        c["start"] = f"{start}T08:00:00+00:00"
        c["rig"]["options"] = (
            {"aging": False} if i < 2 else {"aging": False, "alpha_deg": 177.989, "x_R_um": 9672.9}
        )
        if i:  # a recalibration measures the stage through the compensation in use first
            c["as_found"] = {"reference": f"c{i - 1}", "model": "II"}
        campaigns[f"c{i}"] = c
    work = make_workdir(tmp_path, campaigns)
    # c0 first, as a lab's earlier calibration is on disk; then c1 on one core, as a real rig
    # takes one plan at a time: its as-found run goes first by its rule's priority
    assert snakemake(work, "--config", 'campaigns=["c0"]').returncode == 0
    plan = snakemake(work, "-n", "results/c1/summary.json").stdout
    priority, rule = {}, None
    for line in plan.splitlines():
        if m := re.match(r"\s*(?:local)?rule (\w+):", line):
            rule = m.group(1)
            priority.setdefault(rule, 0)
        elif m := re.match(r"\s*priority: (-?\d+)", line):
            priority[rule] = int(m.group(1))
    acquisitions = {r: n for r, n in priority.items() if r.startswith("acquire") and r != "acquire_as_found"}
    assert acquisitions and priority["acquire_as_found"] > max(acquisitions.values()), priority
    proc = snakemake(work, "--cores", "1", "results/c1/summary.json")
    assert proc.returncode == 0, proc.stderr[-3000:]
    proc = snakemake(work, "reports/index.html", "reports/stages/SN-7/history.pdf")
    assert proc.returncode == 0, proc.stderr[-3000:]
    h = json.loads((work / "results/stages/SN-7/history.json").read_text())
    assert [c["campaign"] for c in h["campaigns"]] == ["c0", "c1", "c2"]
    assert h["changes"][1]["models"]["II"]["significant"]  # 0.3° and 100 µm: far beyond any σ
    assert h["due"]["tolerance_um"] == 50.0 and h["due"]["method"]
    assert np.isfinite(h["campaigns"][0]["models"]["II"]["accuracy_um"])
    assert (work / "reports/stages/SN-7/history.pdf").read_bytes()[:4] == b"%PDF"
    # as found, then as left: c1 through c0's bundle, c2 (re-mounted) through c1's
    s1 = json.loads((work / "results/c1/summary.json").read_text())
    found, left = s1["models"]["II"]["as_found"], s1["models"]["II"]["as_left"]
    assert found["reference"] == "c0" and found["date"] < left["date"]
    assert left["accuracy_um"] == s1["models"]["II"]["accuracy_um"]
    runs = work / "results/c1/runs"
    first = (runs / "as_found.nc").stat().st_mtime
    assert all(first <= f.stat().st_mtime for f in runs.glob("*.nc")), (
        "the stage is found as it was used, first"
    )
    from calflow.data.io import open_dataset

    found_m = open_dataset(work / "results/c1/metrics/as_found.nc")
    left_m = open_dataset(work / "results/c1/metrics/validation_heldout_II.nc")
    for k in ("target_x", "target_y", "target_theta"):  # the same held-out targets, in the same order
        np.testing.assert_array_equal(found_m[k].values, left_m[k].values)
    iv = h["interval"]
    assert iv["inputs"]["campaign"] == ["c1", "c2"] and iv["inputs"]["level"] == [0, 1]
    assert iv["inputs"]["days_since_adjustment"] == pytest.approx([90, 91], abs=0.01)
    # the re-mount (0.3°, 100 µm) shows as found through c1's compensation, far beyond c1's as found
    assert iv["inputs"]["as_found_minus_as_left"][1] > 10 * abs(iv["inputs"]["as_found_minus_as_left"][0])
    assert "not enough history" in h["due"]["statement"]
    assert "As found, as left" in (work / "reports/stages/SN-7/history.html").read_text()
    assert "stages/SN-7/history.html" in (work / "reports/index.html").read_text()
    yaml.safe_dump(h)


def test_nano_entry_takes_kept_coefficients_and_heldout_max_error():
    from calflow.nano.report.history import history_entry as nano_entry

    s = {
        "models": {
            "two_dof": [
                {"name": "a_1x", "value": 0.975, "std_error": 1.6e-4, "in_model": True, "unit": "1"},
                {"name": "b_3x", "value": 0.0, "std_error": 3.9e-8, "in_model": False, "unit": "um-2"},
            ]
        },
        "tests": {"single": {"heldout_max_accuracy_nm": 110.9, "max_accuracy_nm": 121.6}},
    }
    e = nano_entry(s)
    assert list(e) == ["two_dof"]
    assert e["two_dof"]["parameters"] == {"a_1x": {"value": 0.975, "std": 1.6e-4}}
    assert e["two_dof"]["accuracy_um"] == pytest.approx(0.1109)
    one = build(
        "N1",
        [
            (dict(camp("a", "2026-01-05T08:00:00+00:00"), robot="stage2d"), s),
            (dict(camp("b", "2026-02-05T08:00:00+00:00"), robot="stage2d"), s),
        ],
    )
    assert one["changes"][0]["models"]["two_dof"]["statistic"] == 0.0
