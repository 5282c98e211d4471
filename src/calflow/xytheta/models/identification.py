"""Nonlinear least squares identification of the XYΘ parameters (Sec. 4.5.4).

The thesis uses MATLAB's ``lsqnonlin`` on the pose differences of Eq. (4.28)–(4.30); calflow
fits the readings of Eq. (4.28) with the initial reading as a nuisance parameter — the
generalised least squares of the same differences — so that σ reaches the Cramér–Rao
bound at linear cost: Gauss–Newton with an analytic Jacobian
(:mod:`calflow.identification.gauss_newton`; :func:`scipy.optimize.least_squares` as its
fallback).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calflow.identification import gauss_newton
from calflow.identification.design import information
from calflow.identification.robust import Robust, mad_sigma, outliers
from calflow.xytheta.models import cost
from calflow.xytheta.models.kinematics import PARAMETER_NAMES, Parameters

#: Smallest noise scale (µm) the outlier screening uses: below any sensor's resolution, so
#: rounding-level residuals of exact data are never called outliers.
SIGMA_FLOOR_UM = 1e-6


#: Relative tolerance of the robust screening fit: it only has to tell outliers (many σ)
#: from the rest; the estimate is the least-squares refit on the kept readings.
SCREEN_RTOL = 1e-6


@dataclass(frozen=True)
class Identification:
    """Result of an identification.

    ``std`` and ``correlation`` cover the free parameters (µm or degree); they are NaN
    where no residual degree of freedom is left. ``residual_rms_um`` is the RMS of ε of
    Eq. (4.30) (pose differences); ``sigma_um`` the noise per reading and axis the fit
    implies. ``jacobian`` is ∂ε/∂φ of Eq. (4.30) (for the identifiability and observability
    diagnostics of the thesis); ``information`` is the Fisher information per σ² of the
    free parameters with the initial reading profiled out (Jᵀ J of the centred readings).
    ``rejected`` are the indices (into the input rows) of the readings rejected as outliers.
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
    sigma_um: float = float("nan")
    information: np.ndarray | None = None
    offset_um: tuple[float, float] = (float("nan"), float("nan"))
    rejected: tuple[int, ...] = ()
    loss: str = "none"


@dataclass(frozen=True)
class CramerRao:
    """Cramér–Rao bound of the free parameters: ``information`` (Fisher, 1/unit²),
    ``covariance`` its inverse and ``std`` the bound on each σ (µm or degree)."""

    free: tuple[str, ...]
    information: np.ndarray
    covariance: np.ndarray
    std: dict[str, float]


def _columns(free) -> list[int]:
    unknown = set(free) - set(PARAMETER_NAMES)
    if unknown:
        raise ValueError(f"free parameters {sorted(unknown)} unknown; expected some of {PARAMETER_NAMES}")
    return [PARAMETER_NAMES.index(name) for name in free] + [4, 5]  # + the initial reading x_m0, y_m0


def _inverse(A: np.ndarray) -> np.ndarray | None:
    try:
        return np.linalg.inv(A)
    except np.linalg.LinAlgError:
        return None


def profiled_information(J: np.ndarray, n_free: int) -> np.ndarray:
    """Fisher information per σ² of the first ``n_free`` columns of ``J`` (2n × (p + 2), rows
    x₁, y₁, x₂, …, the initial reading's columns last) with the initial reading profiled out.

    Those columns are −1 on their axis' rows (:func:`cost.reading_jacobian`), so the Schur
    complement of their block in Jᵀ J is the design's information with the offset as a
    nuisance, :func:`calflow.identification.design.information` — one formula for the bound
    before acquisition and the covariance after. Linear in the readings."""
    return information(np.asarray(J)[:, :n_free].reshape(-1, 2, n_free))


def crlb(
    parameters: Parameters, X, Y, theta, sigma_um: float, free=PARAMETER_NAMES, ex=0.0, ey=0.0
) -> CramerRao:
    """Cramér–Rao bound of the free parameters of Eq. (4.18) for the poses (X, Y µm, θ degree).

    The readings carry independent noise of ``sigma_um`` (µm) per axis and the initial
    reading (x_m0, y_m0) of Eq. (4.27) is unknown: I(φ) = Sᵀ S / σ², S the Jacobian of the
    tool points with its mean over the poses removed (the Schur complement of the
    offset). No unbiased estimator from these poses does better; :func:`identify` attains
    it when the model is the rig's. Linear in the number of poses.
    """
    X, Y, theta = (np.asarray(a, dtype=float) for a in (X, Y, theta))
    idx = _columns(free)
    J = cost.reading_jacobian(
        parameters, X, Y, theta, np.broadcast_to(ex, X.shape), np.broadcast_to(ey, X.shape)
    )
    info = profiled_information(J[:, idx], len(free)) / float(sigma_um) ** 2
    cov = _inverse(info)
    cov = np.full_like(info, np.nan) if cov is None else cov
    return CramerRao(tuple(free), info, cov, {name: float(np.sqrt(cov[k, k])) for k, name in enumerate(free)})


