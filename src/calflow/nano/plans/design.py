"""Optimal design of the nano training positions and its Cramér–Rao bound.

The single model, Eq. (5.3)–(5.5), and the 2-DoF model, Eq. (5.10), are linear in their
coefficients: a training reading gives q = g(x)ᵀ a + tᵀ b + λ + e with the position basis
g(x) = (x, x², …, x^n1) (1-DoF) or (x, …, x^n1, y, …, y^n2) (one equation per joint of
Eq. 5.10, both on the same basis), the thermocouple readings t and the offset λ. The design
sets the positions; it cannot set the temperatures. With λ a nuisance parameter and the
thermal terms left out (temperature uncorrelated with the position sequence, the best
case), the information of a on R readings of σ each is the Schur complement of
:func:`calflow.identification.design.information`, and its inverse the Cramér–Rao bound of
the geometric coefficients — a lower bound of their σ: the thermal drift, hysteresis and
creep of a real stage are not white noise.

Positions are computed on the unit stroke u = x / x_max (conditioning; D does not change),
and coefficients are returned per µm: σ(a_i) = σ(ã_i) / x_max^i, in µm^(1−i).
"""

from __future__ import annotations

import numpy as np

from calflow.identification.design import crlb_sigma, information, optimal_design, space_filling


def basis(positions: np.ndarray, order: int, scale_um: np.ndarray) -> np.ndarray:
    """Position basis of Eq. (5.3) / (5.10) at ``positions`` (n, d) µm, as (n, 1, d·order)
    regressor rows on the unit stroke (u = x / ``scale_um`` per axis; columns u_j^i for
    each axis j, i = 1..order)."""
    u = np.asarray(positions, dtype=float) / np.asarray(scale_um, dtype=float)
    cols = [u[:, j] ** i for j in range(u.shape[1]) for i in range(1, order + 1)]
    return np.column_stack(cols)[:, None, :]


def coefficient_scale(order: int, scale_um: np.ndarray) -> np.ndarray:
    """x_max^i of every coefficient of :func:`basis`: σ(a) = σ(ã) / this."""
    return np.concatenate([float(s) ** np.arange(1, order + 1) for s in np.atleast_1d(scale_um)])


def candidates(lo_um, hi_um, step_um: float) -> np.ndarray:
    """Candidate positions (N, d) µm: the grid of ``step_um`` over the box [lo, hi] per axis,
    the upper end included."""
    axes = [np.unique(np.append(np.arange(lo, hi, step_um), hi)) for lo, hi in zip(lo_um, hi_um)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, len(axes))


def design_positions(
    pool: np.ndarray, n: int, order: int, scale_um, criterion: str = "D", fraction_space_filling: float = 0.5
) -> np.ndarray:
    """Indices of n distinct positions of ``pool`` (N, d): ⌊f n⌋ space-filling (maximin from
    the stroke's start, a guard against a model that is not exact), the rest maximising ``criterion`` of the
    position basis's information given them (multiplicative weights then Fedorov exchange)."""
    lo, hi = pool.min(0), pool.max(0)
    m = int(np.floor(fraction_space_filling * n))
    fixed_idx = space_filling(pool, m, lo, hi, start="corner")  # the ends of the stroke first
    keep = np.setdiff1d(np.arange(len(pool)), fixed_idx)
    J = basis(pool, order, scale_um)
    d = optimal_design(J[keep], n, criterion, J[fixed_idx] if m else None)
    return np.concatenate([fixed_idx, keep[d.index]]).astype(int)


def information_per_cycle(rows: np.ndarray, order: int, scale_um) -> np.ndarray:
    """Information (σ = 1) of the geometric coefficients on the unit stroke from one cycle's
    readings at ``rows`` (R, d) µm; c identical cycles carry c times it (λ common to all)."""
    return information(basis(rows, order, scale_um))


def coefficient_sigma(rows: np.ndarray, cycles: int, sigma_um: float, order: int, scale_um) -> np.ndarray:
    """Cramér–Rao σ of the geometric coefficients a (µm^(1−i), axis-major) from ``cycles``
    cycles of readings at ``rows`` (R, d) µm, σ ``sigma_um`` per reading."""
    s = crlb_sigma(basis(rows, order, scale_um), sigma_um) / np.sqrt(cycles)
    return s / coefficient_scale(order, scale_um)


def shape_sigma_um(
    rows: np.ndarray, cycles: int, sigma_um: float, order: int, lo_um, hi_um, points: int = 41
) -> float:
    """Worst Cramér–Rao σ (µm) over the stroke of the model's geometric correction relative to
    its start, g(x)ᵀa − g(x_lo)ᵀa: what the positions and cycles determine (λ and the thermal
    terms aside). Evaluated on ``points`` per axis."""
    lo, hi = np.asarray(lo_um, dtype=float), np.asarray(hi_um, dtype=float)
    scale = np.maximum(np.abs(hi), np.abs(lo))
    M = information_per_cycle(rows, order, scale) * cycles / sigma_um**2
    try:
        Minv = np.linalg.inv(M)
    except np.linalg.LinAlgError:
        return float("inf")
    grid = candidates(lo, hi, float(np.min(hi - lo)) / (points - 1))
    D = basis(grid, order, scale)[:, 0, :] - basis(lo[None, :], order, scale)[:, 0, :]
    return float(np.sqrt(np.max(np.einsum("ip,pq,iq->i", D, Minv, D))))


def cycles_for(target_um: float, rows: np.ndarray, sigma_um: float, order: int, lo_um, hi_um) -> int:
    """The fewest cycles whose :func:`shape_sigma_um` is at most ``target_um`` (σ ∝ 1/√cycles)."""
    one = shape_sigma_um(rows, 1, sigma_um, order, lo_um, hi_um)
    return max(1, int(np.ceil((one / target_um) ** 2 - 1e-9)))


def raster(positions: np.ndarray) -> np.ndarray:
    """One 2-DoF cycle (Fig. 5.21): columns of increasing x, y rising on even columns and
    falling on odd ones; returns the visiting order (indices)."""
    p = np.asarray(positions, dtype=float)
    xs = np.unique(p[:, 0])
    col = np.searchsorted(xs, p[:, 0])
    key_y = np.where(col % 2 == 0, p[:, 1], -p[:, 1])
    return np.lexsort((key_y, col))
