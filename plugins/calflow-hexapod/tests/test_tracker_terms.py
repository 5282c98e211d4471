"""The laser tracker's declared terms for the hexapod's certificate."""

from __future__ import annotations

import pytest

from calflow_hexapod.certificate import tracker_terms
from calflow_hexapod.stage import tracker
from calflow_hexapod.stage.physics import HexapodTruth


def test_tracker_terms_are_the_specifications_mpe_over_four():
    truth = HexapodTruth()
    terms = {t.name: t for t in tracker_terms(2.0)}
    assert terms["tracker ADM, random"].u == pytest.approx((10 + 0.3 * 2.0) / 4)
    assert terms["tracker transverse, random"].u == pytest.approx((15 + 6 * 2.0) / 4)
    systematic = terms["tracker angle encoders, systematic (transverse MPE/4)"]
    assert systematic.scope == "target" and systematic.u == pytest.approx((15 + 6 * 2.0) / 4)
    # the same MPE/4 the simulated tracker draws its random errors from, at its station distance
    import numpy as np

    _, s_t, _ = tracker.sigmas(truth, np.zeros((1, 3)))
    assert tracker_terms(truth.tracker_distance_m)[1].u == pytest.approx(s_t[0], rel=0.02)
