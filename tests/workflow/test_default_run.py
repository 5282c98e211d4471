"""The three thesis campaigns, run in full, against the thesis's own results.

Issue 4 (XYΘ, Table 4.8) and issue 5 (nanopositioning, Sec. 5.3.3, 5.4.2). The oracle
validation below commands the targets through the simulated truth's exact inverse: it
is test-only, and measures the rig's own repeatability at the validation targets.
"""

import json

import numpy as np
import pytest
from conftest import ROOT

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
