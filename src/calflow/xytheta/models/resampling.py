"""How well an XYΘ identification predicts poses it did not see: k-fold cross-validation
and the bootstrap σ of the parameters (Sec. 4.5.4), on the fits of
:mod:`calflow.xytheta.models.identification`.
"""

from __future__ import annotations

import numpy as np

from calflow.identification import gauss_newton
from calflow.xytheta.models import cost
from calflow.xytheta.models.identification import _fit, _start, _valid, identify
from calflow.xytheta.models.kinematics import Parameters


def _fold_fits(readings: cost.Readings, train: np.ndarray, idx: list[int], base: np.ndarray) -> np.ndarray:
    """(φ, x_m0, y_m0) fitted by least squares to each row set of ``train`` (folds × readings,
    boolean), each started as :func:`_fit` starts it: the folds' Gauss–Newton iterations run
    in lock-step (:func:`gauss_newton.solve_batch`) on their Gram matrices; a fold that
    does not converge so is fitted alone by :func:`_fit`. Shape (folds, 6)."""
    C, M = readings.columns, train.astype(float)
    grams = (C[None] * M[:, None, :]) @ C.T

    def full(x):
        phi = np.tile(base, (x.shape[0], 1))
        phi[:, idx] = x
        return phi

    def residuals(phi):  # (folds, 2 axes, readings)
        return np.stack([cost.Readings._coefficients(p).T for p in phi]) @ C

    def sum_sq(x):
        R = residuals(full(x))
        return np.einsum("kn,kn->k", (R * R).sum(axis=1), M)

    def normal(x):
        phi = full(x)
        E = np.stack([cost.Readings._derivatives(p) for p in phi])[..., idx]  # (folds, 2, 7, p)
        DR = (residuals(phi) * M[:, None, :]) @ C.T  # Dᵀ ε per fold and axis
        N = (E.swapaxes(-1, -2) @ (grams[:, None] @ E)).sum(axis=1)
        return N, np.einsum("kajp,kaj->kp", E, DR)

    start = np.tile(base, (train.shape[0], 1))
    start[:, 4:] = 0.0
    start[:, 4:] = (residuals(start) * M[:, None, :]).sum(axis=-1) / M.sum(axis=1)[:, None]  # the mean misfit
    x, converged = gauss_newton.solve_batch(sum_sq, normal, start[:, idx], 2 * M.sum(axis=1))
    out = full(x)
    for f in np.flatnonzero(~converged):
        alone = base.copy()
        alone[idx] = _fit(readings.subset(train[f]), idx, alone)[1].x
        out[f] = alone
    return out


def cross_validate(
    X,
    Y,
    theta,
    P_mx,
    P_my,
    free,
    initial: Parameters,
    k: int = 5,
    seed: int = 0,
    ex=0.0,
    ey=0.0,
    f_ax=0.0,
    f_ay=0.0,
) -> float:
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
    ok = np.flatnonzero(_valid(X, Y, theta, P_mx, P_my))
    rest = ok[1:]
    if k < 2 or rest.size < 2 * k:
        raise ValueError(f"cross-validation: {rest.size} poses cannot make {k} folds of 2 or more")
    folds = np.array_split(np.random.default_rng(seed).permutation(rest), k)
    readings = cost.Readings(
        X[ok], Y[ok], theta[ok], P_mx[ok], P_my[ok], ex[ok], ey[ok]
    )  # Θ's trigonometry once
    predict = cost.Readings(X[ok], Y[ok], theta[ok], P_mx[ok], P_my[ok], ex[ok], ey[ok], f_ax[ok], f_ay[ok])
    position = np.full(X.size, -1)
    position[ok] = np.arange(ok.size)
    train = np.ones((k, ok.size), dtype=bool)
    for f, fold in enumerate(folds):
        train[f, position[fold]] = False  # the home row is never in a fold
    idx, base = _start(initial, free)
    estimates = _fold_fits(readings, train, idx, base)
    sq, count = 0.0, 0
    for fold, phi in zip(folds, estimates):
        phi[4:] = 0.0  # the offset cancels in ε
        eps = cost.differences_of_readings(predict.subset(np.sort(position[fold])).residuals(phi))
        sq, count = sq + float(eps @ eps), count + eps.size
    return float(np.sqrt(sq / count))


def bootstrap_std(
    X, Y, theta, P_mx, P_my, free, initial: Parameters, n_resamples: int = 200, seed: int = 0, ex=0.0, ey=0.0
) -> dict[str, float]:
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
        fit = identify(
            X[rows],
            Y[rows],
            theta[rows],
            P_mx[rows],
            P_my[rows],
            free=free,
            initial=initial,
            ex=ex[rows],
            ey=ey[rows],
        )
        estimates.append([getattr(fit.parameters, name) for name in free])
    sd = np.std(np.asarray(estimates), axis=0, ddof=1)
    return {name: float(v) for name, v in zip(free, sd)}
