"""Simulated XYΘ stages that age with the campaign's start (rig.options.aging)."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from calflow.configuration.campaign import load as load_campaign
from calflow.errors import ConfigError
from calflow.xytheta.stage.aging import DEFAULT_SINCE
from calflow.xytheta.stage.aging import resolve as _resolve
from calflow.xytheta.stage.physics import XYThetaTruth

ROOT = Path(__file__).resolve().parents[2]
BASE = XYThetaTruth()


def resolve(options, start):
    return _resolve(options, start, BASE)


def test_no_change_at_commissioning_or_when_off():
    assert resolve({}, DEFAULT_SINCE) == {}
    assert resolve({"aging": False, "alpha_deg": 177.0}, "2027-01-05T08:00:00+00:00") == {"alpha_deg": 177.0}


def test_wear_grows_with_time_and_keeps_switched_off_effects_off():
    year = resolve({"aging": {"wear_per_year": 0.1, "seasonal_degC": 0}}, "2027-01-05T14:00:00+00:00")
    assert year["backlash_um"] == pytest.approx(BASE.backlash_um * 1.1, rel=1e-3)
    assert year["lead_fwd_um"][0] == pytest.approx(BASE.lead_fwd_um[0] * 1.1, rel=1e-3)
    off = resolve({"backlash_um": 0.0, "aging": {"wear_per_year": 0.1}}, "2027-01-05T08:00:00+00:00")
    assert off["backlash_um"] == 0.0


def test_seasonal_scale_follows_the_room():
    a = {"aging": {"seasonal_degC": 1.0, "seasonal_peak_day": 196, "wear_per_year": 0}}
    summer = resolve(dict(a), "2026-07-15T08:00:00+00:00")["scale_ppm"][0]
    winter = resolve(dict(a), "2027-01-10T08:00:00+00:00").get("scale_ppm", BASE.scale_ppm)[0]
    assert summer > BASE.scale_ppm[0] + BASE.expansion_ppm_per_degC  # ≈ 2 °C warmer than in January
    assert abs(winter - BASE.scale_ppm[0]) < 0.1 * BASE.expansion_ppm_per_degC


def test_remount_event_from_its_date_on():
    a = {"aging": {"events": [{"date": "2026-07-01T00:00:00+00:00", "alpha_deg": 0.02, "x_R_um": 20}]}}
    before = resolve(dict(a), "2026-06-30T08:00:00+00:00")
    after = resolve(dict(a), "2026-07-01T00:00:00+00:00")
    assert "alpha_deg" not in before
    assert after["alpha_deg"] == pytest.approx(BASE.alpha_deg + 0.02)
    assert after["x_R_um"] == pytest.approx(BASE.x_R_um + 20)


def _campaign(tmp_path, options, start="2026-09-01T08:00:00+00:00"):
    data = yaml.safe_load((ROOT / "config/campaigns/xytheta-thesis.yaml").read_text())
    data["rig"]["options"] = options
    data["start"] = start
    path = tmp_path / "aged.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_loader_resolves_ageing(tmp_path):
    c = load_campaign(_campaign(tmp_path, {}))
    assert c["rig"]["options"]["backlash_um"] > BASE.backlash_um
    assert "aging" not in c["rig"]["options"]
    assert load_campaign(_campaign(tmp_path, {"aging": False}))["rig"]["options"] == {}


@pytest.mark.parametrize(
    "aging,key",
    [
        ({"wear": 1}, "aging.wear"),
        ({"wear_per_year": -1}, "aging.wear_per_year"),
        ({"events": [{"alpha_deg": 1}]}, "aging.events.0"),
        ({"since": "yesterday"}, "aging.since"),
        (3, "aging"),
    ],
)
def test_bad_ageing_refused(tmp_path, aging, key):
    with pytest.raises(ConfigError, match=rf"aged\.yaml.*{key}"):
        load_campaign(_campaign(tmp_path, {"aging": aging}))
