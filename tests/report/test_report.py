"""Reports: every figure function drawn from small synthetic inputs, headline numbers read
back from the HTML, captions, SVG, autoescaping and the PDF (issue 7)."""

from __future__ import annotations

import copy
import re
import zlib

import numpy as np
import pytest
import xarray as xr
from markupsafe import escape

from calflow.nano.report.reference import STAGE1D, STAGE2D
from calflow.report import render_campaign, render_index, write_pdf
from calflow.report.render import num, render_campaign_pages, sig
from calflow.xytheta.report.reference import XYTHETA

EVIL = "Stage <script>alert('x')</script> & friends"
ISO230_KEYS = ("A", "A_fwd", "A_bwd", "E", "E_fwd", "E_bwd", "R", "R_fwd", "R_bwd", "M", "B", "B_mean")
CAMPAIGN_CMD = "snakemake --cores 2 --config 'campaigns=[\"t\"]'"


# ---------------------------------------------------------------- helpers
def _attrs(kind, robot, plan, **extra):
    return {
        "Conventions": "CF-1.11",
        "calflow_kind": kind,
        "calflow_version": "0",
        "campaign": "t",
        "robot": robot,
        "source": "simulated",
        "plan": plan,
        "config_sha256": "0" * 64,
        **extra,
    }


def _write(ds, path):
    path.parent.mkdir(parents=True, exist_ok=True)
    ds.to_netcdf(path, engine="netcdf4")
    return str(path)


def headline_cells(html):
    return re.findall(r'data-key="([^"]+)">([^<]+)<', html)


def lookup(summary, key):
    for part in key.split("."):
        summary = summary[part]
    return summary


def assert_headline_equals_summary(html, summary, must):
    cells = headline_cells(html)
    keys = {k for k, _ in cells}
    assert set(must) <= keys, f"missing headline keys: {set(must) - keys}"
    for key, text in cells:
        assert float(text) == pytest.approx(lookup(summary, key), abs=5e-4), key


def assert_figures(html, ids):
    figures = re.findall(r"<figure\b.*?</figure>", html, flags=re.S)
    assert figures, "the report has figures"
    for f in figures:
        assert "<figcaption" in f and "<svg" in f, f[:200]
        assert re.search(r"Figure \d+\.", f) and "cf. thesis Fig." in f
    found = re.findall(r'<figure id="([^"]+)"', html)
    assert set(ids) <= set(found), f"missing figures: {set(ids) - set(found)}"
    numbers = [int(n) for n in re.findall(r'class="fignum">Figure (\d+)\.', html)]
    assert numbers == list(range(1, len(figures) + 1))


def assert_escaped(html):
    assert "<script>alert" not in html
    assert "&lt;script&gt;alert(" in html


def pdf_pages(data: bytes) -> int:
    """Pages of a PDF: /Type /Page objects, in the file and inside its compressed streams."""
    chunks = [data]
    for m in re.finditer(rb"stream\r?\n", data):
        try:
            chunks.append(zlib.decompressobj().decompress(data[m.end() :]))
        except zlib.error:
            pass
    return sum(len(re.findall(rb"/Type\s*/Page(?![a-zA-Z])", c)) for c in chunks)


def _inputs(files):
    return {f: "ab" * 32 for f in files}


# ---------------------------------------------------------------- XYΘ fixture
MODELS = {
    "I": (["x_R", "y_R"], False, False),
    "II": (["x_R", "y_R", "alpha", "beta"], False, False),
    "III": (["x_R", "y_R", "alpha", "beta"], True, False),
    "IV": (["x_R", "y_R", "alpha", "beta"], False, True),
    "V": (["x_R", "y_R", "alpha", "beta"], True, True),
}


