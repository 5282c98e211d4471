"""Export of XYΘ models: controller files, the bundle, the Compensator (docs/export.md)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import xarray as xr
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from calflow.errors import DataError
from calflow.xytheta.export import Compensator
from calflow.xytheta.export import controllers as ctl
from calflow.xytheta.export.bundle import load, write_bundle
from calflow.xytheta.export.tables import rebuild, write_tables
from calflow.xytheta.export.verification import export_plan
from calflow.xytheta.export.writer import export_model
from calflow.xytheta.models.kinematics import Parameters
from calflow.xytheta.models.ladder import MicroModel
from calflow.xytheta.tables.angle import AngleTable
from calflow.xytheta.tables.angle_residuals import AngleLUT
from calflow.xytheta.tables.pose import PoseAngleLUT
from calflow.xytheta.tables.position import PositionLUT

PROV = {"campaign": "test", "config_sha256": "0" * 64, "export_calflow_version": "test"}
small = st.floats(-20.0, 20.0, allow_nan=False)


def _lut(seed: int, n: int = 41, cross: float = 1.0) -> PositionLUT:
    """Smooth random XY tables over 0..2000 µm, forward and backward differing (backlash)."""
    rng = np.random.default_rng(seed)
    q = np.linspace(0.0, 2000.0, n)

    def tab(scale):
        a, p = rng.uniform(-scale, scale, 2), rng.uniform(0, 2 * np.pi, 2)
        return np.column_stack(
            [a[0] * np.sin(q / 300 + p[0]) + 0.5 * scale, a[1] * np.sin(q / 300 + p[1]) - 0.5 * scale]
        )

    return PositionLUT(q, q, tab(3.0), cross * tab(1.0), cross * tab(1.0), tab(2.0))


def _model(position=None, angle=None) -> MicroModel:
    p = Parameters(9500.0, 7700.0, 177.7, -0.09)
    return MicroModel(
        "V",
        p,
        ("x_R", "y_R", "alpha", "beta"),
        {"x_R": 1.0, "y_R": 1.1, "alpha": 0.01, "beta": 0.02},
        np.eye(4),
        {},
        position,
        angle,
        "linear",
    )


# --- controller files ---------------------------------------------------------------

comp_strategy = st.integers(2, 40).flatmap(
    lambda n: st.tuples(
        arrays(float, n, elements=st.floats(0.1, 500.0)),
        arrays(float, n, elements=small),
        arrays(float, n, elements=small),
    )
)


@settings(max_examples=30, deadline=None)
@given(comp_strategy)
def test_linuxcnc_file_reads_back_what_was_written(tmp_path_factory, data):
    steps, fwd, rev = data
    comp = ctl.AxisCompensation("x", np.cumsum(steps) - 1000.0, fwd, rev)
    path = tmp_path_factory.mktemp("lcnc") / "x.comp"
    ctl.write_linuxcnc(comp, path)
    back = ctl.read_linuxcnc(path, "x")
    for name in ("nominal", "forward", "reverse"):  # 7 decimals of a millimetre: 0.1 nm
        assert np.max(np.abs(getattr(back, name) - getattr(comp, name))) <= 0.5e-4 + 1e-9


@settings(max_examples=30, deadline=None)
@given(comp_strategy)
def test_twincat_list_reads_back_to_its_resolution(tmp_path_factory, data):
    steps, fwd, rev = data
    comp = ctl.AxisCompensation("y", np.cumsum(steps), fwd, rev)
    path = tmp_path_factory.mktemp("tc") / "y.lis"
    ctl.write_twincat(comp, path, 7, "provenance line")
    back, number = ctl.read_twincat(path)
    assert number == 7 and back.axis == "y"
    for name in ("nominal", "forward", "reverse"):  # integers of 0.1 µm
        assert np.max(np.abs(getattr(back, name) - getattr(comp, name))) <= 0.05 + 1e-9


def test_linuxcnc_type_1_example_of_its_documentation(tmp_path):
    """ini-config.adoc's Type 1 example; control.c adds the trim of the direction of travel."""
    path = tmp_path / "doc.comp"
    path.write_text("-1.000 0.005 -0.005\n0.000 0.002 -0.003\n1.000 0.003 -0.004\n")
    comp = ctl.read_linuxcnc(path, "x")
    assert comp.correction(500.0, 1) == pytest.approx(2.5)  # µm: halfway between 0.002 and 0.003 mm
    assert comp.correction(-500.0, -1) == pytest.approx(-4.0)
    commands, d = comp.command([500.0, 500.0, -500.0], start=0.0)  # no change keeps the last direction
    assert list(d) == [1, 1, -1]
    assert commands == pytest.approx([502.5, 502.5, -504.0])


