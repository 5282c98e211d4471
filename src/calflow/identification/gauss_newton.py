"""Gauss–Newton least squares for small parameter vectors and many residuals.

The identification problems of calflow have a handful of parameters, thousands to
hundreds of thousands of residuals and are nearly linear (Eq. 4.18 is linear in x_R, y_R
and smooth in α, β): Gauss–Newton on the normal equations, p × p, converges in a few
iterations at O(m p²) each — no m × m object, no per-iteration SVD. Robust losses (the
``loss`` names of :func:`scipy.optimize.least_squares`) are minimised by iteratively
reweighted least squares, the same objective Σ f² ρ((r/f)²). Where Gauss–Newton does not
converge (a singular or indefinite step, or too many iterations), the problem goes to
:func:`scipy.optimize.least_squares` (Levenberg–Marquardt, or TRF for a robust loss).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

#: Converged when the step changes the residual vector by less than this fraction of its norm.
RTOL = 1e-10
#: ... or by less than this (residual unit) per residual: rounding level of exact data.
ATOL = 1e-11


@dataclass(frozen=True)
class Solution:
    """``x`` the estimate, ``fun`` the residuals there, ``nfev`` residual evaluations."""

    x: np.ndarray
    fun: np.ndarray
    nfev: int
    success: bool
    message: str


def _rho(z: np.ndarray, loss: str) -> tuple[np.ndarray, np.ndarray]:
    """ρ(z) and ρ'(z) of scipy's losses, z = (r/f)²."""
    if loss == "linear":
        return z, np.ones_like(z)
    if loss == "soft_l1":
        s = np.sqrt(1.0 + z)
        return 2.0 * (s - 1.0), 1.0 / s
    if loss == "huber":
        big = z > 1.0
        root = np.sqrt(np.where(big, z, 1.0))
        return np.where(big, 2.0 * root - 1.0, z), np.where(big, 1.0 / root, 1.0)
    if loss == "cauchy":
        return np.log1p(z), 1.0 / (1.0 + z)
    raise ValueError(f"loss {loss!r}: expected linear, soft_l1, huber or cauchy")


def solve(
    fun,
    jac,
    x0,
    loss: str = "linear",
    f_scale: float = 1.0,
    max_iter: int = 100,
    rtol: float = RTOL,
    normal=None,
) -> Solution:
    """Minimise Σ f² ρ((r_i/f)²) over x for residuals ``fun(x)`` with Jacobian ``jac(x)``.

    Gauss–Newton (iteratively reweighted for a robust ``loss``) with step halving while
    the cost does not fall, until a step changes the residuals by less than ``rtol`` of
    their norm; falls back to :func:`scipy.optimize.least_squares` when a step
    cannot be found or ``max_iter`` is reached. ``normal(x, r, w)``, when given, returns
    (Jᵀ W J, Jᵀ W r, Jᵀ J) for the residuals ``r`` and weights ``w`` (None for the linear
    loss) without forming J — for a problem whose Jacobian has a small Gram structure;
    ``jac`` then serves the fallback only.
    """
    x = np.asarray(x0, dtype=float).copy()
    r = fun(x)
    nfev = 1
    f2 = float(f_scale) ** 2

    def cost(res):
        if loss == "linear":
            return float(res @ res) / f2
        return float(np.sum(_rho(res**2 / f2, loss)[0]))

    c = cost(r)
    for _ in range(max_iter):
        w = None if loss == "linear" else _rho(r**2 / f2, loss)[1]
        if normal is None:
            A = jac(x)
            Aw = A if w is None else A * w[:, None]
            N, g, plain = A.T @ Aw, Aw.T @ r, None
        else:
            N, g, plain = normal(x, r, w)
        try:
            step = np.linalg.solve(N, g)
        except np.linalg.LinAlgError:
            break
        if not np.all(np.isfinite(step)):
            break
        change = (
            float(np.linalg.norm(A @ step))
            if plain is None
            else float(np.sqrt(max(step @ plain @ step, 0.0)))
        )
        if change <= rtol * float(np.linalg.norm(r)) + ATOL * np.sqrt(r.size):
            return Solution(
                x, r, nfev, True, f"Gauss-Newton converged ({loss} loss)"
            )  # the step is below tolerance
        t = 1.0
        while t > 1e-6:
            trial = x - t * step
            r_new = fun(trial)
            nfev += 1
            c_new = cost(r_new)
            if c_new <= c * (1.0 + 1e-12):  # rounding-level rises at the optimum do not stall it
                break
            t *= 0.5
        else:
            break
        x, r, c = trial, r_new, c_new
    method = "lm" if loss == "linear" else "trf"
    kw = {} if loss == "linear" else {"loss": loss, "f_scale": float(f_scale)}
    sol = least_squares(
        fun,
        x,
        jac=jac,
        method=method,
        x_scale="jac",
        xtol=1e-15 if method == "lm" else 1e-12,
        ftol=1e-15 if method == "lm" else 1e-12,
        gtol=1e-15 if method == "lm" else 1e-12,
        **kw,
    )
    return Solution(
        sol.x,
        sol.fun,
        nfev + int(sol.nfev),
        bool(sol.success),
        f"scipy.optimize.least_squares({method}) after Gauss-Newton stalled: {sol.message}",
    )


def solve_batch(
    cost, normal, x0, sizes, max_iter: int = 100, rtol: float = RTOL
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`solve`'s least-squares iteration run on k independent problems in lock-step.

    ``x0`` (k × p) the starts; ``cost(x)`` the k sums of squared residuals at the rows of
    ``x``; ``normal(x)`` the k normal equations (Jᵀ J, Jᵀ r), shapes (k, p, p) and (k, p);
    ``sizes`` the k residual counts. Each problem takes the steps, step halvings and
    stopping rule :func:`solve` would give it, so Python's overhead is paid once per
    iteration for all k. Returns (x, converged): a problem whose Gauss–Newton does not
    converge (singular or non-finite step, no decrease, ``max_iter``) is left at its
    start with ``converged`` False, for the caller to hand to :func:`solve`.
    """
    x = np.array(x0, dtype=float)
    k = x.shape[0]
    c = cost(x)
    floor = ATOL * np.sqrt(np.asarray(sizes, dtype=float))
    active = np.ones(k, dtype=bool)
    converged = np.zeros(k, dtype=bool)
    for _ in range(max_iter):
        if not active.any():
            break
        N, g = normal(x)
        try:
            step = np.linalg.solve(N, g[..., None])[..., 0]
        except np.linalg.LinAlgError:
            break
        active &= np.all(np.isfinite(step), axis=1)
        change = np.sqrt(np.maximum(np.einsum("kp,kpq,kq->k", step, N, step), 0.0))
        done = active & (change <= rtol * np.sqrt(c) + floor)
        converged |= done
        active &= ~done
        t = np.where(active, 1.0, 0.0)
        pending = active.copy()
        trial, c_new = x.copy(), c.copy()
        while pending.any():
            trial[pending] = x[pending] - t[pending, None] * step[pending]
            c_try = cost(trial)
            accepted = pending & (c_try <= c * (1.0 + 1e-12))
            c_new[accepted] = c_try[accepted]
            pending &= ~accepted
            t[pending] *= 0.5
            stalled = pending & (t <= 1e-6)
            active &= ~stalled
            pending &= ~stalled
        x[active], c[active] = trial[active], c_new[active]
    x[~converged] = np.asarray(x0, dtype=float)[~converged]
    return x, converged
