"""Interim checks: a short campaign that verifies a stage through the compensation it runs."""

from __future__ import annotations

import copy
import json

import numpy as np
import pytest
import xarray as xr
import yaml
from conftest import SMALL_XYTHETA, make_workdir, snakemake
from hypothesis import given, settings
from hypothesis import strategies as st

from calflow.configuration.campaign import load as load_campaign
from calflow.errors import ConfigError
from calflow.xytheta.models.kinematics import Parameters, forward
from calflow.xytheta.plans.interim import candidates, scaled_jacobian, sensitive_poses, sensitive_targets

TOL = 20.0  # µm rms: Model II without tables errs ~7 µm rms over the workspace, more at its edges
P = Parameters(9572.9, -4367.2, 177.689, 0.015)  # about the default rig's geometry


def reference(**extra) -> dict:
    c = copy.deepcopy(SMALL_XYTHETA)
    c["models"] = {"II": c["models"]["II"]}
    c["validation"] = {
        **c["validation"],
        "cycles": 2,
        "heldout": {"targets": 6, "cycles": 2, "error_budget": False},
    }
    c["xy_tests"]["compensation"] = []
    c["observability"] = {**c["observability"], "study": False}  # a check reads no observability
    c["identification"] = {**c["identification"], "poses": 400}  # a calibration's share of rig time
    c.update({"stage": "SN-9", "start": "2026-01-05T08:00:00+00:00", **extra})
    c["rig"]["options"] = {"aging": False}
    return c


def check(ref="ref", start="2026-02-05T08:00:00+00:00", stage="SN-9", rig=None, **spec) -> dict:
    return {
        "robot": "xytheta",
        "stage": stage,
        "seed": 5,
        "start": start,
        "rig": {"factory": "simulated", "options": rig or {"aging": False}},
        "interim_check": {"reference": ref, "model": "II", **spec},
    }


def test_targets_see_the_drift_better_than_the_workspace_average():
    """The chosen targets' smallest drift visibility beats that of the whole candidate grid (a
    set of all candidates, averaged), and a target at home (J = 0) is never chosen."""
    q = candidates([0, 4000], [800, 2800], [0, 5])
    idx = sensitive_poses(q, P, 6)
    G = scaled_jacobian(q, P)
    info = np.einsum("nij,nik->njk", G, G)
    chosen = np.linalg.eigvalsh(info[idx].mean(axis=0))[0]
    average = np.linalg.eigvalsh(info.mean(axis=0))[0]
    assert chosen > 1.5 * average
    assert len(set(idx.tolist())) == 6


@settings(max_examples=25, deadline=None)
@given(
    dx=st.floats(-30, 30).filter(lambda v: abs(v) > 1),
    da=st.floats(-0.03, 0.03).filter(lambda v: abs(v) > 1e-3),
)
def test_targets_error_under_a_change_is_the_jacobian_prediction(dx, da):
    """Commanding the chosen targets' joints on a stage whose x_R and α moved reaches points off
    by J·δ to first order (Eq. 4.18): the selection's model of the error holds."""
    targets, record = sensitive_targets(P, 5, [0, 4000], [800, 2800], [0, 5])
    q = np.array(record["joints"])
    moved = Parameters(P.x_R + dx, P.y_R, P.alpha + da, P.beta)
    x0, y0 = forward(*q.T, P)
    x1, y1 = forward(*q.T, moved)
    G = scaled_jacobian(q, P)  # per unit of the default drift (20 µm, 0.01°)
    pred = G @ np.array([dx / 20.0, da / 0.01])
    assert np.allclose(np.column_stack([x1 - x0, y1 - y0]), pred, atol=1e-3 * (1 + np.abs(pred).max()))
    assert np.allclose(targets[:, :2], np.column_stack([x0, y0]))


@pytest.mark.parametrize(
    "spec,match",
    [
        (check(ref="missing"), "interim_check.reference': expected a campaign of"),
        (
            check(ref="other"),
            "interim_check.reference': expected a calibration of stage 'SN-9', got 'other' of stage 'SN-8'",
        ),
        (check(model="V"), "interim_check.model': expected one of the reference's models"),
        ({**check(), "models": {"II": {"free": ["x_R"]}}}, "models': an interim check identifies no model"),
    ],
)
def test_refuses_a_bad_reference(tmp_path, spec, match):
    (tmp_path / "ref.yaml").write_text(yaml.safe_dump(reference()))
    (tmp_path / "other.yaml").write_text(yaml.safe_dump(reference(stage="SN-8")))
    (tmp_path / "check.yaml").write_text(yaml.safe_dump(spec))
    with pytest.raises(ConfigError, match=rf"check\.yaml: key '{match}"):
        load_campaign(tmp_path / "check.yaml")


