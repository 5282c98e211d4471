"""GUM interferometer budget against Table 3.4 of the thesis."""

import math

import pytest

from calflow.instruments.interferometer import DEFAULT_INPUTS, atmospheric_ppm, combine, interferometer_budget

# Table 3.4 as printed (nm).
PRINTED = {
    "U_1": 0.087,
    "U_2": 0.08,
    "U_3": 3.0,
    "U_4": 0.262,
    "U_5": 29.0,
    "U_6": 26.2,
    "U_7": 10.0,
    "U_8": 0.76,
}


def test_each_component_matches_table_3_4_to_printed_precision():
    b = interferometer_budget()
    assert round(b.U_1, 3) == PRINTED["U_1"]
    # U_2 = 0.15 / sqrt(3) = 0.0866: the table truncates to 0.08
    assert PRINTED["U_2"] <= b.U_2 < PRINTED["U_2"] + 0.01
    assert round(b.U_3) == PRINTED["U_3"]
    assert round(b.U_4, 3) == PRINTED["U_4"]
    assert round(b.U_5) == PRINTED["U_5"]
    assert round(b.U_6, 1) == PRINTED["U_6"]
    assert round(b.U_7) == PRINTED["U_7"]
    assert round(b.U_8, 2) == PRINTED["U_8"]
    assert round(b.U_W_ppm, 4) == 0.5233


def test_components_by_hand():
    b = interferometer_budget()
    s3 = math.sqrt(3.0)
    assert b.U_1 == pytest.approx(0.0005 * 0.3e-6 / s3 * 1e9)  # L(m) x 0.3 ppm / sqrt3, in nm
    assert b.U_2 == pytest.approx((0.3 / 2.0) / s3)
    assert b.U_3 == pytest.approx(4.2 / math.sqrt(2.0))
    u_w = math.sqrt((0.1 / s3) ** 2 + (0.9 / s3) ** 2 + (0.0375 / s3) ** 2)
    assert b.U_W_ppm == pytest.approx(u_w)
    assert b.U_4 == pytest.approx(u_w * 1e-6 * 0.0005 * 1e9)
    assert b.U_5 == pytest.approx(0.1 * 0.5e3 / s3)
    assert b.U_6 == pytest.approx(u_w * 1e-6 * 0.05 * 1e9)
    assert b.U_7 == pytest.approx(0.01 * math.tan(1e-6) * 1e9)
    assert b.U_8 == pytest.approx(0.0005 * (1.0 - math.cos(math.radians(0.1))) * 1e9)


def test_combination_reproduces_40_6_nm_from_printed_components():
    assert round(combine(*PRINTED.values()), 1) == 40.6


def test_default_combined_uncertainty():
    b = interferometer_budget()
    expected = math.sqrt(
        b.U_1**2 + b.U_2**2 + b.U_3**2 + b.U_5**2 + b.U_7**2 + b.U_8**2 + (b.U_4 + b.U_6) ** 2
    )
    assert b.combined_nm == pytest.approx(expected)
    # unrounded components give 40.51 nm; Table 3.4's 40.6 nm combines rounded U_3 = 3, U_5 = 29
    assert b.combined_nm == pytest.approx(40.6, abs=0.1)
    # U_4 and U_6 add linearly: the budget is larger than with them in quadrature
    quad = math.sqrt(expected**2 - (b.U_4 + b.U_6) ** 2 + b.U_4**2 + b.U_6**2)
    assert b.combined_nm > quad


def test_atmospheric_conversion_gives_thesis_ppm():
    ppm = atmospheric_ppm(temperature_K=0.1, pressure_mmHg=2.25, humidity_percent=3.0)
    assert ppm["temperature_ppm"] == pytest.approx(0.1)
    assert ppm["pressure_ppm"] == pytest.approx(0.9)
    assert ppm["humidity_ppm"] == pytest.approx(0.0375)
    for k, v in ppm.items():
        assert DEFAULT_INPUTS[k] == pytest.approx(v)


def test_overrides():
    base = interferometer_budget()
    longer = interferometer_budget(deadpath_mm=100.0)
    assert longer.U_6 == pytest.approx(2.0 * base.U_6)
    assert longer.U_4 == pytest.approx(base.U_4)
    # thesis-printed Abbe angle 6 µrad: 1 cm x tan(6 µrad) = 60 nm
    assert interferometer_budget(abbe_angle_urad=6.0).U_7 == pytest.approx(60.0, rel=1e-6)
    cfg = {**DEFAULT_INPUTS, "measured_distance_um": 1000.0}
    b2 = interferometer_budget(**cfg)
    assert b2.U_1 == pytest.approx(2.0 * base.U_1)
    assert b2.inputs["measured_distance_um"] == 1000.0


def test_bad_inputs_and_immutable_defaults():
    with pytest.raises(ValueError, match="unknown"):
        interferometer_budget(deadpath_m=0.05)
    with pytest.raises(ValueError, match="finite and >= 0"):
        interferometer_budget(resolution_nm=-1.0)
    with pytest.raises(TypeError):
        DEFAULT_INPUTS["deadpath_mm"] = 1.0


def test_table_rows():
    b = interferometer_budget()
    rows = b.table()
    assert len(rows) == 9
    assert [r[3] for r in rows[:8]] == list(b.components_nm)
    assert rows[-1][3] == b.combined_nm
    assert {r[1] for r in rows} == {"intrinsic", "environmental", "installation", "combined"}
    assert all(isinstance(r[0], str) and isinstance(r[2], str) for r in rows)
