"""Monte-Carlo study of the XYΘ identification (issue 8): points, aggregate, page, workflow."""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest
import yaml
from conftest import SMALL_XYTHETA, make_workdir, snakemake

from calflow.configuration.config import validate
from calflow.errors import ConfigError
from calflow.xytheta.stage.rig import XYThetaTruth
from calflow.xytheta.studies.aggregate import aggregate, cell
from calflow.xytheta.studies.montecarlo import (
    grid,
    identify_run,
    jobs,
    load_study,
    parse_seeds,
    render_page,
    run_point,
    seed_batches,
    simulate_run,
)

PARAMS = ("x_R_um", "y_R_um", "alpha_deg", "beta_deg")


def small_campaign() -> dict:
    c = validate(yaml.safe_load(yaml.safe_dump(SMALL_XYTHETA)), "campaign-xytheta", "small.yaml")
    c["name"] = "small"
    return c


def clean_rig() -> dict:
    """Rig options with every error the models do not describe switched off: sensor noise
    is then the only source of identification error."""
    from calflow.xytheta.stage.physics import options_off

    return {**options_off(), "stage_repeatability_um": 0.0}


# ---------------------------------------------------------------------------- points


def test_run_point_on_tiny_settings():
    pt = run_point(small_campaign(), seed=0, noise_um=0.2, poses=8, validation_cycles=2)
    assert (pt["seed"], pt["noise_um"], pt["poses"], pt["model"]) == (0, 0.2, 8, "II")
    assert pt["failed"] is None
    assert pt["diagnostics"]["n_poses"] == 9  # the home pose comes on top
    for key in PARAMS:
        p = pt["parameters"][key]
        assert p["free"] and p["std"] > 0
        assert p["abs_error"] == pytest.approx(abs(p["estimate"] - p["truth"]))
        assert p["z"] == pytest.approx(p["error"] / p["std"])
    assert pt["parameters"]["x_R_um"]["truth"] == XYThetaTruth().x_R_um
    assert pt["accuracy_um"] > 0 and pt["repeatability_um"] > 0
    assert 0 < pt["diagnostics"]["O2"] <= 1 and pt["diagnostics"]["O4"] > 0
    json.dumps(pt, allow_nan=False)  # strict JSON: no NaN
    again = run_point(small_campaign(), seed=0, noise_um=0.2, poses=8, validation_cycles=2)
    assert again == pt  # reproducible to the bit


def test_identification_uses_the_run_dataset_only(tmp_path):
    """The analysis path gets a run dataset read back from disk: no simulator, no truth."""
    from calflow.data.io import open_dataset, write_dataset
    from calflow.xytheta.plans.poses import identification

    c = small_campaign()
    p = c["identification"]
    run, truth = simulate_run(
        c, identification(30, p["x_um"], p["y_um"], p["theta_deg"], seed=5), "identification", 5, 0.1
    )
    write_dataset(run, tmp_path / "run.nc")
    model, diag = identify_run(open_dataset(tmp_path / "run.nc", kind="run"), c, "II")
    assert model is not None and diag["n_poses"] == 31
    assert abs(model.parameters.alpha - truth["alpha_deg"]) < 0.5


def test_error_shrinks_with_poses_and_grows_with_noise():
    """On a rig whose only error is sensor noise, the median identification error over 6 seeds
    falls with the number of poses (~1/sqrt(n)) and rises with the noise (~linearly)."""
    c, rig = small_campaign(), clean_rig()
    pts = [
        run_point(c, s, n, p, validation_cycles=2, rig_options=rig)
        for s in range(6)
        for n in (0.1, 2.0)
        for p in (10, 200)
    ]
    agg = aggregate(pts)
    for key in PARAMS:
        med = {
            (n, p): cell(agg, n, p)["parameters"][key]["abs_error"]["median"]
            for n in (0.1, 2.0)
            for p in (10, 200)
        }
        for n in (0.1, 2.0):
            assert med[(n, 200)] < med[(n, 10)], (key, n, med)
        for p in (10, 200):
            assert med[(2.0, p)] > 3 * med[(0.1, p)], (key, p, med)
    # the reported std is honest when the model describes the rig: RMS of z ≈ 1
    z = np.array([pt["parameters"][k]["z"] for pt in pts for k in PARAMS])
    assert 0.6 < np.sqrt(np.mean(z**2)) < 1.6