def test_twincat_values_are_errors_the_controller_subtracts(tmp_path):
    """P-COMP-00023's example: setpoint 19866.7 µm reached at 19856.5 µm, value -102 (0.1 µm)."""
    path = tmp_path / "y.lis"
    lines = [
        "kopf.achs_nr 2",
        "kw.ssfk.unit 1",
        "kw.ssfk.bilateral 1",
        "kw.ssfk.kw_nr_max 2",
        "kw.ssfk.table[0].setpoint 198000",
        "kw.ssfk.table[1].setpoint 198667",
        "kw.ssfk.table[0].pos 0",
        "kw.ssfk.table[1].pos -102",
        "kw.ssfk.table[0].neg 0",
        "kw.ssfk.table[1].neg 80",
    ]
    path.write_text("\n".join(lines) + "\n")
    comp, number = ctl.read_twincat(path, "y")
    assert number == 2
    assert comp.correction(19866.7, 1) == pytest.approx(
        10.2
    )  # the stage falls 10.2 µm short: command 10.2 more
    assert comp.correction(19866.7, -1) == pytest.approx(-8.0)


@pytest.mark.parametrize(
    "text, field",
    [
        ("0 0 0\n# comment\n1 0 0\n", "line 2"),
        ("1 0 0\n0 0 0\n", "ascending"),
        ("0 0\n1 0 0\n", "line 1"),
        ("0 0 0\n\n1 0 0\n", "line 2"),
    ],
)
def test_bad_linuxcnc_files_are_refused_naming_the_problem(tmp_path, text, field):
    path = tmp_path / "bad.comp"
    path.write_text(text)
    with pytest.raises(DataError, match=field):
        ctl.read_linuxcnc(path, "x")


def test_bad_twincat_list_is_refused(tmp_path):
    path = tmp_path / "bad.lis"
    path.write_text("kw.ssfk.unit 1\nkw.ssfk.bilateral 1\nkw.ssfk.kw_nr_max 2\nkw.ssfk.table[0].setpoint 0\n")
    with pytest.raises(DataError, match="kw.ssfk.table"):
        ctl.read_twincat(path)


@settings(max_examples=8, deadline=None)
@given(st.integers(0, 10_000))
def test_controller_correction_reproduces_the_model_command_at_the_entries(seed):
    """nominal + t(nominal) solves X = N + e(X) — the model's inverse — at every table entry."""
    lut = _lut(seed, cross=0.0)
    for axis, col in (("x", 0), ("y", 1)):
        comp, info = ctl.from_position_table(lut, axis)
        assert info["resampling_error_um"]["forward"] < 1e-12
        N = comp.nominal[2:-2]
        for d in (1, -1):
            dd = np.full(N.shape, d)
            X = lut.compensate(N, N, dd, dd, iterations=30)[col]
            assert np.allclose(N + comp.correction(N, d), X, atol=1e-9)


