"""The three thesis campaigns, run in full, against the thesis's own results.

Issue 4 (XYΘ, Table 4.8) and issue 5 (nanopositioning, Sec. 5.3.3, 5.4.2). The oracle
validation below commands the targets through the simulated truth's exact inverse: it
is test-only, and measures the rig's own repeatability at the validation targets.
"""

import json
import re

import numpy as np
import pytest
from conftest import ROOT, SOURCE_DATE_EPOCH, snakemake

from calflow.nano.stage.unseen.options import TC_ERRORS

CAMPAIGN = "xytheta-thesis"

THESIS_4_8 = {"I": 95.980, "II": 34.338, "III": 26.461, "IV": 2.838, "V": 2.568}


@pytest.fixture(scope="module")
def thesis(thesis_run):
    summaries = {
        name: json.loads((thesis_run / f"results/{name}/summary.json").read_text())
        for name in ("xytheta-thesis", "nano1d-thesis", "nano2d-thesis")
    }
    summaries["work"] = thesis_run
    return summaries


def test_exported_files_reproduce_the_models_in_closed_loop(thesis):
    """Issue 16: every model's bundle, the LinuxCNC and TwinCAT files of the models with a
    position table, read back by their loaders; the held-out targets commanded through the
    bundle agree with the in-process model within the repeatability for Models III–V, and the
    report shows both accuracies side by side (docs/export.md). Before the CF-checker tests:
    after the compliance checker has opened every output, netCDF4 segfaults opening a model
    file's groups in the same process (calflow.data.io.group_names)."""
    from calflow.xytheta.export import Compensator
    from calflow.xytheta.export.controllers import read_linuxcnc, read_twincat
    from calflow.xytheta.models.ladder import MicroModel

    s, work = thesis[CAMPAIGN], thesis["work"]
    for name, m in s["models"].items():
        folder = work / f"results/{CAMPAIGN}/export/{name}"
        e = m["export"]
        assert e["command_difference_um"] == 0.0
        assert e["in_process_accuracy_um"] == m["accuracy_um"]
        assert abs(e["accuracy_um"] - e["in_process_accuracy_um"]) <= e["max_barycentre_shift_um"] + 1e-9
        model = MicroModel.read(work / f"results/{CAMPAIGN}/models/{name}.nc")
        t = np.array([[p["x_um"], p["y_um"], p["theta_deg"]] for p in m["per_target"]])
        assert np.array_equal(Compensator.load(folder).joints(*t.T)[0], model.inverse(*t.T)[0])
        has_files = (folder / "linuxcnc_x.comp").exists()
        assert has_files == m["position_table"] == bool(e["controllers"])
        if has_files:
            assert read_linuxcnc(folder / "linuxcnc_y.comp", "y").nominal.size <= 256
            assert read_twincat(folder / "twincat_x_ssfk.lis")[1] == 1
            assert set(e["controllers"]) == {"linuxcnc", "twincat"}
    for name in ("III", "IV", "V"):
        assert s["models"][name]["export"]["verified"] is True, name
    html = (work / f"reports/{CAMPAIGN}/report.html").read_text()
    table = html[html.index('id="export-verification"') :]
    assert "through the exported compensation" in table and "in-process model" in table
    for name in ("III", "V"):
        assert f"{s['models'][name]['export']['accuracy_um']:.3f}" in table


def test_nano_netcdf_outputs_pass_the_cf_checker(thesis):
    """The nano campaigns' runs, models and metrics: no CF-1.11 error or warning (the XYΘ
    files are checked below)."""
    from conftest import cf_problems

    results = thesis["work"] / "results"
    files = sorted(f for name in ("nano1d-thesis", "nano2d-thesis") for f in (results / name).rglob("*.nc"))
    assert len(files) >= 10
    assert cf_problems(files) == []


def test_xytheta_heldout_accuracy_of_the_geometric_and_position_models(thesis):
    """Held out: the geometry (II) and the XY tables (III) help on poses they never saw, and
    the best model lies within a few times the rig's own floor there. Whether the angle
    tables (IV, V) help is the rig's physics' answer, shown in the report, not asserted.
    The thesis's Table 4.8 stays beside calflow's numbers; no test asks them to agree."""
    s = thesis["xytheta-thesis"]
    models = s["models"]
    acc = {k: v["accuracy_um"] for k, v in models.items()}
    assert all(v["protocol"] == "heldout" for v in models.values())
    assert acc["I"] > acc["II"] > acc["III"]
    h = s["validation"]["heldout"]
    floor, oracle = h["floor_um"], h["oracle_accuracy_um"]
    # the exact-inverse oracle is the accuracy floor (a model may reach it, not beat it by much);
    # the repeatability floor RP is another quantity, which an accuracy AP may lie below
    assert floor > 0 and 0 < oracle < 1.5 * min(acc.values())
    assert min(acc["III"], acc["V"]) < 3 * floor
    for name, m in models.items():
        assert m["reference_targets"]["thesis_accuracy_um"] == THESIS_4_8[name]  # shown beside, not asserted