def test_points_carry_the_cramer_rao_bound_and_the_estimator_reaches_it():
    """Each point scores the bound at the rig's truth (its noise: sensor, repeatability,
    resolution); on a rig whose errors Model II represents, the spread over seeds divided
    by it is near 1 (30 seeds: ± ~13 %; the 200-seed figure is in docs/benchmarks.md)."""
    rig = {**clean_rig(), "stage_repeatability_um": 0.3}
    pts = [run_point(small_campaign(), s, 0.4, 60, validation_cycles=2, rig_options=rig) for s in range(30)]
    for pt in pts:
        for key in PARAMS:
            p = pt["parameters"][key]
            assert p["crlb"] > 0 and p["std"] == pytest.approx(p["crlb"], rel=0.3)
    c = aggregate(pts)["cells"][0]
    for key in PARAMS:
        p = c["parameters"][key]
        assert p["crlb_rms"] == pytest.approx(
            np.sqrt(np.mean([pt["parameters"][key]["crlb"] ** 2 for pt in pts]))
        )
        assert p["sigma_ratio_crlb"] == pytest.approx(p["spread"] / p["crlb_rms"])
        assert 0.7 < p["sigma_ratio_crlb"] < 1.3, (key, p["sigma_ratio_crlb"])


# ---------------------------------------------------------------------------- aggregate


def _point(seed, noise, poses, errors, std=1.0, accuracy=10.0, failed=None):
    return {
        "campaign": "c",
        "model": "II",
        "seed": seed,
        "noise_um": noise,
        "poses": poses,
        "failed": failed,
        "accuracy_um": None if failed else accuracy,
        "repeatability_um": None if failed else 1.0,
        "diagnostics": {
            "O1": 0.1,
            "O2": 0.01 * poses,
            "O3": 1.0,
            "O4": 0.001 * poses,
            "residual_rms_um": 0.5,
            "n_poses": poses + 1,
        },
        "parameters": {
            k: {
                "units": "um",
                "free": True,
                "estimate": 1.0 + errors,
                "std": std,
                "truth": 1.0,
                "error": errors,
                "abs_error": abs(errors),
                "z": errors / std,
            }
            for k in PARAMS
        },
    }


def test_aggregate_math_on_hand_built_points():
    errs = [-2.0, -1.0, 0.0, 1.0, 2.0]
    pts = [_point(s, 0.5, 10, e, std=2.0, accuracy=10.0 + s) for s, e in enumerate(errs)]
    pts += [_point(s, 0.5, 100, e / 10, std=0.1) for s, e in enumerate(errs)]
    pts.append(_point(5, 0.5, 100, 0.0, failed="did not converge"))
    agg = aggregate(pts)
    assert agg["noise_um"] == [0.5] and agg["poses"] == [10, 100] and agg["n_points"] == 11
    a = cell(agg, 0.5, 10)
    p = a["parameters"]["x_R_um"]
    assert p["abs_error"]["median"] == 1.0 and p["abs_error"]["mean"] == pytest.approx(1.2)
    assert p["abs_error"]["p05"] == pytest.approx(np.percentile([2, 1, 0, 1, 2], 5))
    assert (p["abs_error"]["p25"], p["abs_error"]["p95"]) == (1.0, 2.0)  # sorted 0, 1, 1, 2, 2
    assert p["bias"] == pytest.approx(0.0)
    assert p["spread"] == pytest.approx(np.std(errs, ddof=1))
    assert p["reported_std_rms"] == pytest.approx(2.0)
    assert p["std_ratio"] == pytest.approx(np.std(errs, ddof=1) / 2.0)
    assert p["rms_z"] == pytest.approx(np.sqrt(np.mean(np.square(errs) / 4.0)))
    assert p["crlb_rms"] is None and p["sigma_ratio_crlb"] is None  # hand-built points carry no bound
    assert a["accuracy_um"]["median"] == 12.0 and a["accuracy_um"]["n"] == 5
    assert a["O2"]["median"] == pytest.approx(0.1) and a["failed"] == 0
    b = cell(agg, 0.5, 100)
    assert (b["n"], b["failed"]) == (6, 1)
    assert b["accuracy_um"]["n"] == 5  # the failed point is left out
    assert b["parameters"]["beta_deg"]["std_ratio"] == pytest.approx(np.std(errs, ddof=1) / 10 / 0.1)
    json.dumps(agg, allow_nan=False)
    with pytest.raises(ValueError):
        aggregate([])
    with pytest.raises(ValueError, match="several models"):
        aggregate([pts[0], {**pts[1], "model": "I"}])