def test_resampled_table_keeps_its_size_and_reports_its_error():
    lut = _lut(3, n=401)
    comp, info = ctl.from_position_table(lut, "x", max_entries=50)
    assert comp.nominal.size == 50 and comp.nominal[0] == 0.0 and comp.nominal[-1] == 2000.0
    full, _ = ctl.from_position_table(lut, "x")
    err = np.max(np.abs(np.interp(full.nominal, comp.nominal, comp.forward) - full.forward))
    assert info["resampling_error_um"]["forward"] == pytest.approx(err)
    assert 0 < err < 0.05  # smooth tables: a least-squares fit on 50 knots is close


# --- bundle and Compensator -----------------------------------------------------------


@settings(max_examples=25, deadline=None)
@given(arrays(float, (3, 2), elements=small), arrays(float, 4, elements=small), small)
def test_tables_round_trip_exactly(tmp_path_factory, a, b, scalar):
    ds = xr.Dataset(
        {
            "f": (("p", "direction"), a, {"units": "um"}),
            "g": (("theta",), b, {"units": "um"}),
            "alpha": ((), scalar, {"units": "degree"}),
        },
        coords={
            "direction": ("direction", np.array([1, -1], dtype=np.int8)),
            "theta": ("theta", np.linspace(0, 5, 4), {"units": "degree"}),
        },
        attrs={"table": "t"},
    )
    folder = tmp_path_factory.mktemp("tables")
    back = rebuild(folder, json.loads(json.dumps(write_tables(ds, folder, "angle_table"))))
    assert back.attrs == {"table": "t"}
    for name in ("f", "g", "alpha"):
        assert np.array_equal(back[name].values, ds[name].values)
    assert np.array_equal(back["theta"].values, ds["theta"].values)
    assert list(back["direction"].values) == [1, -1]
    assert (folder / "angle_table_theta.csv").read_text().splitlines()[0] == "theta [degree],g [um]"


def _angles(kind: str, seed: int):
    rng = np.random.default_rng(seed)
    theta = np.linspace(0.0, 5.0, 6)
    if kind == "angle":
        return AngleTable(theta, rng.normal(0, 3, (2, 6)), rng.normal(0, 3, (2, 6)), 177.7, -0.09)
    if kind == "lut":
        return AngleLUT(theta, rng.normal(0, 3, 6), rng.normal(0, 3, 6), 177.7, -0.09)
    return PoseAngleLUT(
        np.array([-2000.0, -1200.0]),
        np.array([-400.0, -200.0]),
        theta,
        rng.normal(0, 3, (2, 6)),
        rng.normal(0, 3, (2, 6)),
        177.7,
        -0.09,
    )


@settings(max_examples=12, deadline=None)
@given(st.integers(0, 1000), st.sampled_from(["angle", "lut", "pose", None]), st.booleans())
def test_compensator_commands_exactly_as_the_in_process_model(tmp_path_factory, seed, angle, position):
    model = _model(_lut(seed) if position else None, _angles(angle, seed) if angle else None)
    folder = tmp_path_factory.mktemp("bundle")
    write_bundle(model, folder, PROV)
    comp = Compensator.load(folder)
    rng = np.random.default_rng(seed)
    X = rng.uniform(200, 1800, 8)
    Y = rng.uniform(200, 1800, 8)
    t = rng.uniform(0, 5, 8)
    x, y = model.forward(X, Y, t)
    Xc, Yc, tc = comp.joints(x, y, t)
    Xm, Ym = model.inverse(x, y, t)
    assert np.array_equal(Xc, Xm) and np.array_equal(Yc, Ym) and np.array_equal(tc, t)
    doc = load(folder)
    assert doc["parameters"]["alpha"] == {"value": 177.7, "std": 0.01, "units": "degree", "free": True}
    assert doc["provenance"]["config_sha256"] == "0" * 64


def test_bundle_of_another_format_is_refused(tmp_path):
    (tmp_path / "bundle.json").write_text(json.dumps({"format": "other", "version": 1}))
    with pytest.raises(DataError, match="format"):
        Compensator.load(tmp_path)