def parameter_covariance(J: np.ndarray, r: np.ndarray, n_free: int) -> tuple[np.ndarray, int, float]:
    """Covariance of the estimate, the residual dof and σ̂ (µm) from the reading Jacobian
    (2n × (p + 2), the initial reading last) and the residuals r of :func:`cost.reading_residuals`.

    With independent readings (the nuisance formulation), Cov = σ̂² (Sᵀ S)⁻¹ with S the
    offset-profiled Jacobian and σ̂² = rᵀ r / (2n − p − 2), unbiased. This replaces the
    sandwich over the dense 2(n−1)² difference Gram of the differenced cost. NaNs when no
    degree of freedom is left.
    """
    m = J.shape[0]
    dof = m - J.shape[1]
    nan = np.full((n_free, n_free), np.nan)
    if dof <= 0:
        return nan, dof, float("nan")
    sigma2 = float(r @ r) / dof
    inv = _inverse(profiled_information(J, n_free))
    return (nan if inv is None else sigma2 * inv), dof, float(np.sqrt(sigma2))


def _least_squares(problem, start, loss="linear", f_scale=1.0, rtol=gauss_newton.RTOL):
    """Gauss–Newton on ``problem`` = (fun, jac, normal) from :func:`_problem`."""
    fun, jac, normal = problem
    return gauss_newton.solve(fun, jac, start, loss, f_scale, rtol=rtol, normal=normal)


def _problem(readings: cost.Readings, idx: list[int], base: np.ndarray):
    """Residuals, Jacobian and normal equations of ``readings`` in the free columns ``idx``
    of (x_R, y_R, α, β, x_m0, y_m0); the others keep their value in ``base``."""
    every_column = idx == list(range(6))
    cols = np.ix_(idx, idx)

    def full(values):
        if every_column:
            return values
        phi = base.copy()
        phi[idx] = values
        return phi

    def fun(values):
        return readings.residuals(full(values))

    def jac(values):
        J = readings.jacobian(full(values))
        return J if every_column else J[:, idx]

    def normal(values, r, w):
        N, g, plain = readings.normal(full(values), r, w)
        return (N, g, plain) if every_column else (N[cols], g[idx], plain[cols])

    return fun, jac, normal


def _valid(X, Y, theta, P_mx, P_my) -> np.ndarray:
    return np.isfinite(X) & np.isfinite(Y) & np.isfinite(theta) & np.isfinite(P_mx) & np.isfinite(P_my)


def _start(initial: Parameters | None, free) -> tuple[list[int], np.ndarray]:
    """Free columns of (φ, x_m0, y_m0) and the starting vector (offset filled later)."""
    initial = initial or Parameters(x_R=0.0, y_R=0.0)
    return _columns(free), np.concatenate([initial.as_array(), [0.0, 0.0]])


def _fit(readings: cost.Readings, idx: list[int], base: np.ndarray):
    """Least-squares fit of the free columns from ``base`` (its offset started at the mean
    misfit, in place). Returns the problem and the solution."""
    problem = _problem(readings, idx, base)
    base[4:] = np.mean(problem[0](base[idx]).reshape(-1, 2), axis=0)  # start the offset at the mean misfit
    return problem, _least_squares(problem, base[idx])


