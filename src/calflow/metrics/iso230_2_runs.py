"""ISO 230-2 of a run dataset: attained positions grouped by target, direction and cycle."""

from __future__ import annotations

import numpy as np
import xarray as xr

from calflow.errors import DataError
from calflow.metrics.iso230_2 import iso230_2

NM_PER_UM = 1000.0


def _where(run: xr.Dataset) -> str:
    return f"run {run.attrs.get('campaign', '?')}/{run.attrs.get('plan', '?')}"


def tables_of_run(run: xr.Dataset, attained=None, target=None):
    """``(targets, forward, backward, forward_cycles, backward_cycles, excluded_targets)``: the attained
    positions of a 1-DoF run per target (both directions) and cycle, as
    :func:`iso230_2_of_run` scores them (its notes say which targets and cycles are kept)."""
    x = np.asarray(run["meas_x"].values if attained is None else attained, dtype=float)
    tgt = np.asarray(run["target_x"].values if target is None else target, dtype=float)
    direction, cycle = run["direction"].values.astype(int), run["cycle"].values.astype(int)
    key = np.round(tgt, 6)
    fwd_t, bwd_t = set(key[direction > 0]), set(key[direction < 0])
    both = np.array(sorted(fwd_t & bwd_t))
    if both.size == 0:
        raise DataError(f"{_where(run)}: no target is reached in both directions; ISO 230-2 needs both")

    def table(sign: int) -> tuple[np.ndarray, np.ndarray]:
        # each sample's cell (target, cycle), the samples of a cell in their order
        rows = np.flatnonzero(direction == sign)
        cycles = np.unique(cycle[rows])
        a = np.full((both.size, cycles.size), np.nan)
        i = np.minimum(np.searchsorted(both, key[rows]), both.size - 1)
        rows, i = rows[both[i] == key[rows]], i[both[i] == key[rows]]
        cell = i * cycles.size + np.searchsorted(cycles, cycle[rows])
        order = np.argsort(cell, kind="stable")
        cells, first, count = np.unique(cell[order], return_index=True, return_counts=True)
        one = x[rows[order[first]]]
        a.flat[cells[count == 1]] = np.where(np.isfinite(one), one, np.nan)[count == 1]
        for c, f, n in zip(cells[count > 1], first[count > 1], count[count > 1], strict=True):
            v = x[rows[order[f : f + n]]]
            a.flat[c] = np.nanmean(v) if np.isfinite(v).any() else np.nan
        keep = np.all(np.isfinite(a), axis=0)
        return a[:, keep], cycles[keep]

    fwd, fc = table(1)
    bwd, bc = table(-1)
    excluded = sorted(float(t) for t in (fwd_t | bwd_t) - set(both))
    return both, fwd, bwd, fc, bc, excluded


def iso230_2_of_run(run: xr.Dataset, attained=None, target=None) -> dict:
    """ISO 230-2 of a 1-DoF run (training): E, M, B, R, A and parts, in nm.

    ``attained``/``target`` (µm, one per sample) replace ``meas_x``/``target_x`` — e.g. the
    stage-frame displacement and the command of an XY characterisation sweep.

    Attained positions ``meas_x`` grouped by target ``target_x`` and ``direction`` (+1
    forward, −1 backward), one column per cycle.  Only targets reached in both directions
    are used: the turning point of the sweep (480 µm) is reached forward only and is
    listed in ``excluded_targets_um``.  Cycles with a NaN reading at any used target in a
    direction are dropped for that direction.
    """
    both, fwd, bwd, fc, bc, excluded = tables_of_run(run, attained, target)
    r = iso230_2(both, fwd, bwd)
    nm = {
        k: float(getattr(r, k)) * NM_PER_UM
        for k in ("E", "E_fwd", "E_bwd", "M", "B", "B_mean", "R", "R_fwd", "R_bwd", "A", "A_fwd", "A_bwd")
    }
    return {
        "units": "nm",
        **{f"{k}_nm": v for k, v in nm.items()},
        "targets_um": both.tolist(),
        "excluded_targets_um": excluded,
        "cycles_forward": int(fc.size),
        "cycles_backward": int(bc.size),
        "mean_deviation_forward_nm": (r.x_fwd * NM_PER_UM).tolist(),
        "mean_deviation_backward_nm": (r.x_bwd * NM_PER_UM).tolist(),
    }