def test_export_writes_every_file_and_the_plan_commands_through_them(tmp_path):
    from calflow.data.runs import RunMetadata

    model = _model(_lut(5, n=401), _angles("angle", 5))
    path = tmp_path / "V.nc"
    model.write(
        path,
        RunMetadata(
            campaign="test",
            robot="xytheta",
            source="simulated",
            plan="identification",
            config_sha256="1" * 64,
            start="2026-01-01T00:00:00+00:00",
            model="V",
        ),
    )
    info = export_model(path, tmp_path / "V")
    names = {p.name for p in (tmp_path / "V").iterdir()}
    assert {
        "bundle.json",
        "README.md",
        "linuxcnc_x.comp",
        "linuxcnc_y.comp",
        "twincat_x_ssfk.lis",
        "twincat_y_ssfk.lis",
    } <= names
    assert (
        info["files"]["linuxcnc_x.comp"]["entries"] == 256
        and info["files"]["twincat_x_ssfk.lis"]["entries"] == 401
    )
    assert "cross-axis" in (tmp_path / "V" / "README.md").read_text()
    rng = np.random.default_rng(1)
    X, Y, t = rng.uniform(300, 1700, 4), rng.uniform(300, 1700, 4), rng.uniform(0, 5, 4)
    targets = np.column_stack([*model.forward(X, Y, t), t])
    plan, paths = export_plan(tmp_path / "V", targets, 2, 0.5)
    assert paths == ("bundle", "linuxcnc", "twincat")
    mode = plan.extra["mode"]
    assert len(plan) == 3 * (1 + 8) and list(plan.pose[mode == 1][:3]) == [0, 1, 2]
    tt = np.tile(targets, (2, 1))
    for k in range(3):  # each segment starts at the uncompensated home pose
        assert plan.commands["x"][mode == k][0] == 0.0 and plan.commands["y"][mode == k][0] == 0.0
    Xm, Ym = model.inverse(tt[:, 0], tt[:, 1], tt[:, 2])
    assert np.array_equal(plan.commands["x"][mode == 0][1:], Xm)
    # the controller rows: nominal kinematics plus the file's correction, a few µm from the model's
    # (own-axis terms kept, cross-axis terms and the file's resolution not)
    lc = plan.commands["x"][mode == 1][1:]
    assert 0 < np.max(np.abs(lc - Xm)) < 5.0


def _meta():
    from calflow.data.runs import RunMetadata

    return RunMetadata(
        campaign="test",
        robot="xytheta",
        source="simulated",
        plan="validation_export",
        config_sha256="1" * 64,
        start="2026-01-01T00:00:00+00:00",
        model="V",
    )


def _visits(targets, offset, cycles, rng):
    """Rows (home first) of a validation segment whose tool points land at target + offset + noise (µm).
    At Θ = 0 with a home reading of (0, 0), Eq. 4.27 gives the tool point −(x_m, y_m)."""
    t = np.tile(targets, (cycles, 1))
    p = t[:, :2] + offset + rng.normal(0, 0.2, (len(t), 2))
    pose = np.concatenate([[0], np.tile(np.arange(1, len(targets) + 1), cycles)])
    nan = [np.nan]
    return {
        "pose": pose,
        "meas_x": np.concatenate([[0.0], -p[:, 0]]),
        "meas_y": np.concatenate([[0.0], -p[:, 1]]),
        "meas_theta": np.zeros(len(pose)),
        "target_x": np.concatenate([nan, t[:, 0]]),
        "target_y": np.concatenate([nan, t[:, 1]]),
        "target_theta": np.zeros(len(pose)),
    }


