"""Decision rules (ILAC-G8:09/2019), specific false-accept risk (JCGM 106), the stage's
specification refused in one line, and the certificate page."""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from calflow.certificate.annotate import annotate, check_stages
from calflow.certificate.conformity import check, decide, probability_above
from calflow.certificate.page import render
from calflow.cli import main
from calflow.errors import ConfigError

ROOT = Path(__file__).resolve().parents[2]
XY = {"accuracy_um": True, "repeatability_um": True, "cv_rms_um": False}


@settings(max_examples=50, deadline=None)
@given(st.floats(0.0, 10.0), st.floats(0.01, 3.0), st.floats(0.5, 12.0))
def test_pfa_is_the_normal_tail_closed_form(y, u, limit):
    """Infinite dof: P(Y > T) = 1 − Φ((T − y)/u) = erfc((T − y)/(u√2))/2."""
    closed = 0.5 * math.erfc((limit - y) / (u * math.sqrt(2)))
    assert probability_above(y, u, None, limit) == pytest.approx(closed, abs=1e-12)
    d = decide(y, limit, "simple", U=1.96 * u, k=1.96, dof=math.inf)
    if d["decision"] == "pass":
        assert d["pfa"] == pytest.approx(closed, abs=1e-12) and d["pfr"] == 0.0
    else:
        assert d["pfa"] == 0.0 and d["pfr"] == pytest.approx(1 - closed, abs=1e-12)


def test_pfa_with_finite_dof_is_students_t():
    assert probability_above(3.0, 0.5, 8, 3.5) == pytest.approx(stats.t.sf(1.0, 8))
    assert probability_above(3.0, 0.0, 8, 3.5) == 0.0


def test_guarded_acceptance_caps_the_specific_risk_at_the_one_sided_coverage():
    # at the guard band's edge y = T − U with k = t_0.975(ν): PFA is exactly 2.5 %
    k = stats.t.ppf(0.975, 10)
    d = decide(3.5 - 1.0, 3.5, "guarded", U=1.0, k=k, dof=10)
    assert d["decision"] == "pass" and d["pfa"] == pytest.approx(0.025)
    assert decide(3.5 - 1.0 + 1e-9, 3.5, "guarded", U=1.0, k=k, dof=10)["decision"] == "fail"


@pytest.mark.parametrize(
    "rule,y,expected",
    [
        ("simple", 3.5, "pass"),  # on the limit: accepted (y ≤ T)
        ("simple", 3.5 + 1e-9, "fail"),
        ("guarded", 2.5, "pass"),  # y = T − U
        ("guarded", 2.6, "fail"),
        ("non-binary", 2.5, "pass"),  # y + U = T
        ("non-binary", 2.50001, "conditional pass"),
        ("non-binary", 3.5, "conditional pass"),  # y = T
        ("non-binary", 3.50001, "conditional fail"),
        ("non-binary", 4.5, "conditional fail"),  # y − U = T
        ("non-binary", 4.50001, "fail"),
    ],
)
def test_each_rule_at_its_boundaries(rule, y, expected):
    d = decide(y, 3.5, rule, U=1.0, k=2.0, dof=math.inf)
    assert d["decision"] == expected
    assert d["guard_band"] == (0.0 if rule == "simple" else 1.0)


@pytest.mark.parametrize(
    "settings,match",
    [
        (
            {"specification": {"accuracy_um": 3.5}, "decision_rule": "lenient"},
            r"key 'stages.S.decision_rule': expected one of",
        ),
        (
            {"specification": {"cv_rms_um": 1.0}, "decision_rule": "guarded"},
            r"'stages.S.specification.cv_rms_um'.*no U",
        ),
        (
            {"specification": {"accuracy_nm": 350}},
            r"'stages.S.specification.accuracy_nm': the family does not compute",
        ),
        (
            {"specification": {"accuracy_um": 0}},
            r"'stages.S.specification.accuracy_um': expected a tolerance > 0, got 0",
        ),
        ({"specification": {"accuracy_um": -1.0}}, r"expected a tolerance > 0, got -1.0"),
        ({"specification": {"accuracy_um": True}}, r"expected a tolerance > 0, got True"),
        ({"decision_rule": "guarded"}, r"key 'stages.S.specification': expected a tolerance per metric"),
    ],
)
def test_bad_specification_is_one_line(settings, match):
    with pytest.raises(ConfigError, match=match) as err:
        check(settings, XY, "config/config.yaml", "stages.S.")
    assert "\n" not in str(err.value) and str(err.value).startswith("config/config.yaml: key ")