def test_workflow_passes_an_unchanged_stage_and_flags_a_remount(tmp_path):
    """A small calibration, an interim check on the unchanged stage and one after a re-mount
    (α + 0.3°, x_R + 100 µm), through the workflow: the first within tolerance, the second
    "recalibrate"; both enter the stage's history; each check costs ≤ 5 % of the calibration's
    rig time, measured from the runs' time axes."""
    remount = {"aging": False, "alpha_deg": 177.989, "x_R_um": 9672.9}
    campaigns = {
        "ref": reference(),
        "ok": check(targets=4, tolerance_um=TOL),
        "moved": check(start="2026-04-05T08:00:00+00:00", rig=remount, targets=4, cycles=6, tolerance_um=TOL),
    }
    work = make_workdir(tmp_path, campaigns)
    proc = snakemake(
        work,
        "reports/index.html",
        "reports/stages/SN-9/history.pdf",
        "reports/ok/report.pdf",
        "reports/moved/report.html",
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    ok = json.loads((work / "results/ok/summary.json").read_text())["interim_check"]
    moved = json.loads((work / "results/moved/summary.json").read_text())["interim_check"]
    assert ok["decision"] == "within tolerance", ok
    assert moved["decision"] == "recalibrate", moved
    assert ok["rms_um"] < ok["indifference_rms_um"] < moved["rms_um"]
    assert moved["rms_um"] > 2 * ok["rms_um"]  # the re-mount: ~20 µm at X = 3800 µm
    # acquired sequentially: the re-mount is plain at the first look (after two cycles of six),
    # and the rig stopped there; the run holds the visits the decision used, and no more
    assert (moved["cycles_acquired"], moved["visits"], moved["planned"]) == (2, 8, 24)
    run = xr.open_dataset(work / "results/moved/runs/interim_check.nc")
    assert run.sizes["sample"] == 1 + moved["visits"]
    assert ok["planned"] == 4 * ok["cycles"] and ok["visits"] == 4 * ok["cycles_acquired"]
    assert xr.open_dataset(work / "results/ok/runs/interim_check.nc").sizes["sample"] == 1 + ok["visits"]
    for k in (ok, moved):
        assert 0 < k["rig_time_s"] <= 0.05 * k["reference_rig_time_s"]
        assert k["rig_time_ratio"] == pytest.approx(k["rig_time_s"] / k["reference_rig_time_s"])
        assert "identification" in k["reference_runs"] and "export_II" in k["reference_runs"]
    assert not (work / "results/ok/runs/identification.nc").exists()  # a check identifies nothing
    h = json.loads((work / "results/stages/SN-9/history.json").read_text())
    kinds = {c["campaign"]: c["kind"] for c in h["campaigns"]}
    assert kinds == {"ref": "calibration", "ok": "interim", "moved": "interim"}
    assert h["campaigns"][2]["decision"] == "recalibrate"
    assert h["charts"]["accuracy_um"]["II"]["campaigns"] == ["ref"]  # limits: the calibrations'
    html = (work / "reports/moved/report.html").read_text()
    assert 'data-key="interim_check.decision"><strong>recalibrate' in html
    assert (work / "reports/ok/report.pdf").read_bytes()[:4] == b"%PDF"


@settings(max_examples=50, deadline=None)
@given(r0=st.floats(0.2, 5.0), ratio=st.floats(1.2, 10.0))
def test_indifference_point_zeroes_the_expected_ratio(r0, ratio):
    """At the indifference rms the mean log-likelihood ratio of a visit (errors N(0, σ² I₂),
    |e|² averaging r²) is zero, and it lies between H0 and H1."""
    from calflow.lifecycle.decisions.sprt import SPRT
    from calflow.xytheta.report.interim import indifference_rms_um

    r1 = r0 * ratio
    r = indifference_rms_um(r0, r1)
    test = SPRT(r0, r1)
    e = np.array([[r, 0.0]])  # |e|² = r²: the llr is linear in |e|², so this is its mean
    assert abs(test.llr(e)[0]) < 1e-9 * (1 + abs(test.llr(np.array([[r1, 0.0]]))[0]))
    assert r0 < r < r1


def test_a_calibration_without_models_is_refused(tmp_path):
    c = reference()
    del c["models"]
    (tmp_path / "cal.yaml").write_text(yaml.safe_dump(c))
    with pytest.raises(ConfigError, match=r"cal\.yaml: key 'models': missing"):
        load_campaign(tmp_path / "cal.yaml")
