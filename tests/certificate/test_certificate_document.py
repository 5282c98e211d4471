"""What a certificate states besides its results (ISO/IEC 17025 §7.8), and as found / as left."""

from __future__ import annotations

import copy
import json

import numpy as np
import pytest
import xarray as xr
from hypothesis import given, settings
from hypothesis import strategies as st

from calflow.certificate import Measurement
from calflow.certificate.annotate import annotate, least_favourable
from calflow.certificate.document import number, record
from calflow.certificate.environment import environment
from calflow.certificate.page import render

LAB = {
    "name": "Lab <One>",
    "address": "1 Rue de l'Épitaphe, Besançon",
    "accreditation": "COFRAC 2-9999",
    "approver": {"name": "A. Approver", "role": "technical manager"},
    "signing_key": "/secret/key.p12",
}
ITEM = {"customer": "Customer AG", "manufacturer": "Maker", "model": "XY-200", "serial_number": "SN-7"}
SPEC = {"specification": {"accuracy_um": 3.5}, "decision_rule": "non-binary"}


def _campaign():
    return {"name": "c1", "robot": "xytheta", "stage": "S1", "start": "2026-07-05T08:00:00+00:00"}


def _targets(rng, offset):
    cmd = rng.uniform(-1000, 1000, (6, 2))
    return cmd, [c + [offset, 0.0] + rng.normal(0, 0.1, (4, 2)) for c in cmd]


def _summary(found: float, left: float) -> dict:
    block = {"accuracy_um": found, "date": "2026-07-05T08:00:01+00:00", "reference": "c0"}
    return {
        "campaign": "c1",
        "robot": "xytheta",
        "description": "d",
        "models": {
            "III": {
                "accuracy_um": left,
                "as_left": {"accuracy_um": left, "date": "2026-07-05T09:00:00+00:00"},
                "as_found": dict(block),
            }
        },
        "as_found": {"model": "III", **block},
    }


def _measurements(rng, found, left):
    """As an XYΘ calibration with an as-found run declares them: the as-found block twice
    (the model's and the summary's top-level copy), then the as-left figure."""
    cf, af = _targets(rng, found)
    cl, al = _targets(rng, left)
    keys = {"accuracy": "accuracy_um"}
    kw = {"label": "Model III, as found", "state": "as_found", "traceability": ("pattern pitch",)}
    return [
        Measurement(("models", "III", "as_found"), keys, data={"command": cf, "attained": af}, **kw),
        Measurement(("as_found",), keys, data={"command": cf, "attained": af}, **kw),
        Measurement(
            ("models", "III"), keys, data={"command": cl, "attained": al}, label="Model III", state="as_left"
        ),
    ]


def _annotated(monkeypatch, found=6.0, left=2.0):
    rng = np.random.default_rng(3)
    ms = _measurements(rng, found, left)
    # the figures the data give, so the summary and the U describe the same values
    from calflow.metrics.iso9283 import iso9283

    def ap(m):
        return max(iso9283(c, a).ap for c, a in zip(m.data["command"], m.data["attained"], strict=True))

    s = _summary(ap(ms[0]), ap(ms[2]))
    monkeypatch.setattr("calflow.certificate.annotate.resolve", lambda target: lambda c, f: ms)
    return annotate(s, _campaign(), [], SPEC)


def test_as_found_and_as_left_are_decided_apart_and_the_as_left_one_stands(monkeypatch):
    s = _annotated(monkeypatch)
    cert = s["certificate"]
    assert cert["decisions"] == {"as_found": "fail", "as_left": "pass"}
    assert cert["decision"] == "pass"  # what the stage leaves the lab with
    page = render(json.loads(json.dumps(s)), _campaign(), "cmd", record(s, _campaign(), LAB, ITEM, None))
    block = page[page.index('id="decisions"') :]
    assert 'data-state="as_found"' in block and 'data-decision="fail"' in block
    assert 'data-state="as_left"' in block and "leaves the laboratory" in block


def test_a_figure_kept_under_two_paths_is_one_row(monkeypatch):
    s = _annotated(monkeypatch)
    rows = [(f["label"], f["key"]) for f in s["certificate"]["figures"]]
    assert len(rows) == len(set(rows)) == 2
    assert "uncertainty" in s["as_found"]  # the copy still carries its U for the history