def test_xytheta_error_budget_accounts_for_every_models_heldout_error(thesis, thesis_run):
    """Per model, the budget's entries (baseline, each effect of the rig, interaction) add up in
    signed quadrature to the RMS of the held-out per-target AP; every effect of the default
    rig has its entry; what no model represents is marked; the report shows the table."""
    import xarray as xr

    s = thesis["xytheta-thesis"]
    eb = s["validation"]["heldout"]["error_budget"]
    assert {"lead_screw", "backlash", "yaw", "decode", "lost_motion", "gross_errors"} <= set(eb["effects"])
    assert {"yaw", "expansion", "decode", "drift", "lost_motion", "gross_errors"} == set(eb["unmodelled"])
    for name, m in s["models"].items():
        b = m["error_budget_um"]
        assert set(b) == {"baseline", "interaction", *eb["effects"]}
        total = sum(np.sign(v) * v**2 for v in b.values())
        with xr.open_dataset(
            thesis_run / f"results/xytheta-thesis/metrics/validation_heldout_{name}.nc"
        ) as ds:
            ms = float(np.mean(ds["ap"].values ** 2))
        assert np.isclose(total, ms, rtol=1e-6) and np.isclose(m["error_budget_rms_um"] ** 2, ms, rtol=1e-9)
        assert m["error_budget_rms_um"] <= m["accuracy_um"]  # an RMS over targets, the max is AP
        assert 0 < b["baseline"]
    # Model I's fixed α, β stay wrong on a rig without effects: its baseline is most of its error;
    # Model V's baseline is noise, a small part of its error
    assert s["models"]["I"]["error_budget_um"]["baseline"] > 0.5 * s["models"]["I"]["error_budget_rms_um"]
    assert s["models"]["V"]["error_budget_um"]["baseline"] < s["models"]["V"]["error_budget_rms_um"]
    html = (thesis_run / "reports/xytheta-thesis/report.html").read_text()
    assert 'id="error-budget"' in html and "signed quadrature" in html


def test_heldout_targets_are_disjoint_from_every_training_pose(thesis):
    """From the run datasets alone: ≥ 50 held-out targets, their plan recorded, none of them
    an identification or angle-table pose; the summary says the same."""
    import xarray as xr

    runs = thesis["work"] / "results/xytheta-thesis/runs"

    def joints(path):
        with xr.open_dataset(path) as ds:
            sel = ds["pose"].values > 0
            return ds.attrs["plan"], np.column_stack(
                [ds[f"cmd_{j}"].values[sel] for j in ("x", "y", "theta")]
            )

    training = [
        joints(p) for p in sorted(runs.glob("identification.nc")) + sorted(runs.glob("angle_residuals_*.nc"))
    ]
    assert {plan for plan, _ in training} == {"identification", "angle_residuals"}
    train = np.vstack([q for _, q in training])
    for path in sorted(runs.glob("validation_heldout_*.nc")):
        plan, q = joints(path)
        assert plan == "validation_heldout"
        targets = np.unique(q[:, 2])
        assert targets.size >= 50
        d = np.min(
            np.abs(q[:, None, 0] - train[None, :, 0])
            + np.abs(q[:, None, 1] - train[None, :, 1])
            + 1e3 * np.abs(q[:, None, 2] - train[None, :, 2]),
            axis=1,
        )
        assert d.min() > 1.0, path.name
    h = thesis["xytheta-thesis"]["validation"]["heldout"]
    assert h["n_targets"] >= 50 and h["coincident_samples"] == 0 and isinstance(h["seed"], int)


def test_every_model_has_both_protocols_cross_validation_and_adequacy(thesis):
    for name, m in thesis["xytheta-thesis"]["models"].items():
        assert m["accuracy_um"] > 0 and m["reference_targets"]["accuracy_um"] > 0, name
        idf = m["identification"]
        assert idf["cv_rms_um"] > 0 and idf["residual_rms_um"] > 0 and idf["cv_folds"] == 5, name
        assert 0.8 < idf["cv_rms_um"] / idf["residual_rms_um"] < 1.5, name  # no overfitting with 4 parameters
        assert set(m["adequacy"]) >= {"chi2_dof", "adequate", "statement"}, name