def identify(
    X,
    Y,
    theta,
    P_mx,
    P_my,
    free=PARAMETER_NAMES,
    initial: Parameters | None = None,
    ex=0.0,
    ey=0.0,
    f_ax=0.0,
    f_ay=0.0,
    robust: Robust | None = None,
) -> Identification:
    """Identify the free parameters of Eq. (4.18) from measured tool points.

    ``X``, ``Y`` (µm), ``theta`` (degree) are the joint values; ``P_mx``, ``P_my`` the
    measured tool points of :func:`cost.measured_points` (µm). Parameters not in ``free``
    keep their value from ``initial``. Rows with a NaN are dropped.

    The cost is Eq. (4.28) per reading with the initial reading (x_m0, y_m0) estimated as a
    nuisance parameter: the generalised least squares of the pose differences of
    Eq. (4.29)–(4.30), efficient (σ at the Cramér–Rao bound, :func:`crlb`) where ordinary
    least squares on the differences is not, with linear cost and memory. ``robust``
    (:class:`calflow.identification.robust.Robust`) screens the readings with a robust
    loss, rejects those beyond ``reject_sigma`` robust σ and refits the rest by least
    squares; None fits every reading.
    """
    X, Y, theta, P_mx, P_my = (np.asarray(a, dtype=float) for a in (X, Y, theta, P_mx, P_my))
    ex, ey = np.broadcast_to(ex, X.shape), np.broadcast_to(ey, X.shape)
    f_ax, f_ay = np.broadcast_to(f_ax, X.shape), np.broadcast_to(f_ay, X.shape)
    ok = _valid(X, Y, theta, P_mx, P_my)
    rows = np.flatnonzero(ok)
    X, Y, theta, P_mx, P_my, ex, ey, f_ax, f_ay = (
        a[ok] for a in (X, Y, theta, P_mx, P_my, ex, ey, f_ax, f_ay)
    )
    n = len(X)
    idx, base = _start(initial, free)
    p = len(free)
    if 2 * n < p + 2 or n < 2:
        raise ValueError(
            f"identification of {p} parameters needs at least {max(2, (p + 3) // 2)} valid poses, got {n}"
        )
    readings = cost.Readings(X, Y, theta, P_mx, P_my, ex, ey, f_ax, f_ay)
    problem, sol = _fit(readings, idx, base)
    keep = np.ones(n, dtype=bool)
    if robust is not None:
        keep, problem, sol = _screen(readings, idx, base, problem, sol, robust)
    A = problem[1](sol.x)
    cov, dof, sigma = parameter_covariance(A, sol.fun, p)
    phi = base.copy()
    phi[idx] = sol.x
    phi, offset = Parameters.from_array(phi[:4]), phi[4:]
    with np.errstate(invalid="ignore", divide="ignore"):
        sd = np.sqrt(np.diag(cov))
        corr = cov / np.outer(sd, sd)
    return Identification(
        parameters=phi,
        free=tuple(free),
        std={name: float(sd[k]) for k, name in enumerate(free)},
        correlation=corr,
        covariance=cov,
        jacobian=cost.differences_of_readings(A[:, :p]),  # ∂ε/∂φ of Eq. (4.30), as cost.jacobian
        residual_rms_um=float(np.sqrt(np.mean(cost.differences_of_readings(sol.fun) ** 2))),
        n_poses=int(keep.sum()),
        dof=dof,
        nfev=int(sol.nfev),
        success=bool(sol.success),
        message=str(sol.message),
        sigma_um=sigma,
        information=profiled_information(A, p),
        offset_um=(float(offset[0]), float(offset[1])),
        rejected=tuple(int(i) for i in rows[~keep]),
        loss="none" if robust is None else robust.loss,
    )


def _screen(readings: cost.Readings, idx, base, problem, sol, robust: Robust):
    """Robust screening: a fit with ``robust.loss`` over every reading, then rounds of
    rejecting readings beyond ``reject_sigma`` robust σ and refitting the rest by least
    squares, until the rejected set repeats. Returns (kept mask, its problem, final
    least-squares solution)."""
    fun_all = problem[0]
    x = sol.x
    if robust.loss != "linear":
        scale = max(mad_sigma(sol.fun), SIGMA_FLOOR_UM)
        x = _least_squares(problem, x, robust.loss, robust.f_scale_sigma * scale, SCREEN_RTOL).x
    keep = None
    for _ in range(robust.max_rounds):
        r = fun_all(x).reshape(-1, 2)
        scale = max(mad_sigma(r if keep is None else r[keep]), SIGMA_FLOOR_UM)
        new = ~outliers(r, scale, robust.reject_sigma)
        if 2 * int(new.sum()) - len(idx) < len(idx):
            # too little redundancy left to call a reading an outlier (fewer residual degrees
            # of freedom than unknowns): reject nothing more
            new = np.ones(len(r), dtype=bool) if keep is None else keep
        if keep is not None and np.array_equal(new, keep):
            break
        keep = new
        problem = _problem(readings if keep.all() else readings.subset(keep), idx, base)
        sol = _least_squares(problem, x)
        x = sol.x
    return keep, problem, sol


def noise_sigma(eps: np.ndarray, n_poses: int, n_free: int) -> float:
    """σ̂ (µm): the noise per reading and axis that the residuals ε imply, Cov(ε) = σ² D Dᵀ.

    ``E[εᵀε] ≈ σ² (tr(D Dᵀ) − 2 p)``, tr(D Dᵀ) = 4 (n − 1) (the fit's own ``sigma_um``,
    from the independent per-reading residuals, is exact: rᵀr / (2n − p − 2)); this is
    what a model-adequacy test compares with the repeatability floor.
    """
    effective = 4.0 * (n_poses - 1) - 2.0 * n_free
    return float(np.sqrt(float(eps @ eps) / effective)) if effective > 0 else float("nan")
