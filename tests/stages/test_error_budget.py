"""The error budget's arithmetic (calflow.xytheta.stage.error_budget): its entries add up, in
signed quadrature, to the held-out RMS they split; each effect is what its removal takes
away; a rig without an effect has no entry for it."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from calflow.xytheta.stage.error_budget import REPLAYS, active_effects, combine, groups, replay_options
from calflow.xytheta.stage.physics import EFFECTS, XYThetaTruth

aps = st.lists(st.floats(0.0, 50.0), min_size=3, max_size=3)


@settings(max_examples=50, deadline=None)
@given(full=aps, noise=aps, without=st.lists(aps, min_size=1, max_size=4))
def test_entries_add_up_in_signed_quadrature_to_the_heldout_rms(full, noise, without):
    names = list(EFFECTS)[: len(without)]
    records = [{"replay": "baseline", "active": True, "ap_um": {"V": noise}}]
    records += [{"replay": n, "active": True, "ap_um": {"V": w}} for n, w in zip(names, without)]
    b = combine({"V": np.array(full)}, records)["models"]["V"]
    total = sum(np.sign(v) * v**2 for v in b["error_budget_um"].values())
    assert np.isclose(total, np.mean(np.square(full)), rtol=1e-9, atol=1e-9)
    assert np.isclose(b["rms_ap_um"] ** 2, np.mean(np.square(full)))
    for n, w in zip(names, without):  # an effect's entry: what the rig without it takes away
        d = np.mean(np.square(full)) - np.mean(np.square(w))
        assert np.isclose(np.sign(b["error_budget_um"][n]) * b["error_budget_um"][n] ** 2, d, atol=1e-9)
    g = groups(b["error_budget_um"], [names[0]])
    assert np.isclose(sum(np.sign(v) * v**2 for v in g.values()), total, atol=1e-9)


def test_inactive_replays_are_left_out_and_unmodelled_effects_are_marked():
    records = [
        {"replay": "baseline", "active": True, "ap_um": {"II": [1.0, 1.0]}},
        {"replay": "yaw", "active": True, "ap_um": {"II": [1.0, 2.0]}},
        {"replay": "lead_screw", "active": True, "ap_um": {"II": [3.0, 3.0]}},
        {"replay": "decode", "active": False},
    ]
    b = combine({"II": [2.0, 2.0]}, records)
    assert b["effects"] == ["yaw", "lead_screw"]
    assert b["unmodelled"] == ["yaw"]
    assert (
        b["models"]["II"]["error_budget_um"]["lead_screw"] < 0 < b["models"]["II"]["error_budget_um"]["yaw"]
    )


def test_active_effects_follow_the_rig_options():
    every = active_effects(XYThetaTruth())
    assert set(every) == set(REPLAYS) - {"baseline"}
    modelled = active_effects(XYThetaTruth(unmodelled=False))
    assert "yaw" not in modelled and "lost_motion" not in modelled and "gross_errors" not in modelled
    assert {"lead_screw", "backlash", "theta_periodic", "axis_runout"} <= set(modelled)
    assert "scale" not in active_effects(XYThetaTruth().without("scale_ppm"))


def test_each_replay_switches_off_only_its_effect():
    for name in REPLAYS:
        opts = replay_options(name)
        truth = XYThetaTruth(**{k: tuple(v) if isinstance(v, list) else v for k, v in opts.items()})
        left = set(active_effects(truth))
        if name == "baseline":
            assert left == set()
        else:
            assert left == set(REPLAYS) - {"baseline", name}
    assert set(EFFECTS.unmodelled_fields) >= {"yaw_urad", "decode_error_um"}