def test_adequacy_flags_every_model_whose_parameters_are_biased(thesis):
    """A model whose free parameters sit more than 3 σ from the rig's truth is said not to
    fit, in the summary and in the report's words, and the report prints no ± beside it."""
    s = thesis["xytheta-thesis"]
    truth = s["truth"]["parameters"]
    html = (thesis["work"] / "reports/xytheta-thesis/report.html").read_text()
    biased_models = 0
    for name, m in s["models"].items():
        biased = any(
            abs(p["value"] - truth[k]) > 3 * p["std"] for k, p in m["parameters"].items() if p["std"]
        )
        if biased:
            biased_models += 1
            assert m["adequacy"]["adequate"] is False, name
            assert f"Model {name}: The model does not fit" in html
    assert biased_models >= 1  # the default rig has errors no model represents
    assert "assumes a fit the model does not have" in html


def test_angle_table_is_indexed_by_theta_with_a_step_from_the_spectrum(thesis):
    for name in ("IV", "V"):
        info = thesis["xytheta-thesis"]["models"][name]["angle_table_info"]
        assert info["table"] == "angle_sweep"
        theta = np.array(info["theta_deg"])
        assert np.allclose(np.diff(theta)[:-1], info["step_deg"])
        assert info["step_deg"] <= info["shortest_period_deg"] / 10 + 1e-9 or info["undersampled"]
        assert np.array(info["f_ax_um"]).shape == (2, theta.size)  # forward, backward
        assert len(info["sweep_theta_deg"]) >= theta.size
        assert info["step_deg"] / info["sweep_step_deg"] == pytest.approx(
            round(info["step_deg"] / info["sweep_step_deg"])
        )


def test_xytheta_identified_geometry_is_close_to_truth(thesis):
    s = thesis["xytheta-thesis"]
    truth = s["truth"]["parameters"]
    p = s["models"]["II"]["parameters"]
    assert abs(p["alpha_deg"]["value"] - truth["alpha_deg"]) < 0.05
    assert abs(p["beta_deg"]["value"] - truth["beta_deg"]) < 0.05
    assert s["characterisation"]["periods_um"]["xx"] == pytest.approx(400, rel=0.02)


def test_the_oracle_is_accurate_and_validation_repeatability_is_the_rigs(thesis):
    """Commanded through the rig's exact inverse (test-only truth), the Table 4.7 targets are
    reached within noise; Model V's repeatability at them is the rig's own."""
    from calflow.acquisition.runner import acquire
    from calflow.configuration.campaign import load as load_campaign
    from calflow.data.runs import RunMetadata
    from calflow.xytheta.evaluation import xytheta_validation_metrics
    from calflow.xytheta.models.kinematics import inverse as nominal_inverse
    from calflow.xytheta.plans.poses import validation
    from calflow.xytheta.stage.rig import simulated_xytheta
    from calflow.xytheta.tables.position import infer_directions

    c = load_campaign(ROOT / "config/campaigns/xytheta-thesis.yaml")
    rig = simulated_xytheta(seed=c["seed"], stream="validation_oracle", **c["rig"]["options"])
    truth = rig.truth_model

    def oracle(x, y, theta):
        # the world frame is the home pose's (Eq. 4.27): aim at the target from the home tool point
        x0, y0, _ = truth.tool_point(0.0, 0.0, 0.0, 1, 1)
        X0, Y0 = nominal_inverse(x, y, theta, truth.parameters)
        return truth.exact_inverse(x + x0, y + y0, theta, infer_directions(X0), infer_directions(Y0))

    meta = RunMetadata(
        campaign="oracle", robot="xytheta", source="simulated", plan="validation", config_sha256="0" * 64
    )
    run = acquire(validation(oracle, c["validation"].get("targets"), c["validation"]["cycles"]), rig, meta)
    m = xytheta_validation_metrics(run, meta)
    rp_oracle = m.attrs["repeatability_um"]
    assert m.attrs["accuracy_um"] < rp_oracle  # the oracle is accurate to within the rig's repeatability
    v = thesis["xytheta-thesis"]["models"]["V"]["reference_targets"]["repeatability_um"]
    assert 0.67 * rp_oracle <= v <= 1.5 * rp_oracle, (v, rp_oracle)