def test_simple_rule_allows_a_figure_without_u():
    assert check({"specification": {"cv_rms_um": 1}}, XY, "c.yaml") == {
        "specification": {"cv_rms_um": 1.0},
        "decision_rule": "simple",
    }


def test_check_config_refuses_a_bad_stage_specification_in_one_line(tmp_path, capsys):
    folder = tmp_path / "campaigns"
    folder.mkdir()
    for name in ("demo-sn0042-2026-01", "demo-sn0042-2026-07"):
        shutil.copy(ROOT / "config" / "campaigns" / f"{name}.yaml", folder / f"{name}.yaml")
    cfg = {
        "campaigns": ["demo-sn0042-2026-01", "demo-sn0042-2026-07"],
        "campaign_dir": str(folder),
        "stages": {"SN-0042": {"specification": {"E_nm": 100}, "decision_rule": "guarded"}},
    }
    path = tmp_path / "config.yaml"
    path.write_text(yaml.safe_dump(cfg))
    status = main(["check-config", str(path)])
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert status == 2 and len(err) == 1
    assert err[0].startswith(f"calflow: error: {path}: key 'stages.SN-0042.specification.E_nm': the family")


def test_check_stages_ignores_stages_without_campaigns():
    check_stages({"OTHER": {"specification": {"nothing": 1}}}, {}, {}, "config.yaml")


def _summary():
    return {"campaign": "c1", "robot": "xytheta", "description": "d", "models": {"III": {"accuracy_um": 2.0}}}


def _campaign():
    return {"name": "c1", "robot": "xytheta", "stage": "S1", "start": "2026-01-05T08:00:00+00:00"}


def test_annotate_and_page_show_u_k_rule_and_decision(monkeypatch):
    """The certificate page carries the decision, U, k and the rule of each figure."""
    from calflow.certificate import Measurement
    from calflow.family import family_of

    rng = np.random.default_rng(0)
    cmd = rng.uniform(-1000, 1000, (5, 2))
    att = [c + [1.2, 0.0] + rng.normal(0, 0.2, (4, 2)) for c in cmd]

    def measurements(campaign, files):
        return [
            Measurement(
                ("models", "III"), {"accuracy": "accuracy_um"}, data={"command": cmd, "attained": att}
            )
        ]

    fam = family_of("xytheta")
    monkeypatch.setattr("calflow.certificate.annotate.resolve", lambda target: measurements)
    assert fam.uncertainty
    s = annotate(
        _summary(), _campaign(), [], {"specification": {"accuracy_um": 3.5}, "decision_rule": "guarded"}
    )
    unc = s["models"]["III"]["uncertainty"]["accuracy_um"]
    conf = s["models"]["III"]["conformity"]["accuracy_um"]
    assert set(unc) >= {"U", "k", "dof_eff", "budget"} and unc["value"] == 2.0
    assert set(conf) >= {"rule", "spec", "decision", "pfa"} and conf["rule"] == "guarded"
    assert s["certificate"]["decision"] == conf["decision"]
    html = render(json.loads(json.dumps(s)), _campaign(), "snakemake …")
    row = html[html.index('data-key="models.III.accuracy_um"') :]
    assert f'data-decision="{conf["decision"]}"' in row
    assert f"{unc['U']:.3f}" in row and f"{unc['k']:.3f}" in row
    assert 'data-rule="guarded"' in html and "ILAC-G8:09/2019 4.2.2" in html


def test_page_without_specification_says_so_and_escapes():
    s = _summary()
    s["description"] = "<script>alert(1)</script>"
    s["certificate"] = {"specification": {}, "decision_rule": None, "decision": None, "figures": []}
    html = render(s, _campaign(), "cmd")
    assert "No specification is stated" in html and "<script>alert" not in html


def test_as_found_without_u_is_not_decided_by_a_guarded_rule(monkeypatch):
    s = _summary()
    s["models"]["III"]["as_found"] = {"accuracy_um": 3.0, "date": "2026-07-05"}
    from calflow.certificate import Measurement

    monkeypatch.setattr(
        "calflow.certificate.annotate.resolve",
        lambda target: (
            lambda c, f: [Measurement(("models", "III"), {"accuracy": "accuracy_um"}, kind="none")]
        ),
    )
    s = annotate(s, _campaign(), [], {"specification": {"accuracy_um": 3.5}, "decision_rule": "guarded"})
    found = s["models"]["III"]["as_found"]["conformity"]["accuracy_um"]
    assert found["decision"] is None and "no U" in found["statement"]
