"""1-D accuracy and intrinsic / extrinsic repeatability (thesis Sec. 3.2.3, Eq. 3.13-3.18).

Model of a measured position (Eq. 3.11): ``x_m = P(x_T) + x_T + g(x_T) + L(t)``, with P the
intrinsic error of the stage, g the position-dependent (geometric) error and L(t) the
external drift.  After calibration (Eq. 3.17-3.18), ``x_m = P(x_T) + x_T + T(t)`` with T the
residual of imperfect compensation; the formulas are the same with T in place of L.

Inputs are in any consistent length unit; outputs are in that same unit.

The standard deviation σ in Eq. (3.14), (3.16) and (3.18) is not defined further in the
thesis, which says the 1-D formulas follow ISO 9283.  We therefore take σ as ISO 9283's
S_l (Eq. 3.8) in 1-D: the sample standard deviation (n - 1) of l_i = |x_mi - x̄_m|.  With
this choice AP and RP here equal ``iso9283(...)`` with d = 1 exactly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .iso9283 import _finite, _readonly

__all__ = [
    "RepeatabilityDecomposition",
    "accuracy_1d",
    "repeatability_1d",
    "decompose_repeatability",
]


def _series(x, name: str) -> np.ndarray:
    a = np.asarray(x, dtype=float)
    if a.ndim != 1:
        raise ValueError(f"{name} must be a 1-D series of n positions; got shape {a.shape}")
    if a.size < 2:
        raise ValueError(f"{name} needs n >= 2 values (σ uses n - 1); got n = {a.size}")
    return _finite(a, name)


def _scalar(x, name: str) -> float:
    a = np.asarray(x, dtype=float)
    if a.ndim != 0 and a.shape != (1,):
        raise ValueError(f"{name} must be a single value; got shape {a.shape}")
    return float(_finite(a.reshape(()), name))


def _distance_to_barycentre(x: np.ndarray) -> tuple[float, float]:
    """ISO 9283's l̄ and S_l in 1-D (thesis Eq. 3.6, 3.8): the mean of l_i = |x_i - x̄| (the
    *mean* absolute deviation about the mean, not the median absolute deviation of robust
    statistics) and the sample standard deviation (n - 1) of the l_i."""
    l = np.abs(x - x.mean())
    return float(l.mean()), float(np.std(l, ddof=1))


def accuracy_1d(measured, target) -> float:
    """1-D accuracy AP = |x̄_m - x_T|, Eq. (3.13) (also Eq. 3.15 and 3.17, first line).

    Parameters
    ----------
    measured : array_like (n,)
        The n measured positions x_mi after reaching target ``x_T`` n times.
    target : float
        The target x_T, same unit.

    Returns
    -------
    float
        AP in the unit of the inputs.
    """
    x = _series(measured, "measured")
    return abs(float(x.mean()) - _scalar(target, "target"))


def repeatability_1d(measured) -> float:
    """1-D repeatability RP = (1/n) sum_i |x_mi - x̄_m| + 3σ, Eq. (3.14) (3.16, 3.18).

    σ is the sample standard deviation (n - 1) of |x_mi - x̄_m| (ISO 9283 S_l in 1-D,
    see the module docstring).  The mean absolute deviation equals ISO's l̄ in 1-D.

    Parameters
    ----------
    measured : array_like (n,), n >= 2
        Measured positions, any length unit.

    Returns
    -------
    float
        RP in the unit of the inputs.
    """
    l_bar, sigma = _distance_to_barycentre(_series(measured, "measured"))
    return l_bar + 3.0 * sigma


@dataclass(frozen=True, eq=False)
class RepeatabilityDecomposition:
    """Accuracy and repeatability split into intrinsic and extrinsic parts (Eq. 3.13-3.18).

    All values in the unit of the inputs.

    Attributes
    ----------
    n : int
        Number of measured positions.
    ap : float
        AP_E = |x̄_m - x_T|, Eq. (3.15) (AP_S, Eq. 3.17, after calibration).
    rp : float
        RP_E = (1/n) sum |x_mi - x̄_m| + 3σ_E, Eq. (3.16) first line (RP_S, Eq. 3.18).
    mean_abs_deviation : float
        (1/n) sum |x_mi - x̄_m|.
    sigma : float
        σ_E, sample standard deviation (n - 1) of |x_mi - x̄_m|.
    intrinsic : ndarray (n,)
        P_i - P̄, the intrinsic deviations (measured minus extrinsic, centred).
    extrinsic : ndarray (n,)
        L_i - L̄ (or T_i - T̄), the extrinsic deviations.
    intrinsic_term : float
        (1/n) sum |P_i - P̄|, the intrinsic term of the bound in Eq. (3.16).
    extrinsic_term : float
        (1/n) sum |L_i - L̄|, the extrinsic term of the bound in Eq. (3.16).
    rp_bound : float
        intrinsic_term + extrinsic_term + 3σ_E, the right-hand side of the inequality in
        Eq. (3.16); ``rp <= rp_bound`` always (triangle inequality).
    extrinsic_mean : float
        (1/n) sum L_i, the extrinsic contribution inside the absolute value of Eq. (3.15).
    ap_intrinsic : float
        |x̄_m - L̄ - x_T| = |g(x_T) + P̄|, Eq. (3.13): the accuracy without the extrinsic part.
    rp_intrinsic : float
        Eq. (3.14) applied to x_mi - L_i: the intrinsic repeatability RP_I.
    """

    n: int
    ap: float
    rp: float
    mean_abs_deviation: float
    sigma: float
    intrinsic: np.ndarray
    extrinsic: np.ndarray
    intrinsic_term: float
    extrinsic_term: float
    rp_bound: float
    extrinsic_mean: float
    ap_intrinsic: float
    rp_intrinsic: float


def decompose_repeatability(measured, target, extrinsic) -> RepeatabilityDecomposition:
    """Split AP and RP of one target into intrinsic and extrinsic parts, Eq. (3.15)-(3.18).

    Given the measured positions x_mi (Eq. 3.11) and an estimate of the extrinsic part of
    each measurement, L_i (thermal drift, Eq. 3.15-3.16) or T_i (residual drift after
    compensation, Eq. 3.17-3.18), the intrinsic part is P_i + g + x_T = x_mi - L_i, so
    P_i - P̄ = (x_mi - L_i) - mean(x_m - L).  Then (Eq. 3.16)

        RP_E = (1/n) sum |(P_i - P̄) + (L_i - L̄)| + 3σ_E
             <= (1/n) sum |P_i - P̄| + (1/n) sum |L_i - L̄| + 3σ_E.

    Parameters
    ----------
    measured : array_like (n,)
        Measured positions x_mi at one target, any length unit, n >= 2.
    target : float
        The target x_T, same unit.
    extrinsic : array_like (n,)
        L_i (or T_i) for each measurement, same unit.  Its deviations from its mean give
        the extrinsic repeatability; its mean (with L = 0 meaning no drift) is removed for
        ``ap_intrinsic``.

    Returns
    -------
    RepeatabilityDecomposition
        Values in the unit of the inputs.
    """
    x = _series(measured, "measured")
    x_t = _scalar(target, "target")
    ext = _series(extrinsic, "extrinsic")
    if ext.shape != x.shape:
        raise ValueError(
            f"extrinsic must have one value per measurement: shape {x.shape}; got shape {ext.shape}"
        )
    n = x.size
    l_bar, sigma = _distance_to_barycentre(x)
    corrected = x - ext  # P_i + g(x_T) + x_T
    p_dev = corrected - corrected.mean()
    l_dev = ext - ext.mean()
    intrinsic_term = float(np.abs(p_dev).mean())
    extrinsic_term = float(np.abs(l_dev).mean())
    l_bar_c, sigma_c = _distance_to_barycentre(corrected)
    return RepeatabilityDecomposition(
        n=n,
        ap=abs(float(x.mean()) - x_t),
        rp=l_bar + 3.0 * sigma,
        mean_abs_deviation=l_bar,
        sigma=sigma,
        intrinsic=_readonly(p_dev),
        extrinsic=_readonly(l_dev),
        intrinsic_term=intrinsic_term,
        extrinsic_term=extrinsic_term,
        rp_bound=intrinsic_term + extrinsic_term + 3.0 * sigma,
        extrinsic_mean=float(ext.mean()),
        ap_intrinsic=abs(float(corrected.mean()) - x_t),
        rp_intrinsic=l_bar_c + 3.0 * sigma_c,
    )