def test_nano1d_five_days_follow_the_thesis(thesis):
    s = thesis["nano1d-thesis"]
    tests = s["tests"]
    none, kmz, single = (tests[k]["series"] for k in ("no_calibration", "adaptive_kmz", "single"))
    # no calibration stays at the stage's geometric error or above (Fig. 5.18: > 400 nm; here the
    # unscaled Table 5.1 cubic, ~0.34 um p-v, plus the sensor's nonlinearity: > 300 nm), far above
    # both calibrations; KMZ below 200 nm throughout (Fig. 5.18)
    assert min(none["max_ap_nm"]) > 300
    assert min(none["max_ap_nm"]) > 2 * max(max(kmz["max_ap_nm"]), max(single["max_ap_nm"]))
    assert max(kmz["max_ap_nm"]) < 200
    # single: below 400 nm while the temperature is within the training range, worse after
    inside = np.array(single["in_training_range"], dtype=bool)
    ap = np.array(single["max_ap_nm"])
    assert inside.any() and (~inside).any()
    assert ap[inside].max() < 400
    assert np.median(ap[~inside]) > 1.5 * np.median(ap[inside])
    # robustness: no calibration worst in space and time (Table 5.2). Which calibration is best in
    # time is the rig's physics (issue 14): the thermocouples read at every pose follow the lumped
    # network's drift better than one KMZ visit per test here, unlike the thesis; the summary's
    # ordering block must state whichever it is
    r = s["robustness"]
    assert r["no_calibration"]["space"] > max(r["adaptive_kmz"]["space"], r["single"]["space"])
    assert r["no_calibration"]["time"] > 5 * max(r["single"]["time"], r["adaptive_kmz"]["time"])
    best_in_time = min(("single", "adaptive_kmz"), key=lambda k: r[k]["time"])
    label = {"single": "the single model", "adaptive_kmz": "the adaptive KMZ model"}[best_in_time]
    assert f"Time robustness R_T from best to worst: {label}" in s["ordering"]["statement"]
    # intrinsic (metrology room): AP of the order of 350 nm, RP of the order of 35 nm (Sec. 5.3.3)
    assert 175 < s["intrinsic"]["accuracy_nm"] < 700
    assert 15 < s["intrinsic"]["repeatability_nm"] < 70


def test_nano_validation_records_what_is_out_of_sample(thesis):
    """Validation after training in time; positions training visited are named, and the
    max AP over the others is given per test type (thesis protocol kept beside)."""
    for name, shared in (("nano1d-thesis", [[0.0], [240.0], [480.0]]), ("nano2d-thesis", [[0.0, 0.0]])):
        s = thesis[name]
        h = s["validation"]["heldout"]
        assert h["time_disjoint"] and h["validation_start_h"] > h["training_end_h"]
        assert h["shared_positions_um"] == shared
        for mode, t in s["tests"].items():
            assert t["heldout_max_accuracy_nm"] <= t["max_accuracy_nm"], (name, mode)


def test_nano_summaries_and_reports_carry_iso9283_beyond_ap_rp(thesis):
    from calflow.configuration.campaign import load as load_campaign

    keys = {"vAP", "AD", "RD", "dAP", "dRP", "stabilisation_time_s", "overshoot"}

    for name in ("nano1d-thesis", "nano2d-thesis"):
        dwell_s = load_campaign(ROOT / "config" / "campaigns" / f"{name}.yaml")["validation"]["dwell_s"]
        block = thesis[name]["iso9283"]
        assert block["standard"] == "ISO 9283:1998" and set(block["modes"]) == set(thesis[name]["tests"])
        for mode, b in block["modes"].items():
            assert set(b) == keys, (name, mode)
            for key, e in b.items():
                assert e["unit"] == ("s" if key == "stabilisation_time_s" else "nm") and e[
                    "clause"
                ].startswith("7.")
                assert e["value"] is not None or e["reason"].startswith("not supported by this data"), (
                    name,
                    mode,
                    key,
                )
            assert b["RD"]["value"] > 0 and b["dAP"]["value"] >= 0 and b["dAP"]["period_h"] > 0
            stab, over = b["stabilisation_time_s"], b["overshoot"]  # the step-response run (clauses 7.5, 7.6)
            assert (stab["clause"], over["clause"]) == ("7.5", "7.6") and stab[
                "source"
            ] == "step_response run"
            assert (
                np.isfinite(stab["value"]) and 0 < stab["value"] < dwell_s
            )  # settled long before the reading
            assert np.isfinite(over["value"]) and over["value"] > 0 and stab["band_nm"] > 0
        html = (thesis["work"] / f"reports/{name}/report.html").read_text()
        assert 'id="iso9283-table"' in html and "clause 7.5" in html and 'id="iso9283-stabilisation"' in html
    one, two = (thesis[n]["iso9283"]["modes"] for n in ("nano1d-thesis", "nano2d-thesis"))
    assert all(b["vAP"]["value"] > 0 for b in one.values())  # forward and backward approaches
    assert all(b["vAP"]["value"] is None for b in two.values())  # one approach direction per point
    # uncalibrated, the 1-DoF stage drifts over the five days far more than when the KMZ model corrects it
    assert one["no_calibration"]["dAP"]["value"] > 3 * one["adaptive_kmz"]["dAP"]["value"]


