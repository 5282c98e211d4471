"""Nonlinear least squares identification of the XYΘ parameters (Sec. 4.5.4).

The thesis uses MATLAB's ``lsqnonlin``; calflow uses :func:`scipy.optimize.least_squares`
with the analytic Jacobian of the pose-difference cost, Eq. (4.28)–(4.30).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from calflow.xytheta import cost
from calflow.xytheta.kinematics import PARAMETER_NAMES, Parameters


@dataclass(frozen=True)
class Identification:
    """Result of an identification.

    ``std`` and ``correlation`` cover the free parameters (µm or degree); they are NaN
    where no residual degree of freedom is left. ``residual_rms_um`` is the RMS of ε.
    """

    parameters: Parameters
    free: tuple[str, ...]
    std: dict[str, float]
    correlation: np.ndarray
    covariance: np.ndarray
    jacobian: np.ndarray
    residual_rms_um: float
    n_poses: int
    dof: int
    nfev: int
    success: bool
    message: str


def parameter_covariance(J: np.ndarray, eps: np.ndarray, n_poses: int) -> tuple[np.ndarray, int]:
    """Covariance of the estimate from the Jacobian and residuals, and the residual dof.

    The pose differences make ε correlated: Cov(ε) = σ² D Dᵀ (see
    :func:`cost.difference_operator_gram`). The covariance is the sandwich
    (JᵀJ)⁻¹ Jᵀ (σ² D Dᵀ) J (JᵀJ)⁻¹, with σ² estimated without bias from
    E[rᵀr] = σ² tr((I − H) D Dᵀ). Returns NaNs when no degree of freedom is left.
    """
    m, p = J.shape
    dof = m - p
    nan = np.full((p, p), np.nan)
    if dof <= 0:
        return nan, dof
    G = cost.difference_operator_gram(n_poses)
    try:
        JtJ_inv = np.linalg.inv(J.T @ J)
    except np.linalg.LinAlgError:
        return nan, dof
    middle = J.T @ G @ J
    effective = np.trace(G) - np.trace(JtJ_inv @ middle)
    if effective <= 0:
        return nan, dof
    sigma2 = float(eps @ eps) / effective
    return sigma2 * JtJ_inv @ middle @ JtJ_inv, dof


def identify(X, Y, theta, P_mx, P_my, free=PARAMETER_NAMES, initial: Parameters | None = None,
             ex=0.0, ey=0.0, f_ax=0.0, f_ay=0.0) -> Identification:
    """Identify the free parameters of Eq. (4.18) from measured tool points.

    ``X``, ``Y`` (µm), ``theta`` (degree) are the joint values; ``P_mx``, ``P_my`` the
    measured tool points of :func:`cost.measured_points` (µm). Parameters not in ``free``
    keep their value from ``initial``. Rows with a NaN are dropped.
    """
    X, Y, theta, P_mx, P_my = (np.asarray(a, dtype=float) for a in (X, Y, theta, P_mx, P_my))
    ex, ey = np.broadcast_to(ex, X.shape), np.broadcast_to(ey, X.shape)
    f_ax, f_ay = np.broadcast_to(f_ax, X.shape), np.broadcast_to(f_ay, X.shape)
    ok = np.isfinite(X) & np.isfinite(Y) & np.isfinite(theta) & np.isfinite(P_mx) & np.isfinite(P_my)
    X, Y, theta, P_mx, P_my, ex, ey, f_ax, f_ay = (a[ok] for a in (X, Y, theta, P_mx, P_my, ex, ey, f_ax, f_ay))
    n = len(X)
    initial = initial or Parameters(x_R=0.0, y_R=0.0)
    unknown = set(free) - set(PARAMETER_NAMES)
    if unknown:
        raise ValueError(f"free parameters {sorted(unknown)} unknown; expected some of {PARAMETER_NAMES}")
    idx = [PARAMETER_NAMES.index(name) for name in free]
    base = initial.as_array()

    def full(values):
        phi = base.copy()
        phi[idx] = values
        return Parameters.from_array(phi)

    def fun(values):
        return cost.residuals(full(values), X, Y, theta, P_mx, P_my, ex, ey, f_ax, f_ay)

    def jac(values):
        return cost.jacobian(full(values), X, Y, theta, ex, ey)[:, idx]

    if n < 2:
        raise ValueError(f"identification needs at least 2 valid poses, got {n}")
    sol = least_squares(fun, base[idx], jac=jac, method="lm", x_scale="jac", xtol=1e-15, ftol=1e-15, gtol=1e-15)
    J = jac(sol.x)
    cov, dof = parameter_covariance(J, sol.fun, n)
    std = {name: float(np.sqrt(cov[k, k])) if np.isfinite(cov[k, k]) else float("nan")
           for k, name in enumerate(free)}
    with np.errstate(invalid="ignore", divide="ignore"):
        sd = np.sqrt(np.diag(cov))
        corr = cov / np.outer(sd, sd)
    return Identification(
        parameters=full(sol.x),
        free=tuple(free),
        std=std,
        correlation=corr,
        covariance=cov,
        jacobian=J,
        residual_rms_um=float(np.sqrt(np.mean(sol.fun**2))),
        n_poses=n,
        dof=dof,
        nfev=int(sol.nfev),
        success=bool(sol.success),
        message=str(sol.message),
    )


def noise_sigma(eps: np.ndarray, n_poses: int, n_free: int) -> float:
    """σ̂ (µm): the noise per reading and axis that the residuals ε imply, Cov(ε) = σ² D Dᵀ.

    ``E[εᵀε] ≈ σ² (tr(D Dᵀ) − 2 p)``, tr(D Dᵀ) = 4 (n − 1) (:func:`parameter_covariance`
    gives the exact correction); this is what a model-adequacy test compares with the
    repeatability floor.
    """
    effective = 4.0 * (n_poses - 1) - 2.0 * n_free
    return float(np.sqrt(float(eps @ eps) / effective)) if effective > 0 else float("nan")


def cross_validate(X, Y, theta, P_mx, P_my, free, initial: Parameters, k: int = 5, seed: int = 0,
                   ex=0.0, ey=0.0, f_ax=0.0, f_ay=0.0) -> float:
    """k-fold prediction RMS (µm) of the pose-difference residuals ε, Eq. (4.30).

    The poses after the home row are dealt at random into ``k`` folds; each fold's poses
    are predicted by the parameters identified (with ``ex``, ``ey``) on the other folds,
    with the model's angle errors ``f_ax``, ``f_ay`` added in the prediction, and ε is
    taken between consecutive poses of the fold as in the fit. Comparable with the fit's
    ``residual_rms_um``: much larger means the model fits the noise or its structure
    does not carry to poses it has not seen.
    """
    X, Y, theta, P_mx, P_my = (np.asarray(a, dtype=float) for a in (X, Y, theta, P_mx, P_my))
    ex, ey, f_ax, f_ay = (np.broadcast_to(np.asarray(a, dtype=float), X.shape) for a in (ex, ey, f_ax, f_ay))
    ok = np.flatnonzero(np.isfinite(X) & np.isfinite(Y) & np.isfinite(theta) & np.isfinite(P_mx) & np.isfinite(P_my))
    rest = ok[1:]
    if k < 2 or rest.size < 2 * k:
        raise ValueError(f"cross-validation: {rest.size} poses cannot make {k} folds of 2 or more")
    folds = np.array_split(np.random.default_rng(seed).permutation(rest), k)
    sq, count = 0.0, 0
    for fold in folds:
        train = np.sort(np.concatenate([[ok[0]], np.setdiff1d(rest, fold)]))
        fit = identify(X[train], Y[train], theta[train], P_mx[train], P_my[train], free=free, initial=initial,
                       ex=ex[train], ey=ey[train])
        test = np.sort(fold)
        eps = cost.residuals(fit.parameters, X[test], Y[test], theta[test], P_mx[test], P_my[test],
                             ex[test], ey[test], f_ax[test], f_ay[test])
        sq, count = sq + float(eps @ eps), count + eps.size
    return float(np.sqrt(sq / count))


def bootstrap_std(X, Y, theta, P_mx, P_my, free, initial: Parameters, n_resamples: int = 200, seed: int = 0,
                  ex=0.0, ey=0.0) -> dict[str, float]:
    """Pose-bootstrap standard deviations of the free parameters (µm or degree).

    Poses (after the home row, which defines the frame and stays) are resampled with
    replacement and the model refitted ``n_resamples`` times. Why a pairs bootstrap: when
    the model does not fit, the residuals are not independent noise of one σ but a field
    of unmodelled errors sampled at random poses; resampling the poses themselves gives
    the spread of the estimate over such draws (asymptotically the Huber–White sandwich),
    whatever the residuals' size or their dependence on the pose. It does *not* cover the
    bias of a wrong model — the distance to the best-fitting "pseudo-true" value of the
    workspace is what it measures, not the distance to the physical parameters; the
    adequacy test says when the two differ.
    """
    X, Y, theta, P_mx, P_my = (np.asarray(a, dtype=float) for a in (X, Y, theta, P_mx, P_my))
    ex, ey = (np.broadcast_to(np.asarray(a, dtype=float), X.shape) for a in (ex, ey))
    rng = np.random.default_rng(seed)
    n = X.size
    estimates = []
    for _ in range(int(n_resamples)):
        rows = np.concatenate([[0], np.sort(rng.integers(1, n, n - 1))])
        fit = identify(X[rows], Y[rows], theta[rows], P_mx[rows], P_my[rows], free=free, initial=initial,
                       ex=ex[rows], ey=ey[rows])
        estimates.append([getattr(fit.parameters, name) for name in free])
    sd = np.std(np.asarray(estimates), axis=0, ddof=1)
    return {name: float(v) for name, v in zip(free, sd)}