def test_seed_batches():
    study = {"seeds": 7, "seeds_per_job": 3, "noise_um": [0.05, 2.0], "poses": [5]}
    assert seed_batches(study) == ["0-2", "3-5", "6"]
    assert [parse_seeds(b) for b in seed_batches(study)] == [[0, 1, 2], [3, 4, 5], [6]]
    assert jobs(study)[:2] == [("0-2", "0.05", 5), ("0-2", "2", 5)]
    assert len(grid(study)) == 14 and len(jobs(study)) == 6
    with pytest.raises(ValueError):
        parse_seeds("3-1")


# ---------------------------------------------------------------------------- study files and page


def _study_files(tmp_path, body: dict, campaign: dict | None = None):
    (tmp_path / "campaigns").mkdir(exist_ok=True)
    (tmp_path / "campaigns" / "small.yaml").write_text(yaml.safe_dump(campaign or SMALL_XYTHETA))
    path = tmp_path / "mini.yaml"
    path.write_text(yaml.safe_dump(body))
    return path


STUDY = {"campaign": "small", "seeds": 2, "noise_um": [0.1, 1.0], "poses": [5, 30], "validation_cycles": 2}


def test_load_study_defaults_and_errors(tmp_path):
    s = load_study(_study_files(tmp_path, STUDY), tmp_path / "campaigns")
    assert (s["name"], s["model"], s["seeds_per_job"], s["rig_options"]) == ("mini", "II", 1, {})
    assert s["base"]["name"] == "small"
    for body, message in (
        ({**STUDY, "model": "III"}, "position table"),
        ({**STUDY, "model": "IV"}, "identified model"),
        ({**STUDY, "noise_um": []}, "noise_um"),
        ({**STUDY, "poses": [2]}, "poses"),
        ({**STUDY, "rig_options": {"sensor_noise_um": 1}}, "rig_options.sensor_noise_um"),
        ({**STUDY, "colour": "red"}, "colour"),
    ):
        with pytest.raises(ConfigError, match=message):
            load_study(_study_files(tmp_path, body), tmp_path / "campaigns")
    with pytest.raises(ConfigError, match="simulated"):
        load_study(
            _study_files(
                tmp_path,
                STUDY,
                {**SMALL_XYTHETA, "rig": {"factory": "replay", "options": {"recordings": "runs"}}},
            ),
            tmp_path / "campaigns",
        )


def test_default_study_is_valid():
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    s = load_study(root / "config/studies/montecarlo-xytheta.yaml", root / "config/campaigns")
    assert s["base"]["robot"] == "xytheta" and len(grid(s)) >= 48


def test_default_study_smallest_pose_count_identifies_at_every_noise_level():
    """The default study's fewest poses (5: two readings more than the unknowns) identify
    with the campaign's robust screening at every noise level: `make run` runs these points."""
    from pathlib import Path

    from calflow.xytheta.studies.montecarlo import run_point

    root = Path(__file__).resolve().parents[2]
    s = load_study(root / "config/studies/montecarlo-xytheta.yaml", root / "config/campaigns")
    fewest = min(s["poses"])
    for noise in s["noise_um"]:
        for seed in range(s["seeds"]):
            point = run_point(s["base"], seed, float(noise), fewest, s["model"], s["validation_cycles"])
            assert point["poses"] == fewest and np.isfinite(point["accuracy_um"]), (noise, seed, point)


def test_page_renders_figures_and_escapes(tmp_path):
    body = {**STUDY, "description": "<script>alert('x')</script> & co"}
    s = load_study(_study_files(tmp_path, body), tmp_path / "campaigns")
    pts = [_point(seed, float(n), p, (seed + 1) * float(n) / p, std=float(n) / p) for seed, n, p in grid(s)]
    html = render_page(aggregate(pts), s)
    assert html.count("<svg") == 4 and html.count("<figure") == 4
    assert "<script>" not in html and "&lt;script&gt;alert(&#39;x&#39;)&lt;/script&gt; &amp; co" in html
    assert "Monte-Carlo study: mini" in html and "34.338" in html  # thesis Model II beside ours
    ids = re.findall(r'id="([^"]+)"', html)
    assert len(ids) == len(set(ids)), "inline SVGs share no id"