def test_iso230_2_reversal_is_never_negative_and_the_xytheta_report_shows_it(thesis):
    iso = thesis["xytheta-thesis"]["iso230_2"]
    assert set(iso) == {"x", "y"}
    for block in (*iso.values(), thesis["nano1d-thesis"]["iso230_2"]):
        unit = block["units"]
        assert block[f"B_{unit}"] >= abs(block[f"B_mean_{unit}"]) >= 0
    html = (thesis["work"] / f"reports/{CAMPAIGN}/report.html").read_text()
    assert 'id="iso230-x"' in html and 'id="iso230-y"' in html and "B = max |B_i|" in html


def test_nano_error_budget_and_ordering_follow_the_numbers(thesis):
    """Per test type an error budget by effect at the held-out positions whose parts
    combine into its total (root-sum-square plus the signed interaction), and an ordering that
    is the one of the max AP, beside the thesis's."""
    for name in ("nano1d-thesis", "nano2d-thesis"):
        s = thesis[name]
        assert s["validation"]["error_budget_method"]
        for mode, t in s["tests"].items():
            b = t["error_budget_nm"]
            # the thermocouples' own errors sit inside the other entries (calflow.nano.stage.error_budget)
            parts = {k: v for k, v in b.items() if k not in ("total", "interaction", *TC_ERRORS)}
            assert {"geometry", "stage_drift", "hysteresis", "noise_and_estimation"} <= set(parts), (
                name,
                mode,
            )
            ss = sum(v * v for v in parts.values()) + np.sign(b["interaction"]) * b["interaction"] ** 2
            assert np.sqrt(ss) == pytest.approx(b["total"], rel=1e-6), (name, mode)
        none, cal = s["tests"]["no_calibration"]["error_budget_nm"], s["tests"]["single"]["error_budget_nm"]
        assert none["total"] > 5 * cal["total"]  # calibration removes most of what the effects do
        assert cal["geometry"] < 0.1 * none["geometry"]  # the polynomial compensates the geometry
        order = s["ordering"]["order"]
        ap = {k: t["max_accuracy_nm"] for k, t in s["tests"].items()}
        assert order == sorted(ap, key=ap.get) and order[-1] == "no_calibration"
        assert "thesis" in s["ordering"]["statement"]


def test_nano2d_model_brings_micrometres_to_hundreds_of_nanometres(thesis):
    t = thesis["nano2d-thesis"]["tests"]
    assert t["no_calibration"]["max_accuracy_nm"] > 1000
    assert t["single"]["max_accuracy_nm"] < 400


# ------------------------------------------------ the workflow on the same run


def test_nano_training_design_sets_the_achieved_sigma_beside_the_bound(thesis):
    # the thesis grid's bound before acquisition and what identification achieved, in summary and report
    for name, first in (("nano1d-thesis", "a_1"), ("nano2d-thesis", "a_1x")):
        td = thesis[name]["training_design"]
        assert td["plan"] == "grid" and td["crlb_shape_sigma_nm"] > 0
        assert td["achieved_sigma"][first] >= td["crlb_sigma"][first] * 0.9  # a lower bound, up to the draw
        assert td["rig_time_h_achieved"] == pytest.approx(td["rig_time_h"], rel=0.01)
        html = (thesis["work"] / f"reports/{name}/report.html").read_text()
        assert "Training plan: bound before, result after" in html and "lower bound" in html


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


