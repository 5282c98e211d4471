"""The hexapod's error budget: replays switch off what they name, entries add up in squares,
the floor is what the rig's own parameters reach."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from calflow.errors import CalflowError
from calflow_hexapod.stage import error_budget as eb
from calflow_hexapod.stage.physics import EFFECTS, HexapodTruth


def campaign(**rig) -> dict:
    return {
        "name": "hexapod-budget",
        "seed": 2,
        "rig": {"factory": "simulated", "options": rig},
        "identification": {
            "plan": "random",
            "poses": 40,
            "fraction": 0.6,
            "dwell_s": 1.0,
            "initial": {"tool": [0, 0, 60000, 0, 0, 0]},
        },
        "models": {"nominal": {}, "geometric": {}},
        "validation": {"dwell_s": 1.0, "heldout": {"targets": 4, "cycles": 3}},
    }


def test_replay_options_switch_off_exactly_the_named_effect():
    opts = eb.replay_options("compliance")
    assert opts == {"payload_kg": 0.0}
    base = eb.replay_options("baseline")
    assert set(base) == {f for fs in EFFECTS.values() for f in fs}
    t = HexapodTruth(**{k: tuple(v) if isinstance(v, list) else v for k, v in base.items()})
    assert eb.active_effects({"rig": {"options": base}}) == []
    assert t.leg_repeatability_um > 0  # the noise stays


def test_inactive_effect_is_not_replayed():
    c = campaign(joint_play_um=0.0)
    assert "joint_play" not in eb.active_effects(c)
    assert eb.replay(c, "joint_play") == {"replay": "joint_play", "active": False}


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.floats(0.0, 50.0), min_size=3, max_size=3),
    st.lists(st.floats(0.0, 50.0), min_size=3, max_size=3),
)
def test_entries_add_up_in_squares(full, other):
    records = [
        {"replay": "baseline", "active": True, "ap": {"m": {"ap_um": other, "ap_deg": other}}},
        {"replay": "joint_play", "active": True, "ap": {"m": {"ap_um": other[::-1], "ap_deg": full}}},
    ]
    out = eb.combine({"m": {"ap_um": full, "ap_deg": other}}, records)
    for unit in ("um", "deg"):
        b = out["models"]["m"][unit]
        total = sum(np.sign(v) * v**2 for v in b["budget"].values())
        assert total == pytest.approx(b["rms_ap"] ** 2, abs=1e-6)
    assert out["unmodelled"] == ["joint_play"]


def test_budget_of_a_small_campaign_and_its_floor():
    c = campaign()
    out = eb.error_budget(c, names=("baseline", "joint_errors"))
    geo = out["budget"]["models"]["geometric"]["um"]
    nom = out["budget"]["models"]["nominal"]["um"]
    assert nom["budget"]["joint_errors"] > 5.0  # the nominal model cannot undo the joint errors ...
    assert abs(geo["budget"]["joint_errors"]) < nom["budget"]["joint_errors"]  # ... the geometric one can
    assert out["floor"]["floor_um"] > 1.0 and out["floor"]["accuracy_um"] < nom["rms_ap"] * 2


def test_budget_needs_the_simulated_rig():
    c = campaign()
    c["rig"] = {"factory": "gcs", "options": {}}
    with pytest.raises(CalflowError, match="rig.factory"):
        eb.error_budget(c)
