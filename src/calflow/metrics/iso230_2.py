"""ISO 230-2 bidirectional positioning analysis of a linear axis.

Definitions (ISO 230-2:2014, clause 3), for target positions P_i, i = 1..m, each reached
in cycles j = 1..n in the forward (↑) and backward (↓) direction:

* positional deviation x_ij = P_ij - P_i (attained minus target);
* mean unidirectional positional deviation x̄↑_i = (1/n) sum_j x↑_ij (likewise x̄↓_i);
* mean bidirectional positional deviation x̄_i = (x̄↑_i + x̄↓_i) / 2;
* reversal value at a position B_i = x̄↑_i - x̄↓_i (signed); reversal value of the axis
  B = max |B_i| (an absolute value, never negative); mean reversal value of the axis
  B̄ = (1/m) sum_i B_i (signed: it says which direction lies above the other);
* estimator of the unidirectional axis positioning repeatability at a position
  s↑_i = sqrt(sum_j (x↑_ij - x̄↑_i)^2 / (n - 1)) (likewise s↓_i);
* unidirectional positioning repeatability at a position R↑_i = 4 s↑_i (likewise R↓_i);
  bidirectional R_i = max(2 s↑_i + 2 s↓_i + |B_i|, R↑_i, R↓_i);
  of the axis R↑ = max R↑_i, R↓ = max R↓_i, R = max R_i;
* unidirectional systematic positioning error of the axis E↑ = max x̄↑_i - min x̄↑_i
  (likewise E↓); bidirectional E = max(x̄↑_i, x̄↓_i) - min(x̄↑_i, x̄↓_i);
* range of the mean bidirectional positional deviation M = max x̄_i - min x̄_i;
* unidirectional accuracy A↑ = max(x̄↑_i + 2 s↑_i) - min(x̄↑_i - 2 s↑_i) (likewise A↓);
  bidirectional accuracy A = max(x̄↑_i + 2 s↑_i, x̄↓_i + 2 s↓_i)
  - min(x̄↑_i - 2 s↑_i, x̄↓_i - 2 s↓_i).

All results are in the length unit of the inputs.  Forward and backward may have different
numbers of cycles (each >= 2); they share the target positions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .iso9283 import _finite, _readonly

__all__ = ["ISO230_2Result", "iso230_2"]


@dataclass(frozen=True, eq=False)
class ISO230_2Result:
    """ISO 230-2 axis values (floats) and per-position arrays (shape (m,)), input unit.

    Axis values: ``E, E_fwd, E_bwd`` (systematic positioning error), ``M`` (range of mean
    bidirectional positional deviation), ``B`` (axis reversal value max |B_i| >= 0),
    ``B_mean`` (mean reversal value B̄, signed), ``R, R_fwd, R_bwd`` (repeatability),
    ``A, A_fwd, A_bwd`` (accuracy).

    Per position i: ``x_fwd`` = x̄↑_i, ``x_bwd`` = x̄↓_i, ``x_bidir`` = x̄_i, ``s_fwd`` = s↑_i,
    ``s_bwd`` = s↓_i, ``B_i``, ``R_fwd_i`` = 4 s↑_i, ``R_bwd_i`` = 4 s↓_i, ``R_i``.
    ``dev_fwd``/``dev_bwd`` are the deviations x_ij, shape (m, cycles).
    """

    targets: np.ndarray
    dev_fwd: np.ndarray
    dev_bwd: np.ndarray
    x_fwd: np.ndarray
    x_bwd: np.ndarray
    x_bidir: np.ndarray
    s_fwd: np.ndarray
    s_bwd: np.ndarray
    B_i: np.ndarray
    R_fwd_i: np.ndarray
    R_bwd_i: np.ndarray
    R_i: np.ndarray
    E: float
    E_fwd: float
    E_bwd: float
    M: float
    B: float
    B_mean: float
    R: float
    R_fwd: float
    R_bwd: float
    A: float
    A_fwd: float
    A_bwd: float

    @property
    def positions(self) -> int:
        """Number of target positions m."""
        return int(self.targets.size)


def _attained(a, name: str, m: int) -> np.ndarray:
    arr = np.asarray(a, dtype=float)
    if arr.ndim != 2:
        raise ValueError(f"{name} must have shape (positions, cycles); got shape {arr.shape}")
    if arr.shape[0] != m:
        raise ValueError(f"{name} has {arr.shape[0]} positions but targets has {m}; rows must match targets")
    if arr.shape[1] < 2:
        raise ValueError(f"{name} needs at least 2 cycles (s uses n - 1); got {arr.shape[1]}")
    return _finite(arr, name)


def _span(values: np.ndarray) -> float:
    return float(values.max() - values.min())


def iso230_2(targets, forward, backward) -> ISO230_2Result:
    """ISO 230-2 bidirectional analysis of a linear axis (definitions in the module doc).

    Parameters
    ----------
    targets : array_like (m,)
        Target positions P_i, any length unit.
    forward : array_like (m, n_fwd)
        Attained positions P_ij reached in the forward (↑) direction, one row per target,
        one column per cycle, n_fwd >= 2.  Same unit.
    backward : array_like (m, n_bwd)
        Attained positions reached in the backward (↓) direction, n_bwd >= 2.  Same unit.

    Returns
    -------
    ISO230_2Result
        Axis values and per-position arrays, in the unit of the inputs.

    Raises
    ------
    ValueError
        Bad shapes, fewer than 2 cycles, mismatched positions, or NaN/inf.
    """
    tgt = np.asarray(targets, dtype=float)
    if tgt.ndim != 1 or tgt.size < 1:
        raise ValueError(f"targets must be a non-empty 1-D array of positions; got shape {tgt.shape}")
    _finite(tgt, "targets")
    m = tgt.size
    dev_f = _attained(forward, "forward", m) - tgt[:, None]
    dev_b = _attained(backward, "backward", m) - tgt[:, None]

    x_f = dev_f.mean(axis=1)
    x_b = dev_b.mean(axis=1)
    s_f = dev_f.std(axis=1, ddof=1)
    s_b = dev_b.std(axis=1, ddof=1)
    x_bi = (x_f + x_b) / 2.0
    b_i = x_f - x_b
    r_f_i = 4.0 * s_f
    r_b_i = 4.0 * s_b
    r_i = np.maximum.reduce([2.0 * s_f + 2.0 * s_b + np.abs(b_i), r_f_i, r_b_i])

    both = np.concatenate([x_f, x_b])
    upper = np.concatenate([x_f + 2.0 * s_f, x_b + 2.0 * s_b])
    lower = np.concatenate([x_f - 2.0 * s_f, x_b - 2.0 * s_b])
    return ISO230_2Result(
        targets=_readonly(tgt),
        dev_fwd=_readonly(dev_f),
        dev_bwd=_readonly(dev_b),
        x_fwd=_readonly(x_f),
        x_bwd=_readonly(x_b),
        x_bidir=_readonly(x_bi),
        s_fwd=_readonly(s_f),
        s_bwd=_readonly(s_b),
        B_i=_readonly(b_i),
        R_fwd_i=_readonly(r_f_i),
        R_bwd_i=_readonly(r_b_i),
        R_i=_readonly(r_i),
        E=_span(both),
        E_fwd=_span(x_f),
        E_bwd=_span(x_b),
        M=_span(x_bi),
        B=float(np.abs(b_i).max()),
        B_mean=float(b_i.mean()),
        R=float(r_i.max()),
        R_fwd=float(r_f_i.max()),
        R_bwd=float(r_b_i.max()),
        A=float(upper.max() - lower.min()),
        A_fwd=float((x_f + 2.0 * s_f).max() - (x_f - 2.0 * s_f).min()),
        A_bwd=float((x_b + 2.0 * s_b).max() - (x_b - 2.0 * s_b).min()),
    )