def test_every_netcdf_output_passes_the_cf_checker(thesis_run):
    """The IOOS compliance-checker finds no CF-1.11 error or warning in any netCDF output (XYΘ)."""
    from conftest import cf_problems

    files = sorted((thesis_run / "results" / CAMPAIGN).rglob("*.nc"))  # nano: above
    assert len(files) > 30
    assert cf_problems(files) == []


# ------------------------------------------------ stage SN-0042's year, one campaign at a time
# The lab's way (docs/lifecycle.md): after the default run, campaigns of the stage are run one
# at a time. A copy of the year's folders (not of the whole run) keeps this cheap: one small
# calibration and one interim check are run, plus two runs that stop before their history.
YEAR = [
    "demo-sn0042-2026-01",
    "demo-sn0042-2026-04-check",
    "demo-sn0042-2026-07-check",
    "demo-sn0042-2026-07",
    "demo-sn0042-2026-10-check",
]
HISTORY = "results/stages/SN-0042/history.json"


@pytest.fixture(scope="module")
def year(thesis_run, tmp_path_factory):
    """The default run's project with only SN-0042's campaigns on disk (times kept)."""
    import shutil

    work = tmp_path_factory.mktemp("year") / "project"
    work.mkdir()
    shutil.copy(thesis_run / "Snakefile", work / "Snakefile")
    for sub in ["workflow", "config", "results/stages/SN-0042", "reports/stages/SN-0042"] + [
        f"{top}/{name}" for name in YEAR for top in ("results", "reports")
    ]:
        shutil.copytree(thesis_run / sub, work / sub)
    return work


def _digests(work, *tops):
    import hashlib

    return {
        str(p.relative_to(work)): hashlib.sha256(p.read_bytes()).hexdigest()
        for top in tops
        for p in sorted((work / top).rglob("*"))
        if p.is_file() and "/logs/" not in str(p) and "/benchmarks/" not in str(p)
    }


def test_a_bad_campaign_of_the_stage_leaves_every_earlier_result_and_the_history(year):
    """Nothing lost: a check whose reference is itself (refused at load) and a calibration
    whose rig fails (in a job) leave the year's results, history and reports byte for byte."""
    import yaml

    before = _digests(year, "results", "reports")
    assert len([k for k in before if k.startswith("results/stages/")]) == 1
    check = yaml.safe_load((year / f"config/campaigns/{YEAR[1]}.yaml").read_text())
    check["interim_check"]["reference"] = "bad-check"
    (year / "config/campaigns/bad-check.yaml").write_text(yaml.safe_dump(check))
    proc = snakemake(year, "--config", 'campaigns=["bad-check"]')
    assert proc.returncode != 0
    assert "bad-check.yaml: key 'interim_check.reference': expected another campaign" in proc.stderr
    assert _digests(year, "results", "reports") == before
    bad = yaml.safe_load((year / f"config/campaigns/{YEAR[0]}.yaml").read_text())
    bad["start"] = "2026-12-01T08:00:00+00:00"
    bad["rig"] = {"factory": "toyrigs:open_toy", "options": {"camera": [1000.0]}}  # fails on its first read
    (year / "config/campaigns/bad-rig.yaml").write_text(yaml.safe_dump(bad))
    proc = snakemake(year, "--config", 'campaigns=["bad-rig"]', 'rig_plugins=["toyrigs"]')
    assert proc.returncode != 0
    after = _digests(year, "results", "reports")
    assert {k: v for k, v in after.items() if "/bad-rig/" not in k} == before