def test_verification_compares_accuracies_and_barycentres_with_the_repeatability():
    """Hand-made runs: the in-process model lands 3 µm off in x; the bundle path lands the same;
    the controller path 2 µm further: its AP differs by 2 µm, more than RP, and so does every
    barycentre."""
    from calflow.xytheta.evaluation import xytheta_validation_metrics
    from calflow.xytheta.export.verification import compare, summary_entry

    rng = np.random.default_rng(0)
    targets = np.array([[-1000.0, -200.0, 0.0], [-1500.0, -300.0, 0.0], [-2000.0, -100.0, 0.0]])
    model = _visits(targets, (3.0, 0.0), 5, rng)
    held = xytheta_validation_metrics(
        xr.Dataset({k: ("sample", v) for k, v in model.items()}, attrs={"plan": "validation_heldout"}),
        _meta(),
    )
    segments = [_visits(targets, off, 3, rng) for off in ((3.0, 0.0), (5.0, 0.0))]
    rows = {k: np.concatenate([s[k] for s in segments]) for k in segments[0]}
    rows["test_mode"] = np.repeat([0, 1], len(segments[0]["pose"]))
    run = xr.Dataset(
        {k: ("sample", v) for k, v in rows.items()},
        attrs={
            "plan": "validation_export",
            "export_paths": "bundle linuxcnc",
            "export_cycles": 3,
            "bundle_command_difference_um": 0.0,
        },
    )
    ds = compare(run, held, _meta())
    rp = held.attrs["repeatability_um"]
    assert 0.2 < rp < 1.5
    assert ds.attrs["bundle_verified"] == 1 and ds.attrs["linuxcnc_verified"] == 0
    assert np.all(ds["shift"].sel(path="bundle").values < rp)
    assert np.allclose(ds["shift"].sel(path="linuxcnc").values, 2.0, atol=0.6)
    e = summary_entry(ds)
    assert e["verified"] is True and e["barycentres_within_tolerance"] is True
    assert e["controllers"]["linuxcnc"]["barycentres_within_tolerance"] is False
    assert e["accuracy_um"] == pytest.approx(3.0, abs=0.4) and e["controllers"]["linuxcnc"][
        "accuracy_um"
    ] == pytest.approx(5.0, abs=0.4)
    assert e["in_process_accuracy_um"] == held.attrs["accuracy_um"] and e["tolerance_um"] == rp


def test_cli_exports_every_model_and_writes_the_manifest_last(tmp_path, capsys):
    """``calflow export`` over two models: each folder, then manifest.json; a missing model
    file is one line naming it, and nothing is exported."""
    import yaml
    from conftest import SMALL_XYTHETA

    from calflow.cli import main
    from calflow.data.runs import RunMetadata

    campaign = tmp_path / "c.yaml"
    campaign.write_text(yaml.safe_dump(SMALL_XYTHETA))
    meta = RunMetadata(
        campaign="c",
        robot="xytheta",
        source="simulated",
        plan="identification",
        config_sha256="1" * 64,
        start="2026-01-01T00:00:00+00:00",
    )
    paths = []
    for name, position in (("II", None), ("III", _lut(2))):
        model = _model(position)
        model.name = name
        model.write(tmp_path / f"{name}.nc", meta)
        paths.append(tmp_path / f"{name}.nc")
    assert (
        main(
            ["export", "--campaign", str(campaign), "--model", *map(str, paths), "--out", str(tmp_path / "x")]
        )
        == 0
    )
    manifest = json.loads((tmp_path / "x/manifest.json").read_text())
    assert set(manifest) == {"II", "III"} and "linuxcnc_x.comp" in manifest["III"]
    assert "linuxcnc_x.comp" not in manifest["II"] and "bundle.json" in manifest["II"]
    assert load(tmp_path / "x/III")["model"] == "III"
    status = main(
        [
            "export",
            "--campaign",
            str(campaign),
            "--model",
            str(tmp_path / "nope.nc"),
            "--out",
            str(tmp_path / "y"),
        ]
    )
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert status != 0 and len(err) == 1 and "nope.nc" in err[0]
    assert not (tmp_path / "y/manifest.json").exists()