def test_an_interim_checks_as_found_value_carries_the_checks_u(monkeypatch):
    rng = np.random.default_rng(5)
    cmd, att = _targets(rng, 1.0)
    from calflow.metrics.iso9283 import iso9283

    ap = max(iso9283(c, a).ap for c, a in zip(cmd, att, strict=True))
    s = {"campaign": "c1", "robot": "xytheta", "models": {}, "interim_check": {"accuracy_um": ap}}
    s["interim_check"]["as_found"] = {"accuracy_um": ap, "date": "2026-04-05", "reference": "c0"}
    m = Measurement(
        ("interim_check",),
        {"accuracy": "accuracy_um"},
        data={"command": cmd, "attained": att},
        state="as_found",
    )
    monkeypatch.setattr("calflow.certificate.annotate.resolve", lambda target: lambda c, f: [m])
    s = annotate(s, _campaign(), [], SPEC)
    found = s["interim_check"]["as_found"]
    assert found["uncertainty"]["accuracy_um"] == s["interim_check"]["uncertainty"]["accuracy_um"]
    assert found["conformity"]["accuracy_um"]["pfa"] is not None
    assert s["certificate"]["decisions"]["as_left"] is None
    assert s["certificate"]["decision"] == s["certificate"]["decisions"]["as_found"]


@settings(max_examples=30, deadline=None)
@given(st.lists(st.sampled_from(["pass", "conditional pass", "conditional fail", "fail", None]), max_size=6))
def test_least_favourable_is_the_worst_decided(ds):
    order = ["pass", "conditional pass", "conditional fail", "fail"]
    known = [d for d in ds if d]
    assert least_favourable(ds) == (max(known, key=order.index) if known else None)


def test_number_is_stable_for_the_same_results_and_new_when_one_digit_changes():
    s = _summary(5.984584575399292, 2.4)
    assert number(s, "SN-7") == number(copy.deepcopy(s), "SN-7")
    t = copy.deepcopy(s)
    t["models"]["III"]["accuracy_um"] = 2.5
    assert number(t, "SN-7") != number(s, "SN-7")
    assert number(s, "SN-7").startswith("CF-SN-7-")


def test_every_iso_17025_item_is_on_the_page(monkeypatch):
    s = _annotated(monkeypatch)
    s["certificate"]["environment"] = {"statement": "temperature 20.00 °C to 20.10 °C"}
    doc = record(s, _campaign(), LAB, ITEM, None)
    page = render(json.loads(json.dumps(s)), _campaign(), "cmd", doc)
    fields = {
        "laboratory": "Lab &lt;One&gt;",  # escaped
        "address": "Besançon",
        "accreditation": "COFRAC 2-9999",
        "customer": "Customer AG",
        "item": "XY-200",
        "serial_number": "SN-7",
        "calibrated": "2026-07-05T08:00:00+00:00",
        "issued": doc["issued"],
        "method": "ISO 9283:1998",
        "environment": "20.00 °C",
        "traceability": "pattern pitch",
        "approver": "A. Approver, technical manager",
    }
    for field, text in fields.items():
        cell = page[page.index(f'data-field="{field}"') :]
        assert text in cell[: cell.index("</td>")], field
    assert doc["number"] in page and "/secret/key.p12" not in page
    assert f'"{doc["title"]} {doc["number"]} · UNSIGNED"' in page  # the running head of every page
    assert 'data-signature="unsigned"' in page and f"End of certificate {doc['number']}" in page


def test_the_environment_is_the_runs_temperatures(tmp_path):
    files = []
    for i, t in enumerate(([20.0, 20.2, 20.1], [21.0, 20.5, 20.7])):
        ds = xr.Dataset(
            {"temperature": (("sample", "sensor"), np.array(t)[:, None])}, coords={"sensor": ["T1"]}
        )
        (tmp_path / "runs").mkdir(exist_ok=True)
        path = tmp_path / "runs" / f"r{i}.nc"
        ds.to_netcdf(path)
        files.append(str(path))
    no_temp = tmp_path / "runs" / "plain.nc"
    xr.Dataset({"meas_x": ("sample", [1.0])}).to_netcdf(no_temp)
    env = environment([*files, str(no_temp), str(tmp_path / "metrics.nc")])
    t = env["temperature_degC"]
    assert (t["min"], t["max"]) == (20.0, 21.0)
    assert t["mean"] == pytest.approx(np.mean([20.0, 20.2, 20.1, 21.0, 20.5, 20.7]), abs=1e-4)
    assert t["max_excursion"] == pytest.approx(0.5)
    assert env["runs"] == ["r0", "r1"] and env["thermometers"] == ["T1"]
    assert "not known" in environment([str(no_temp)])["statement"]
