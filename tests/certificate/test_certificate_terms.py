"""The families' declared sensor terms (their certificate hooks) against their sources."""

from __future__ import annotations

import math

import numpy as np
import pytest
import xarray as xr

from calflow.instruments.interferometer import interferometer_budget
from calflow.nano.certificate import interferometer_terms
from calflow.xytheta.report.certificate import vision_terms


def test_interferometer_terms_reproduce_table_3_4_at_the_measured_length():
    b = interferometer_budget()
    terms = {t.name: t for t in interferometer_terms(b)}
    L = b.inputs["measured_distance_um"]  # relative terms in ppm of the position: at L they give U_k
    for name, u_nm in (
        ("U_1 laser wavelength", b.U_1),
        ("U_4 atmospheric compensation", b.U_4),
        ("U_8 cosine", b.U_8),
    ):
        assert terms[name].relative and terms[name].u * 1e-6 * L * 1e3 == pytest.approx(u_nm)
    assert terms["U_6 deadpath"].scope == "common" and terms["U_6 deadpath"].u == pytest.approx(b.U_6 / 1e3)
    assert {terms[n].scope for n in ("U_3 optics nonlinearity", "U_5 optics thermal drift", "U_7 Abbe")} == {
        "target"
    }
    assert terms["U_2 electronics (resolution)"].scope == "reading"
    # all eight together at L: Table 3.4's combined uncertainty (U_4 + U_6 in quadrature here, not linearly)
    total = math.sqrt(sum((t.u * (1e-6 * L * 1e3 if t.relative else 1e3)) ** 2 for t in terms.values()))
    assert total == pytest.approx(math.sqrt(b.combined_nm**2 - 2 * b.U_4 * b.U_6))


def test_vision_terms_use_table_3_3_and_the_runs_own_temperature_and_angle():
    pose = np.array([0, 1, 1, 2, 2])
    run = xr.Dataset(
        {
            "temperature": (
                ("sample", "sensor"),
                np.array([[20.0, 20.0], [20.2, 20.2], [20.1, 20.1], [19.9, 19.9], [20.0, 20.0]]),
            ),
            "meas_theta": ("sample", np.array([0.0, 1e-3, -1e-3, 2e-3, 0.0])),
            "pose": ("sample", pose),
        }
    )
    terms, notes = vision_terms(run)
    by = {t.name: t for t in terms}
    drift = by["sensor thermal drift (Table 3.3)"]
    assert drift.u == pytest.approx((0.157 * 0.2 / math.sqrt(3), 1.357 * 0.2 / math.sqrt(3)))
    s = math.sqrt((2 * 1e-6 + 2 * 1e-6) / 2)  # within-target Θ scatter, 2 dof (degree)
    assert by["alignment: world-frame angle"].u == pytest.approx(math.radians(s) * 1e6)
    assert any("pitch" in n for n in notes)
    terms, notes = vision_terms(run.drop_vars("temperature"))
    assert "sensor thermal drift (Table 3.3)" not in {t.name for t in terms}
    assert any("no thermometer" in n for n in notes)


def _nano_run(plan, rng):
    t = np.repeat(np.linspace(0, 500, 6), 4)
    d = np.tile([1, 1, -1, -1], 6)
    return xr.Dataset(
        {
            "meas_x": ("sample", t + 0.1 * np.sin(t / 80) + rng.normal(0, 0.03, t.size)),
            "target_x": ("sample", t),
            "pose": ("sample", np.arange(t.size) // 2),  # each (target, direction) a pose, 2 visits
            "cycle": ("sample", np.arange(t.size) % 2),
            "direction": ("sample", d),
            "time": ("sample", np.arange(t.size, dtype=float)),
        },
        attrs={"plan": plan},
    )


def test_nano_metrology_and_iso230_2_figures(monkeypatch):
    from calflow.metrics.iso9283 import iso9283
    from calflow.nano.certificate import measurements

    rng = np.random.default_rng(0)
    runs = [("m.nc", _nano_run("metrology", rng)), ("t.nc", _nano_run("training", rng))]
    monkeypatch.setattr("calflow.summary_routing.route", lambda files, sections, family="": {"runs": runs})
    campaign = {"name": "n", "robot": "stage1d", "rig": {"factory": "simulated"}}
    ms = {m.path: m for m in measurements(campaign, [])}
    assert set(ms) == {("intrinsic",), ("training",), ("iso230_2",)}
    m = ms[("intrinsic",)]
    assert m.scale == 1000.0 and m.keys["accuracy"] == "accuracy_nm" and len(m.data["attained"]) == 12
    ap = max(iso9283(c, a).ap for c, a in zip(m.data["command"], m.data["attained"]))
    from calflow.certificate.annotate import uncertainties

    assert uncertainties(m)["accuracy"].value == pytest.approx(ap)
    iso = ms[("iso230_2",)]
    assert iso.kind == "iso230_2" and iso.data["forward"].shape == (6, 2)
    assert measurements({**campaign, "robot": "stage2d"}, []) == []