def _xy_model_entry(k, free):
    n = len(free)
    targets = [(i + 1, -1200.0 - 400 * (i % 3), -200.0 - 100 * (i // 3), float(1 + i % 5)) for i in range(9)]
    return {
        "accuracy_um": 90.0 / (k + 1) + 0.123456,
        "repeatability_um": 2.0 / (k + 1) + 0.0004,
        "free": free,
        "position_table": False,
        "angle_table": False,
        "parameters": {
            "x_R_um": {"value": 9572.9 + k, "std": 3.1},
            "y_R_um": {"value": 7795.8 - k, "std": 3.0},
            "alpha_deg": {"value": 177.69, "std": 0.004 if n > 2 else None},
            "beta_deg": {"value": -0.11, "std": 0.009 if n > 2 else None},
        },
        "correlation": np.eye(n).round(3).tolist(),
        "identifiability": {"r_diag": [1.25] * n if k < 3 else [], "not_identifiable": ""},
        "identification": {
            "O1": 7.3,
            "O2": 0.0011,
            "O3": 1.25,
            "O4": 0.0014,
            "condition_number": 876.0,
            "dof": 2396,
            "n_poses": 60,
            "residual_rms_um": 4.2,
            "cv_rms_um": 4.4,
            "cv_folds": 5,
            "sigma_fit_um": 3.0,
        },
        "protocol": "heldout",
        "per_target": [
            {
                "target": t,
                "x_um": 10.0 * t,
                "y_um": -5.0 * t,
                "theta_deg": 0.07 * t,
                "ap_um": 1.5 + k + t / 9,
                "rp_um": 0.4 + t / 90,
            }
            for t in range(1, 51)
        ],
        "reference_targets": {
            "accuracy_um": 80.0 / (k + 1) + 0.654321,
            "repeatability_um": 1.5 / (k + 1),
            "thesis_accuracy_um": 95.98,
            "per_target": [
                {
                    "target": t,
                    "x_um": x,
                    "y_um": y,
                    "theta_deg": th,
                    "ap_um": 1.0 + k + t / 10,
                    "rp_um": 0.3 + t / 100,
                }
                for t, x, y, th in targets
            ],
        },
        "adequacy": (
            {"chi2_dof": 1.02, "p_value": 0.4, "adequate": True, "floor_um": 0.5, "statement": "fits"}
            if k == 1
            else {
                "chi2_dof": 36.0,
                "p_value": 0.0,
                "adequate": False,
                "floor_um": 0.5,
                "statement": "The model does not fit: <b>not bold</b>",
            }
        ),
    }


@pytest.fixture(scope="module", autouse=True)
def strict():
    """A failing figure raises here instead of becoming a note in the report."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("CALFLOW_REPORT_STRICT", "1")
        yield


@pytest.fixture
def sketched(monkeypatch):
    """Figures built from the summary but neither laid out nor serialised as SVG (nine tenths
    of a figure's cost): for the tests that render a campaign again to read its text, notes
    and captions. Every figure is drawn in full, SVG and PNG, by the module's fixtures."""
    import matplotlib.figure
    import matplotlib.pyplot as plt
    from markupsafe import Markup

    from calflow.report import figures

    def to_svg(fig, key):
        plt.close(fig)
        return Markup(f'<svg role="img" aria-labelledby="{key}-caption" class="plot"></svg>')

    monkeypatch.setattr(figures, "to_svg", to_svg)
    monkeypatch.setattr(matplotlib.figure.Figure, "tight_layout", lambda self, *a, **k: None)


@pytest.fixture(scope="module")
def xytheta(xytheta_pages):
    """summary, files and the HTML report of a small XYΘ campaign."""
    return xytheta_pages[:3]


@pytest.fixture(scope="module")
def xytheta_pages(tmp_path_factory, strict):
    """summary, files, the HTML report and its print page (PNG figures, for the PDF)."""
    from calflow.data.runs import RunMetadata
    from calflow.xytheta.models.kinematics import Parameters
    from calflow.xytheta.models.ladder import MicroModel
    from calflow.xytheta.tables.angle_residuals import AngleLUT
    from calflow.xytheta.tables.pose import PoseAngleLUT

    root = tmp_path_factory.mktemp("xytheta")
    files = []
    x, y = np.arange(0.0, 2000.0, 10.0), np.arange(0.0, 800.0, 10.0)
    d = np.array([1, -1], dtype="int8")
    luts = xr.Dataset(
        {
            **{
                f"err_{k}": (
                    (f"{p}_position", "direction"),
                    np.stack([np.sin(c / 64.0), np.sin(c / 64.0) + 1], axis=1),
                    {"units": "um"},
                )
                for k, p, c in (("xx", "x", x), ("xy", "x", x), ("yy", "y", y), ("yx", "y", y))
            },
            **{
                f"rep_{k}": (
                    (f"{p}_position", "direction"),
                    np.abs(np.cos(np.stack([c, c], 1))) / 3,
                    {"units": "um"},
                )
                for k, p, c in (("xx", "x", x), ("xy", "x", x), ("yy", "y", y), ("yx", "y", y))
            },
            **{f"period_{k}": ((), 400.0) for k in ("xx", "xy", "yy", "yx")},
        },
        coords={"x_position": x, "y_position": y, "direction": d},
        attrs=_attrs("luts", "xytheta", "characterisation", repeatability_definition="range over cycles"),
    )
    files.append(_write(luts, root / "luts/position.nc"))
    xy_tests = {}
    for plan, n in (("square", 40), ("random_points", 8)):
        for c, scale in (("none", 20.0), ("linear", 1.0), ("cubic", 0.8)):
            t = np.arange(1, n + 1)
            ap = scale * (1 + np.sin(t))
            ds = xr.Dataset(
                {
                    "target_x": ("target", t * 10.0),
                    "target_y": ("target", t * 5.0),
                    "ap": ("target", ap),
                    "rp": ("target", ap / 10),
                },
                coords={"target": t},
                attrs=_attrs(
                    "metrics",
                    "xytheta",
                    plan,
                    compensation=c,
                    accuracy_um=ap.max(),
                    repeatability_um=ap.max() / 10,
                ),
            )
            files.append(_write(ds, root / f"metrics/{plan}_{c}.nc"))
            xy_tests.setdefault(plan, {})[c] = {
                "accuracy_um": float(ap.max()),
                "repeatability_um": float(ap.max() / 10),
                "per_target": [{"target": int(i), "ap_um": float(a)} for i, a in zip(t, ap)],
            }
    rng = np.random.default_rng(1)
    run = xr.Dataset(
        {
            "cmd_x": ("sample", rng.uniform(0, 4000, 60)),
            "cmd_y": ("sample", rng.uniform(800, 2800, 60)),
            "cmd_theta": ("sample", rng.uniform(0, 5, 60)),
        },
        attrs=_attrs("run", "xytheta", "identification"),
    )
    files.append(_write(run, root / "runs/identification.nc"))
    meta = RunMetadata("t", "xytheta", "simulated", "identify", "0" * 64)
    f = np.array([0, 1, -5, -3, 3, 4.0])
    tables = {
        "IV": AngleLUT(np.arange(6.0), f, f[::-1], 177.7, -0.1),  # one row, and per target (position x angle)
        "V": PoseAngleLUT(
            np.array([0.0, 100, 200]),
            np.array([0.0, 0, 50]),
            np.arange(6.0),
            np.stack([f, f + 1, f - 1]),
            np.stack([f, f * 2, f / 2]),
            177.7,
            -0.1,
        ),
    }
    for name, angle in tables.items():
        model = MicroModel(
            name,
            Parameters(9572.9, 7795.9, 177.7, -0.1),
            ("x_R", "y_R", "alpha", "beta"),
            {},
            np.eye(4),
            {},
            None,
            angle,
        )
        path = root / f"models/{name}.nc"
        path.parent.mkdir(parents=True, exist_ok=True)
        model.write(path, meta)
        files.append(str(path))
    poses = [3, 10, 30, 100, 300]
    summary = {
        "campaign": "t",
        "robot": "xytheta",
        "description": EVIL,
        "calflow_version": "0.1.0",
        "seed": 7,
        "rig": "simulated",
        "models": {name: _xy_model_entry(k, free) for k, (name, (free, _, _)) in enumerate(MODELS.items())},
        "reference": copy.deepcopy(XYTHETA),
        "inputs": _inputs(files),
        "characterisation": {
            "x_stage_angle": -2.31,
            "perpendicularity": -0.11,
            "periods_um": {k: 400.0 for k in ("xx", "xy", "yy", "yx")},
            "repeatability_um": {k: {"median": 0.2, "max": 0.5} for k in ("xx", "xy", "yy", "yx")},
            "peak_to_valley_um": {k: 2.0 for k in ("xx", "xy", "yy", "yx")},
        },
        "xy_tests": xy_tests,
        "observability": {
            "poses": poses,
            **{
                k: [float(p) ** e for p in poses]
                for k, e in (("O1", 0.5), ("O2", -0.1), ("O3", 0.3), ("O4", 0.2))
            },
            "O2_plateau_poses": 30,
        },
        "truth": {"parameters": {"x_R_um": 9572.9, "y_R_um": 7795.9, "alpha_deg": 177.69, "beta_deg": -0.11}},
        "iso230_2": {
            a: {
                "units": "um",
                "targets": 41,
                "cycles_forward": 5,
                "cycles_backward": 5,
                **{f"{k}_um": 1.0 + 0.1 * j + (0.05 if a == "y" else 0.0) for j, k in enumerate(ISO230_KEYS)},
            }
            for a in "xy"
        },
    }
    for name, (_, pos, ang) in MODELS.items():
        summary["models"][name].update(position_table=pos, angle_table=ang)
    html, printed = render_campaign_pages(
        summary, {"name": "t", "robot": "xytheta", "description": EVIL}, CAMPAIGN_CMD, files
    )
    return summary, files, html, printed


def test_xytheta_headline_equals_summary(xytheta):
    summary, _, html = xytheta
    must = [f"models.{m}.accuracy_um" for m in MODELS] + [f"models.{m}.repeatability_um" for m in MODELS]
    must += [f"models.{m}.reference_targets.accuracy_um" for m in MODELS]
    must += [
        f"xy_tests.{p}.{c}.accuracy_um"
        for p in ("square", "random_points")
        for c in ("none", "linear", "cubic")
    ]
    assert_headline_equals_summary(html, summary, must + ["observability.O2_plateau_poses"])


def test_xytheta_characterisation_has_every_iso230_2_value_per_axis(xytheta):
    summary, _, html = xytheta
    assert_headline_equals_summary(html, summary, [f"iso230_2.{a}.{k}_um" for a in "xy" for k in ISO230_KEYS])
    assert "B = max |B_i|" in html and "B̄" in html and "E↑" in html and "A↓" in html


def test_xytheta_report_shows_both_protocols_and_says_when_a_model_does_not_fit(xytheta):
    summary, _, html = xytheta
    assert "held-out AP" in html and "reference-target AP" in html
    assert html.count("The model does not fit") == len(MODELS) - 1  # every model but the adequate one
    assert "&lt;b&gt;not bold&lt;/b&gt;" in html  # summary text is escaped
    # the adequate model prints value ± σ; an inadequate one does not
    assert "assumes a fit the model does not have" in html and "± 3.1" in html
    assert html.count("P50") >= 1  # the 50 held-out targets are listed


def test_xytheta_figures_have_captions_svg_and_units(xytheta):
    _, _, html = xytheta
    assert_figures(
        html,
        [
            "fig-errors",
            "fig-coupling",
            "fig-repeatability",
            "fig-square",
            "fig-random",
            "fig-poses",
            "fig-observability",
            "fig-validation",
            "fig-angle",
        ],
    )
    assert "(µm)" in html and "number of poses" in html and "rotation Θ (°)" in html
    assert "Table 4.8" in html and "95.980" in html  # thesis column beside ours
    assert "simulated truth" in html


def test_xytheta_escapes_and_records_provenance(xytheta):
    summary, files, html = xytheta
    assert_escaped(html)
    for f in files:
        assert f in html
    assert str(escape(CAMPAIGN_CMD)) in html and "calflow report --campaign" in html
    assert "matplotlib" in html and "weasyprint" in html


def test_xytheta_without_identification_run_says_so(xytheta, sketched):
    summary, files, _ = xytheta
    html = render_campaign(
        summary, {"name": "t"}, CAMPAIGN_CMD, [f for f in files if "identification" not in f]
    )
    assert 'id="fig-poses"' not in html and "runs/identification.nc" in html and "Note:" in html


def test_xytheta_pdf_has_pages(xytheta_pages, tmp_path):
    _, _, html, printed = xytheta_pages
    figures = re.findall(r'<figure id="([^"]+)"', html)
    assert re.findall(r'<figure id="([^"]+)"', printed) == figures  # the same figures, as PNG
    assert printed.count('src="data:image/png;base64,') == len(figures) and "<svg" not in printed
    pdf = write_pdf(printed, tmp_path)
    assert pdf[:4] == b"%PDF"
    try:
        import io

        import pypdf

        pages = len(pypdf.PdfReader(io.BytesIO(pdf)).pages)
    except ImportError:
        pages = pdf_pages(pdf)
    assert pages > 1


# ---------------------------------------------------------------- nano fixtures
def _series(n, t0, temp0, in_range=True):
    t = np.arange(n) * 3.0 + t0
    return {
        "test": list(range(n)),
        "time_h": t.tolist(),
        "campaign_time_h": (t + 18).tolist(),
        "day": [0] * n,
        "max_ap_nm": (100 + 10 * np.sin(t)).tolist(),
        "max_rp_nm": (40 + np.cos(t)).tolist(),
        "max_rp_intrinsic_nm": [35.0] * n,
        "temperature_c": (temp0 + 0.1 * np.sin(t)).tolist(),
        "temperature_range_c": [0.02] * n,
        "in_training_range": [in_range, not in_range] * (n // 2) + [in_range] * (n % 2),
    }


def _nano(tmp_path_factory, robot):
    root = tmp_path_factory.mktemp(robot)
    axes = ["x"] if robot == "stage1d" else ["x", "y"]
    modes = (
        ["no_calibration", "adaptive_kmz", "single"] if robot == "stage1d" else ["no_calibration", "single"]
    )
    rng = np.random.default_rng(3)
    cmd = np.tile(np.r_[np.arange(0, 100, 20.0), np.arange(80, -1, -20.0)], 4)
    n = cmd.size
    direction = np.tile(np.r_[np.ones(5), -np.ones(5)], 4).astype("int8")
    data = {
        "time": ("sample", np.arange(n) * 60.0, {"units": "seconds since 2026-01-05T08:00:00+00:00"}),
        "temperature": (
            ("sample", "sensor"),
            20.4 + 0.01 * rng.standard_normal((n, 4)) + np.linspace(0, 0.1, n)[:, None],
        ),
        "pose": ("sample", np.tile(np.arange(10), 4)),
        "cycle": ("sample", np.repeat(np.arange(4), 10)),
        "direction": ("sample", direction),
    }
    for a in axes:
        data[f"cmd_{a}"] = ("sample", cmd)
        data[f"meas_{a}"] = ("sample", cmd + 1e-4 * cmd * (100 - cmd) / 10 + 0.05 * rng.standard_normal(n))
    if robot == "stage1d":
        data["meas_y"] = ("sample", 0.01 * rng.standard_normal(n))
    files = [
        _write(
            xr.Dataset(
                data, coords={"sensor": ["T1", "T2", "T3", "T4"]}, attrs=_attrs("run", robot, "training")
            ),
            root / "runs/training.nc",
        )
    ]
    ntest, npose = 3 * len(modes), 4
    val = {
        "ap": (("test", "pose"), rng.uniform(10, 400, (ntest, npose))),
        "mode": ("test", np.tile(np.arange(len(modes)), 3), {"flag_meanings": " ".join(modes)}),
        "time_h": ("test", 20.0 + 1.3 * np.arange(ntest)),
        "direction": ("pose", np.array([1, 1, -1, -1])),
        "target_x": ("pose", np.array([0.0, 50, 50, 0])),
    }
    if robot == "stage2d":
        val["target_y"] = ("pose", np.array([0.0, 10, 20, 30]))
    files.append(
        _write(
            xr.Dataset(
                val,
                coords={"test": np.arange(ntest), "pose": np.arange(npose)},
                attrs=_attrs("metrics", robot, "validation", start_time_h=18.0),
            ),
            root / "metrics/validation.nc",
        )
    )
    tests = {
        m: {
            "max_accuracy_nm": 300.0 / (k + 1) + 0.0123,
            "max_accuracy_nm_by_day": [100.0, 200.0],
            "max_repeatability_nm": 50.0 + k,
            "max_repeatability_nm_by_day": [40.0, 50.0],
            "max_intrinsic_repeatability_nm": 40.0,
            "n_tests": 5,
            "series": _series(5, 0.5 + k, 20.4 + 0.05 * k),
        }
        for k, m in enumerate(modes)
    }
    coef = [
        {
            "in_model": True,
            "long_name": "coefficient of x^1",
            "name": "a_1",
            "p_value": 0.0,
            "std_error": 1.9e-5,
            "unit": "1",
            "value": 1.0056,
        },
        {
            "in_model": False,
            "long_name": "thermal coefficient of t_1",
            "name": "b_1",
            "p_value": 0.24,
            "std_error": 0.2,
            "unit": "um degC-1",
            "value": 0.0,
        },
        {
            "in_model": True,
            "long_name": "offset",
            "name": "lambda",
            "p_value": None,
            "std_error": 0.07,
            "unit": "um",
            "value": -23.3,
        },
    ]
    summary = {
        "campaign": "t",
        "robot": robot,
        "description": EVIL,
        "calflow_version": "0.1.0",
        "seed": 5,
        "rig": "simulated",
        "models": {m: coef for m in modes if m != "no_calibration"},
        "budget": {
            "combined_nm": 40.509,
            "rows": [
                {
                    "category": "intrinsic",
                    "formula": "L x stability / sqrt(3)",
                    "name": "U_1 laser wavelength",
                    "value_nm": 0.0866,
                },
                {
                    "category": "combined",
                    "formula": "sqrt(sum)",
                    "name": "combined standard uncertainty",
                    "value_nm": 40.509,
                },
            ],
        },
        "reference": copy.deepcopy({"stage1d": STAGE1D, "stage2d": STAGE2D}[robot]),
        "inputs": _inputs(files),
        "tests": tests,
        "robustness": {
            m: {
                "space": 0.3543 / (k + 1),
                "time": 0.0064 / (k + 1),
                "duration_h": 117.3,
                "n_tests": 32,
                "units": {"space": "um", "time": "um/h", "ap": "um", "duration": "h"},
            }
            for k, m in enumerate(modes)
        },
        "training": {
            "accuracy_nm": 370.1,
            "repeatability_nm": 238.5,
            "temperature_c": 20.45,
            "temperature_range_c": 0.1,
            "per_pose": [],
        },
        "validation": {
            "start_h": 18.0,
            "end_h": 40.0,
            "duration_h": 22.0,
            "days": 2,
            "n_tests": ntest,
            "training_temperature_range_c": [20.38, 20.5],
            "drift_estimator": "per-cycle mean",
        },
    }
    no_stream = "not supported by this data: no stream <recorded>"
    summary["iso9283"] = {
        "standard": "ISO 9283:1998",
        "source": "validation run",
        "axes": ["x"],
        "modes": {
            m: {
                **{
                    k: {"value": 10.0 * (j + 1) + k_m, "unit": "nm", "clause": c}
                    for j, (k, c) in enumerate((("AD", "7.4.1"), ("RD", "7.4.2"), ("dRP", "7.7")))
                },
                "vAP": (
                    {"value": 3.25, "unit": "nm", "clause": "7.3"}
                    if robot == "stage1d"
                    else {
                        "value": None,
                        "unit": "nm",
                        "clause": "7.3",
                        "reason": "not supported by this data: one direction",
                    }
                ),
                "dAP": {
                    "value": 55.5,
                    "unit": "nm",
                    "clause": "7.7",
                    "first_test": 0,
                    "last_test": 4,
                    "period_h": 20.0,
                },
                "stabilisation_time_s": {"value": None, "unit": "s", "clause": "7.5", "reason": no_stream},
                "overshoot": {"value": None, "unit": "nm", "clause": "7.6", "reason": no_stream},
            }
            for k_m, m in enumerate(modes)
        },
    }
    if robot == "stage1d":
        summary["intrinsic"] = {
            "accuracy_nm": 401.4468,
            "repeatability_nm": 41.2433,
            "temperature_c": 20.5,
            "temperature_range_c": 0.009,
            "per_pose": [
                {"pose": i, "direction": d, "target_x_um": tx, "ap_nm": 100.0 + i, "rp_nm": 30.0 + i}
                for i, (d, tx) in enumerate(
                    [(1, 0.0), (1, 80.0), (1, 160.0), (-1, 160.0), (-1, 80.0), (-1, 0.0)]
                )
            ],
        }
        summary["iso230_2"] = {f"{k}_nm": 100.0 + j for j, k in enumerate(ISO230_KEYS)}
        summary["iso230_2"].update(cycles_forward=4, cycles_backward=4, excluded_targets_um=[])
    html = render_campaign(
        summary,
        {
            "name": "t",
            "robot": robot,
            "reference": {"stage1d": "thesis-sec5.3", "stage2d": "thesis-sec5.4"}[robot],
        },
        CAMPAIGN_CMD,
        files,
    )
    return summary, files, html


@pytest.fixture(scope="module")
def stage1d(tmp_path_factory, strict):
    return _nano(tmp_path_factory, "stage1d")


@pytest.fixture(scope="module")
def stage2d(tmp_path_factory, strict):
    return _nano(tmp_path_factory, "stage2d")


def test_stage1d_report(stage1d):
    summary, files, html = stage1d
    must = ["intrinsic.accuracy_nm", "intrinsic.repeatability_nm", "budget.combined_nm"]
    must += [f"tests.{m}.max_accuracy_nm" for m in summary["tests"]]
    must += [f"robustness.{m}.{k}" for m in summary["robustness"] for k in ("space", "time")]
    must += [f"iso230_2.{k}_nm" for k in ISO230_KEYS]
    assert_headline_equals_summary(html, summary, must)
    assert_figures(
        html,
        [
            "fig-geometric",
            "fig-drift",
            "fig-metrology",
            "fig-poses-time",
            "fig-max",
            "fig-temperature",
            "fig-acc-temp",
        ],
    )
    assert_escaped(html)
    assert "Fig. 5.18" in html and "Fig. 5.19" in html and "40.600" in html and "ISO 230-2" in html
    assert "µm/°C" in html and "(nm)" in html and "(°C)" in html
    assert all(f in html for f in files)


def test_stage2d_report(stage2d):
    summary, _, html = stage2d
    must = [f"tests.{m}.max_accuracy_nm" for m in summary["tests"]] + ["budget.combined_nm"]
    assert_headline_equals_summary(html, summary, must)
    assert_figures(
        html, ["fig-geometric", "fig-drift", "fig-poses-time", "fig-max", "fig-temperature", "fig-acc-temp"]
    )
    assert "Fig. 5.23" in html and "Fig. 5.24" in html
    assert_escaped(html)
    assert (
        "multi-directional pose accuracy variation vAP (clause 7.3) — not supported by this data: one direction"
        in html
    )


def test_nano_reports_show_iso9283_with_clauses_and_say_what_is_missing(stage1d, stage2d):
    for summary, _, html in (stage1d, stage2d):
        modes = summary["iso9283"]["modes"]
        keys = [f"iso9283.modes.{m}.{k}.value" for m in modes for k in ("AD", "RD", "dAP", "dRP")]
        assert_headline_equals_summary(html, summary, keys)
        section = html[html.index('<section id="iso9283">') :]
        section = section[: section.index("</section>")]
        for clause in ("7.3", "7.4.1", "7.4.2", "7.5", "7.6", "7.7"):
            assert f'<td class="text">{clause}</td>' in section, clause
        assert (
            "Not computed: position stabilisation time (clause 7.5); position overshoot OV (clause 7.6) — "
            "not supported by this data: no stream &lt;recorded&gt;."
        ) in section
        assert "Drift compares test 0 with test 4, 20.0 h apart" in section


def test_index_links_and_headlines(xytheta, stage1d, stage2d):
    summaries = []
    for name, (s, _, _) in zip(("xy", "one", "two"), (xytheta, stage1d, stage2d)):
        s = copy.deepcopy(s)
        s["campaign"] = name
        summaries.append(s)
    html = render_index(summaries)
    for s in summaries:
        assert f'href="{s["campaign"]}/report.html"' in html and f'href="{s["campaign"]}/report.pdf"' in html
        cells = re.findall(rf'data-campaign="{s["campaign"]}" data-key="([^"]+)">([^<]+)<', html)
        assert cells
        for key, text in cells:
            assert float(text) == pytest.approx(lookup(s, key), abs=5e-4), (s["campaign"], key)
    assert_escaped(html)
    assert "95.980" in html and "≈ 1000" in html


def test_a_failing_figure_becomes_a_note(xytheta, sketched, monkeypatch):
    summary, files, _ = xytheta
    monkeypatch.delenv("CALFLOW_REPORT_STRICT")
    broken = copy.deepcopy(summary)
    broken["observability"]["O1"] = ["not a number"] * len(broken["observability"]["poses"])
    html = render_campaign(broken, {"name": "t"}, CAMPAIGN_CMD, files)
    assert 'id="fig-observability"' not in html and "could not be drawn" in html
    assert 'id="fig-validation"' in html


def test_number_formats():
    assert num(None) == "—" and num(float("nan")) == "—" and num(1.23456) == "1.235"
    assert sig(2.663e-08, 4) == "2.663 × 10⁻⁸" and sig(1067.5, 3) == "1068" and sig(0.0451, 3) == "0.0451"
    assert sig(None) == "—" and sig(0.0) == "0"


def _thesis_phrases(html: str) -> list[str]:
    """Every phrase of a page's text around the word "thesis" (tags stripped)."""
    text = re.sub(r"<style.*?</style>|<svg.*?</svg>", " ", html, flags=re.S)
    text = re.sub(r"\s+", " ", re.sub(r"<[^>]+>", " ", text))
    return [text[max(0, m.start() - 60) : m.end() + 40] for m in re.finditer(r"thesis", text)]


def test_a_campaign_without_reference_has_no_reference_column_and_no_comparing_sentence(
    xytheta, stage1d, stage2d, sketched
):
    """A lab's own stage (no ``reference`` key): no grey column, no sentence setting it beside the
    thesis; the thesis is still cited for the method (figure, section and equation numbers)."""
    for summary, files, with_ref in (xytheta, stage1d, stage2d):
        own = copy.deepcopy(summary)
        own["reference"] = {}
        html = render_campaign(own, {"name": "t", "robot": own["robot"]}, CAMPAIGN_CMD, files)
        assert 'class="ref"' not in html and 'class="num ref"' not in html, own["robot"]
        assert 'class="num ref"' in with_ref  # the same summary with its reference has the column
        for phrase in _thesis_phrases(html):
            assert not re.search(
                r"beside|thesis values|thesis's (order|maxima|Table)|thesis reports|thesis AP|thesis R_|dashed",
                phrase,
                re.I,
            ), (own["robot"], phrase)
        assert (
            "40.600" not in html and ">40.6<" not in html
        )  # the thesis's interferometer figure is no fallback


def test_a_reference_is_labelled_with_its_source(stage1d, sketched):
    summary, files, _ = stage1d
    mine = copy.deepcopy(summary)
    mine["reference"] = {"source": "Smith 2024, Table 3", "intrinsic": {"accuracy_nm": 123.0}}
    html = render_campaign(mine, {"name": "t", "robot": "stage1d"}, CAMPAIGN_CMD, files)
    assert "Smith 2024, Table 3" in html and "≈ 123" in html
    index = render_index([mine])
    assert "Smith 2024, Table 3" in index and 'class="num ref"' in index
