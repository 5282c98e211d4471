"""The XYΘ identification design for a model that is not exact (criterion
``discrepancy``): the minimax-variance design (``MV``: the fewest poses whose worst
parameter's Cramér–Rao σ reaches the random plan's), then exchanged against the expected
integrated squared prediction error under a Gaussian-process discrepancy
(:mod:`calflow.identification.discrepancy`) with every parameter's σ kept within that bound —
same pose count, same rig time, less bet on the model being exact.

The discrepancy is what Model II does not represent, largely the lead-screw errors of the X
and Y stages (Sec. 4.4.1): an additive kernel over the joints X, Y (Θ's angle errors are the
angle table's, Models IV–V). Its amplitude and length scale come from data the campaign has
before identification — the characterisation's XY error tables (:class:`PositionLUT`) — by
the moments of a squared-exponential process: s² = var e, ℓ² = var e / var(de/dq).
"""

from __future__ import annotations

import numpy as np

from calflow.identification import discrepancy as dc
from calflow.identification.design import latin_hypercube
from calflow.xytheta.design import criteria as design

#: Test poses drawn over the identification workspace: where the calibrated model is used.
TEST_POSES = 256


def kernel_from_tables(luts) -> dc.Discrepancy:
    """The discrepancy's kernel from the XY error tables (a :class:`calflow.xytheta.tables.position.PositionLUT`).

    Per joint j ∈ {X, Y}: the tables of its own and its cross error (forward and backward
    columns), each less its linear fit; s_j² = ½ Σ_tables var e (the variance per reading axis
    of the 2-vector error), ℓ_j = √(var e / var(de/dq)) pooled over the tables (µm; the zero-lag
    curvature of a squared-exponential covariance). Θ gets no term (amplitude 0, length 1°).
    """
    amp, length = [], []
    for pos, tables in ((luts.x_position, (luts.xx, luts.xy)), (luts.y_position, (luts.yy, luts.yx))):
        pos = np.asarray(pos, dtype=float)
        v = dv = 0.0  # Σ over the two tables of the mean over their columns
        for table in tables:
            for col in np.asarray(table, dtype=float).T:
                ok = np.isfinite(col)
                e = col[ok] - np.polyval(np.polyfit(pos[ok], col[ok], 1), pos[ok])
                v += np.var(e) / 2.0
                dv += np.var(np.gradient(e, pos[ok])) / 2.0
        amp.append(float(np.sqrt(v / 2.0)))
        length.append(float(np.sqrt(v / dv)) if dv > 0 else float(np.ptp(pos)))
    return dc.Discrepancy((amp[0], amp[1], 0.0), (length[0], length[1], 1.0))


def with_kernel_from_tables(campaign: dict, luts_path) -> dict:
    """The campaign with ``identification.design.discrepancy`` taken from the XY tables at
    ``luts_path`` (:func:`kernel_from_tables`) where the config leaves it null."""
    import copy

    from calflow.data.io import open_dataset
    from calflow.xytheta.tables.position import PositionLUT

    given = campaign["identification"]["design"].get("discrepancy") or {}
    if given.get("amplitude_um") is not None and given.get("length") is not None:
        return campaign
    k = kernel_from_tables(PositionLUT.from_dataset(open_dataset(luts_path, kind="luts")))
    out = copy.deepcopy(campaign)
    out["identification"]["design"]["discrepancy"] = {
        "amplitude_um": list(k.amplitude),
        "length": list(k.length),
        "from": "tables",
    }
    return out


def kernel(campaign: dict) -> dc.Discrepancy:
    """The campaign's ``identification.design.discrepancy`` (amplitude µm, length µm/µm/degree)."""
    given = campaign["identification"]["design"].get("discrepancy") or {}
    if given.get("amplitude_um") is None or given.get("length") is None:
        raise ValueError(
            "identification.design.discrepancy: criterion discrepancy needs amplitude_um and length "
            "(X, Y, theta), or the XY tables (calflow acquire --luts; the workflow passes them)"
        )
    return dc.Discrepancy(
        tuple(float(a) for a in given["amplitude_um"]), tuple(float(v) for v in given["length"])
    )


def test_poses(lo, hi, seed: int, n: int = TEST_POSES) -> np.ndarray:
    """``n`` poses (n, 3) spread over the workspace box (a Latin hypercube from its own stream):
    the measure the prediction error is averaged over — never the validation's targets."""
    return latin_hypercube(np.random.default_rng(np.random.SeedSequence([int(seed), 15, 2])), n, lo, hi)


def polish(
    pool: np.ndarray,
    chosen: np.ndarray,
    phi,
    free,
    kern: dc.Discrepancy,
    sigma_um: float,
    sigma_max: np.ndarray,
    lo,
    hi,
    seed: int,
) -> np.ndarray:
    """Indices of ``pool`` that replace ``chosen`` (same count) to lower the expected integrated
    squared prediction error, every free parameter's Cramér–Rao σ (per-axis noise ``sigma_um``)
    at most ``sigma_max``; the frame is anchored at home (0, 0, 0), whose reading the plan makes
    too (a pose of the design that stays)."""
    qt = test_poses(lo, hi, seed)
    q = np.vstack([pool, np.zeros((1, 3))])
    J = design.pose_jacobians(q, phi, free)
    home = len(pool)
    idx = dc.exchange(
        J,
        q,
        np.append(chosen, home),
        design.pose_jacobians(qt, phi, free),
        qt,
        kern,
        np.zeros(3),
        sigma_um,
        sigma_max=sigma_max,
        keep=[home],
    )
    return idx[idx != home]


def expected_error(
    q: np.ndarray, phi, free, kern: dc.Discrepancy, sigma_um: float, lo, hi, seed: int
) -> dict:
    """IMSE, its variance and bias parts (µm²) of the plan ``q`` (n, 3, home included) under ``kern``."""
    qt = test_poses(lo, hi, seed)
    return dc.expected_error(
        design.pose_jacobians(q, phi, free),
        q,
        design.pose_jacobians(qt, phi, free),
        qt,
        kern,
        np.zeros(3),
        sigma_um,
    )