def test_one_campaign_at_a_time_never_shrinks_the_history(year):
    """One more calibration of SN-0042 run alone: the history lists the year and it (six). The
    April check run alone after its results were deleted comes back byte for byte, and the
    history is still six. A campaign deleted from disk leaves it, with the reason."""
    import shutil

    import yaml

    c = yaml.safe_load((year / f"config/campaigns/{YEAR[0]}.yaml").read_text())
    c.update(seed=44, start="2027-01-05T08:00:00+00:00", description="Stage SN-0042, calibration of 2027-01")
    (year / "config/campaigns/demo-sn0042-2027-01.yaml").write_text(yaml.safe_dump(c))
    # the campaign, the history and its page (not every PDF: CI time); the copy has no
    # Snakemake metadata, so the campaign's summary is asked for (its report would do too)
    page = "reports/stages/SN-0042/history.html"
    targets = ["results/demo-sn0042-2027-01/summary.json", HISTORY, page]
    proc = snakemake(
        year, *targets, "--config", 'campaigns=["demo-sn0042-2027-01"]', env_extra=SOURCE_DATE_EPOCH
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    h = json.loads((year / HISTORY).read_text())
    assert [e["campaign"] for e in h["campaigns"]] == YEAR + ["demo-sn0042-2027-01"]
    assert [(e["from"], e["to"]) for e in h["changes"]] == [
        (YEAR[0], YEAR[3]),
        (YEAR[3], "demo-sn0042-2027-01"),
    ]
    assert h["departed"] == [] and "demo-sn0042-2027-01" in (year / page).read_text()
    six = (year / HISTORY).read_bytes()

    check = year / "results" / YEAR[1]
    kept = {p: (check / p).read_bytes() for p in ("summary.json", "runs/interim_check.nc")}
    shutil.rmtree(check)
    targets = [f"results/{YEAR[1]}/summary.json", HISTORY]
    proc = snakemake(year, *targets, "--config", f'campaigns=["{YEAR[1]}"]', env_extra=SOURCE_DATE_EPOCH)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert not re.search(rf"wildcards: campaign={YEAR[0]}\b", proc.stdout + proc.stderr)  # read, not remade
    for p, data in kept.items():
        assert (check / p).read_bytes() == data, p
    assert (year / HISTORY).read_bytes() == six

    shutil.rmtree(year / "results/demo-sn0042-2027-01")
    proc = snakemake(year, HISTORY, "--config", f'campaigns=["{YEAR[1]}"]')
    assert proc.returncode == 0, proc.stderr[-3000:]
    h = json.loads((year / HISTORY).read_text())
    assert [e["campaign"] for e in h["campaigns"]] == YEAR
    assert h["departed"] == [
        {
            "campaign": "demo-sn0042-2027-01",
            "start": "2027-01-05T08:00:00+00:00",
            "kind": "calibration",
            "reason": "results/demo-sn0042-2027-01/summary.json is no longer on disk (its results were deleted)",
        }
    ]


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


FIELDS = (  # ISO/IEC 17025:2017 7.8.2.1 and 7.8.4.1: each a cell of the certificate's first table
    "laboratory",
    "address",
    "accreditation",
    "customer",
    "item",
    "serial_number",
    "calibrated",
    "issued",
    "method",
    "environment",
    "traceability",
    "approver",
)


def test_every_default_certificate_states_iso_17025_its_dcc_holds_and_signs(
    thesis_run, tmp_path, monkeypatch
):
    """Each default campaign's certificate: every 7.8 item present and not empty, its number,
    "unsigned" and "page x of y" on every PDF page (no key in a default run); its DCC valid
    against PTB's schema and read back by dcc-json-toolkit equal to summary.json, figure for
    figure; then made again with a throw-away lab key, verified against its CA."""
    from dcc_check import read_back, results_read_back, schema_errors
    from pdf_check import page_texts
    from throwaway_pki import make

    from calflow.cli import main

    certificates = sorted(thesis_run.glob("reports/*/certificate.html"))
    assert len(certificates) >= 9
    (tmp_path / "pki").mkdir()
    pki = make(tmp_path / "pki")
    for html_file in certificates:
        name = html_file.parent.name
        html = html_file.read_text()
        for field in FIELDS:
            start = html.index(f'data-field="{field}"')
            cell = re.sub(
                r"<[^>]+>", "", html[html.index(">", start) + 1 : html.index("</td>", start)]
            ).strip()
            assert cell and cell != "—", (name, field)
        number = re.search(r'data-number="([^"]+)"', html).group(1)
        pages = page_texts(html_file.with_suffix(".pdf"))
        for i, text in enumerate(pages, 1):
            assert number in text and "UNSIGNED" in text and f"page {i} of {len(pages)}" in text, (name, i)
        xml = html_file.with_suffix(".xml").read_bytes()
        assert schema_errors(xml, tmp_path) == [], name
        summary = json.loads((thesis_run / f"results/{name}/summary.json").read_text())
        for key, (value, U, k, _) in results_read_back(read_back(xml, tmp_path)).items():
            parent_key, leaf = key.rsplit(".", 1)
            parent = summary
            for part in parent_key.split("."):
                parent = parent[part]
            assert value == parent[leaf], (name, key)
            if U is not None:
                assert (U, k) == (parent["uncertainty"][leaf]["U"], parent["uncertainty"][leaf]["k"]), (
                    name,
                    key,
                )
        # signed: the same certificate made with a lab key outside the project
        out = tmp_path / name
        out.mkdir()
        monkeypatch.chdir(thesis_run)
        monkeypatch.setenv("CALFLOW_SIGNING_KEY", str(pki["p12"]))
        monkeypatch.setenv("CALFLOW_SIGNING_PASSWORD", pki["password"])
        args = [
            "certificate",
            "--campaign",
            f"config/campaigns/{name}.yaml",
            "--summary",
            f"results/{name}/summary.json",
        ]
        args += ["--html", str(out / "c.html"), "--pdf", str(out / "c.pdf"), "--xml", str(out / "c.xml")]
        assert main(args) == 0, name
        for suffix in ("pdf", "xml"):
            check = ["verify-certificate", str(out / f"c.{suffix}"), "--trust", str(pki["ca"])]
            assert main([*check, "--summary", f"results/{name}/summary.json"]) == 0, (name, suffix)


def test_every_default_certificate_verifies_unsigned_and_refuses_a_tampered_pdf_dcc_or_summary(
    thesis_run, tmp_path, monkeypatch, capsys
):
    """A newcomer's default run (no key): each certificate's PDF and DCC verify on their
    values and say "unsigned"; one digit changed in the PDF's printed text (the DCC inside
    left alone), in the DCC, or in the summary is refused in one line naming what differs."""
    import shutil

    from pdf_check import change_text

    from calflow.certificate.document import rows
    from calflow.cli import main

    def bump(text: str) -> str:  # its last decimal digit one up
        j = max(i for i, ch in enumerate(text) if ch.isdigit())
        return text[:j] + str((int(text[j]) + 1) % 10) + text[j + 1 :]

    monkeypatch.chdir(thesis_run)
    monkeypatch.delenv("CALFLOW_SIGNING_KEY", raising=False)
    certificates = sorted(thesis_run.glob("reports/*/certificate.pdf"))
    assert len(certificates) >= 9
    for pdf_file in certificates:
        name = pdf_file.parent.name
        summary_file = f"results/{name}/summary.json"
        summary = json.loads((thesis_run / summary_file).read_text())
        for suffix in ("pdf", "xml"):
            assert main(["verify-certificate", f"reports/{name}/certificate.{suffix}"]) == 0, (name, suffix)
            assert capsys.readouterr().out.rstrip().endswith("; unsigned"), (name, suffix)
        # the printed text: the first result's value, or (no result with a U) the number
        with_u = [r for r in rows(summary) if r["uncertainty"] and isinstance(r["value"], (int, float))]
        pdf = pdf_file.read_bytes()
        if with_u:  # (drawn in its row, or its budget's caption if the row's cell wraps it)
            shown = f"{with_u[0]['value']:.4f}"
            what = bump(shown)  # the refusal quotes what the page shows
        else:
            shown = re.search(r'data-number="([^"]+)"', pdf_file.with_suffix(".html").read_text())[1]
            what = "certificate number"
        out = tmp_path / name
        out.mkdir()
        (out / "t.pdf").write_bytes(change_text(pdf, shown, bump(shown)))
        xml = pdf_file.with_suffix(".xml").read_text()
        at = xml.find("<dcc:results")  # the first result's value (not an influence condition's)
        # its leading digit: a last digit of 17 may leave the double unchanged
        value = re.compile(r"<si:value>-?(\d)").search(xml, max(at, 0))
        if value:  # (a DCC of no result has none)
            (out / "t.xml").write_text(xml[: value.start(1)] + bump(value[1]) + xml[value.end(1) :])
        text = (thesis_run / summary_file).read_text()
        first = re.search(r'"accuracy_um": (-?\d+\.\d+)', text) or re.search(r": (\d+\.\d+)", text)
        j = first.start(1) + first[1].startswith("-")  # its leading digit, as in the DCC
        (out / "s.json").write_text(text[:j] + bump(text[j]) + text[j + 1 :])
        shutil.copy(pdf_file.with_suffix(".xml"), out / "c.xml")
        for tampered, summary_arg, names in (
            (out / "t.pdf", summary_file, what),
            (out / "t.xml", summary_file, "result " if with_u else "certificate"),
            (out / "c.xml", str(out / "s.json"), ""),
        ):
            if tampered.suffix == ".xml" and not with_u and summary_arg == summary_file:
                continue  # a DCC of no result has no value to change
            assert main(["verify-certificate", str(tampered), "--summary", summary_arg]) != 0, (
                name,
                tampered,
            )
            err = capsys.readouterr().err.strip()
            assert len(err.splitlines()) == 1 and names in err, (name, tampered, err)


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