def test_commands_batch_of_seeds_and_errors(tmp_path):
    from calflow.cli import parser
    from calflow.errors import CalflowError

    study = _study_files(tmp_path, {**STUDY, "poses": [5]})
    p = parser()

    def call(*argv):
        args = p.parse_args(
            [argv[0], "--study", str(study), "--campaign-dir", str(tmp_path / "campaigns"), *argv[1:]]
        )
        args.func(args)

    call("mc-point", "--seed", "0-1", "--noise", "0.1", "--poses", "5", "--out", str(tmp_path / "a.json"))
    points = json.loads((tmp_path / "a.json").read_text())["points"]
    assert [pt["seed"] for pt in points] == [0, 1] and points[1]["noise_um"] == 0.1
    with pytest.raises(CalflowError, match="missing"):
        call("mc-aggregate", "--points", str(tmp_path / "a.json"), "--out", str(tmp_path / "agg.json"))
    call(
        "mc-aggregate", "--points", str(tmp_path / "a.json"), "--partial", "--out", str(tmp_path / "agg.json")
    )
    assert json.loads((tmp_path / "agg.json").read_text())["missing"] == 2
    with pytest.raises(CalflowError, match="twice"):
        call(
            "mc-aggregate",
            "--points",
            str(tmp_path / "a.json"),
            str(tmp_path / "a.json"),
            "--partial",
            "--out",
            str(tmp_path / "agg.json"),
        )
    for argv, message in (
        (("--seed", "2"), "expected seeds 0 .. 1"),
        (("--noise", "0.3"), "noise_um"),
        (("--poses", "6"), "poses"),
    ):
        base = {"--seed": "0", "--noise": "0.1", "--poses": "5", **dict([argv])}
        with pytest.raises(CalflowError, match=message):
            call("mc-point", *[x for kv in base.items() for x in kv], "--out", str(tmp_path / "b.json"))
    call("mc-report", "--aggregate", str(tmp_path / "agg.json"), "--out", str(tmp_path / "page.html"))
    assert "2 grid points are missing" in (tmp_path / "page.html").read_text()


# ---------------------------------------------------------------------------- workflow


def test_study_through_snakemake(tmp_path):
    work = make_workdir(tmp_path, {"small": SMALL_XYTHETA})
    (work / "config/studies").mkdir()
    (work / "config/studies/mini.yaml").write_text(yaml.safe_dump(STUDY))
    target = "reports/studies/mini.html"
    proc = snakemake(work, "--config", "studies=[mini]", "--", target)
    assert proc.returncode == 0, proc.stderr[-3000:]
    agg = json.loads((work / "results/studies/mini/aggregate.json").read_text())
    assert agg["n_points"] == 8 and agg["missing"] == 0
    assert {(c["noise_um"], c["poses"]) for c in agg["cells"]} == {
        (n, p) for n in (0.1, 1.0) for p in (5, 30)
    }
    assert all(c["n"] == 2 and c["failed"] == 0 and c["accuracy_um"]["median"] > 0 for c in agg["cells"])
    assert sorted(p.name for p in (work / "results/studies/mini/points").iterdir())[:2] == [
        "0_0.1_30.json",
        "0_0.1_5.json",
    ]
    assert (work / "results/studies/mini/benchmarks/point_1_1_30.tsv").exists()
    assert (work / "results/studies/mini/logs/aggregate.log").exists()
    html = (work / target).read_text()
    assert html.count("<svg") == 4 and "mini" in html
    from pdf_check import outside

    # the study writes its page as HTML only (the browser test prints such pages); a PDF it writes is checked here
    assert {str(p): o[:3] for p in (work / "reports").rglob("*.pdf") if (o := outside(p))} == {}
    proc = snakemake(work, "--config", "studies=[mini]", "-n", "--", target)
    assert proc.returncode == 0 and "Nothing to be done" in proc.stdout + proc.stderr, proc.stdout[-3000:]
    # more seeds: only the new points run, then the aggregate and the page
    (work / "config/studies/mini.yaml").write_text(yaml.safe_dump({**STUDY, "seeds": 3}))
    proc = snakemake(work, "--config", "studies=[mini]", "-n", "--quiet", "rules", "--", target)
    assert proc.returncode == 0, proc.stderr[-2000:]
    counts = dict(re.findall(r"^(\w+)\s+(\d+)\s*$", proc.stdout + proc.stderr, re.M))
    assert (
        counts.get("mc_point") == "4" and counts.get("mc_aggregate") == "1" and counts.get("mc_report") == "1"
    )
    assert math.isclose(agg["cells"][0]["noise_um"], 0.1)
