"""Interim check decision: Wald's sequential probability ratio test on position errors.

Each visit of an interim check gives the error vector e (µm, d components) of the pose the
stage reached through the compensation it runs. The test is on the scale of those errors,
which grows both with a new systematic error (a re-mount shifts every target's barycentre)
and with noise:

* H0 "within tolerance": e ~ N(0, σ0² I), σ0 = r0/√d with r0 the rms error of the
  reference calibration's held-out validation through that compensation;
* H1 "recalibrate": e ~ N(0, σ1² I), σ1 = r1/√d with r1 = ``tolerance_um`` as an rms error.

The log-likelihood ratio of one visit is d·ln(σ0/σ1) + |e|²/2·(1/σ0² − 1/σ1²); the
test stops at the first visit where the running sum leaves (ln B, ln A), A = (1−β)/α,
B = β/(1−α) (Wald 1945, *Ann. Math. Statist.* 16, 117–186; these bounds keep the error
rates at most about α and β). At the last planned visit without a decision the test is
truncated: "undecided", with the side the sum leans to.

With ``groups`` (the cycle of each visit) the bounds are looked at only when a group is
complete — a group-sequential SPRT, so that a check stopped early has visited every target
equally often; looking less often keeps the error rates within Wald's bounds (the sum can
only overshoot further) at the cost of a few visits.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class SPRT:
    """Scale SPRT of H0: rms error r0_um against H1: rms error r1_um (r1 > r0), per
    visit errors with ``dim`` components, error rates ``alpha`` (false "recalibrate") and
    ``beta`` (missed "recalibrate")."""

    r0_um: float
    r1_um: float
    alpha: float = 0.05
    beta: float = 0.10
    dim: int = 2

    def __post_init__(self) -> None:
        if not 0 < self.r0_um < self.r1_um:
            raise ValueError(
                f"interim check: expected 0 < reference rms error ({self.r0_um!r} µm) < "
                f"tolerance ({self.r1_um!r} µm)"
            )
        if not (0 < self.alpha < 1 and 0 < self.beta < 1 and self.alpha + self.beta < 1):
            raise ValueError(
                f"interim check: expected error rates in (0, 1) with alpha + beta < 1, got "
                f"alpha {self.alpha!r}, beta {self.beta!r}"
            )

    @property
    def bounds(self) -> tuple[float, float]:
        """(ln B, ln A): accept H0 at or below the first, H1 at or above the second."""
        return float(np.log(self.beta / (1 - self.alpha))), float(np.log((1 - self.beta) / self.alpha))

    def llr(self, errors_um) -> np.ndarray:
        """Log-likelihood ratio of each visit; ``errors_um`` has one row of ``dim`` components per visit."""
        e = np.asarray(errors_um, float).reshape(-1, self.dim)
        s0, s1 = self.r0_um / np.sqrt(self.dim), self.r1_um / np.sqrt(self.dim)
        sq = np.sum(e**2, axis=1)
        return self.dim * np.log(s0 / s1) + 0.5 * sq * (1 / s0**2 - 1 / s1**2)

    def decide(self, errors_um, groups=None, planned: int | None = None) -> dict:
        """``{decision, visits, planned, llr, bounds}``: "within tolerance", "recalibrate" or
        "undecided" (truncated, ``leaning`` to one side) after the visits in order; with
        ``groups`` (one label per visit) the bounds are looked at only at each group's last
        visit. ``planned`` (default: the visits given) is the visits the check may make."""
        steps = np.cumsum(self.llr(errors_um))
        low, high = self.bounds
        planned = int(steps.size) if planned is None else int(planned)
        looks = np.ones(steps.size, bool)
        if groups is not None:
            g = np.asarray(groups)
            looks = np.r_[g[1:] != g[:-1], True] if g.size else looks
        for i, s in enumerate(steps):
            if not looks[i]:
                continue
            decision = "recalibrate" if s >= high else "within tolerance" if s <= low else None
            if decision is not None:
                return {
                    "decision": decision,
                    "visits": i + 1,
                    "planned": planned,
                    "llr": float(s),
                    "bounds": [low, high],
                }
        last = float(steps[-1]) if steps.size else 0.0
        return {
            "decision": "undecided",
            "visits": int(steps.size),
            "planned": planned,
            "llr": last,
            "bounds": [low, high],
            "leaning": "recalibrate" if last > 0 else "within tolerance",
        }

    def expected_visits(self) -> dict:
        """Wald's approximate average sample numbers under H0 and H1 (visits)."""
        low, high = self.bounds
        s0, s1 = self.r0_um / np.sqrt(self.dim), self.r1_um / np.sqrt(self.dim)
        c = 0.5 * (1 / s0**2 - 1 / s1**2)
        base = self.dim * np.log(s0 / s1)
        mean0 = base + c * self.dim * s0**2
        mean1 = base + c * self.dim * s1**2
        asn0 = ((1 - self.alpha) * low + self.alpha * high) / mean0
        asn1 = (self.beta * low + (1 - self.beta) * high) / mean1
        return {"H0": float(asn0), "H1": float(asn1)}
