"""Identification of the hexapod's parameters from measured poses.

**Which method, and why.** Two classical formulations were read: the inverse-kinematic
residuals of Zhuang, Yan & Masory (1998) — per pose, the six leg lengths implied by the
measured platform pose minus the commanded ones, :mod:`calflow_hexapod.models.loop` — and the
implicit-loop method of Wampler, Hollerbach & Arai (1995, IEEE Trans. Robot. Autom. 11(5))
— every loop of the mechanism written as implicit closure equations f(y_k, φ) = 0 in which
*all* measured quantities y_k carry error, solved as a generalised least squares with the
equations of pose k weighted by their linearised covariance C_k = (∂f/∂y) Σ_y (∂f/∂y)ᵀ.

calflow uses the inverse-kinematic residuals *as* the closure equations of the implicit-loop
method: the residual needs no forward kinematics, is nearly linear in the joint parameters
and touches one leg's parameters per equation, which makes 1 000 poses a few milliseconds
of Gauss–Newton; plain least squares on it, as Zhuang et al. do, is however not efficient and
its σ are wrong, because the six residuals of a pose all carry the same measured-pose error
(correlated, and in µm of leg length for errors given in µm and degree). Weighting each pose
by C_k = A_k Σ_M A_kᵀ + σ_λ² I (A_k = ∂r_k/∂M_k, Σ_M the instrument's per-axis variances,
σ_λ the legs' own noise) is Wampler et al.'s error allocation: the fit is then the maximum
likelihood estimate for Gaussian errors, its covariance (J̃ᵀ J̃)⁻¹ (J̃ the whitened
Jacobian) is the Cramér–Rao bound, and χ²/dof of the whitened residuals is 1 when the
model leaves only noise — the adequacy test. A_k depends on φ (the lever arms from the
measured target to the joints), so C_k is recomputed at the estimate and the fit repeated
until the weights settle, as the implicit-loop method linearises at the current estimate.

Gauss–Newton, robust losses and outlier rejection are the core's
(:mod:`calflow.identification.gauss_newton`, :mod:`calflow.identification.robust`); the
identifiable subset of the free parameters comes from the core's QR analysis
(:func:`calflow.identification.diagnostics.identifiability`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from calflow.errors import CalflowError
from calflow.identification import gauss_newton
from calflow.identification.diagnostics import identifiability
from calflow.identification.robust import Robust, mad_sigma, outliers
from calflow_hexapod.models import kinematics
from calflow_hexapod.models.geometry import AXES, Geometry
from calflow_hexapod.models.ladder import LADDER, NAMES, Parameters
from calflow_hexapod.models.loop import closure

#: Default instrument noise per axis (µm for x y z, degree for u v w) when none is given:
#: 1 µm weighs as much as 10⁻⁴ degree (1.7 µrad). Pass the instrument's own σ: their ratio
#: sets the weights, and with it the efficiency of the fit and the truth of its σ.
SIGMA_POSE = (1.0, 1.0, 1.0, 1e-4, 1e-4, 1e-4)
#: Relative tolerance of the QR analysis: |R_kk| below it, relative to the largest, is zero.
QR_RTOL = 1e-8
#: The loop covariances C_k are recomputed at the estimate and the fit repeated (at most
#: REWEIGHT times) until they change by less than WEIGHT_RTOL of their largest element.
REWEIGHT = 3
WEIGHT_RTOL = 1e-3
#: ... the first fit, on COARSE_POSES of the poses (spread over the run), stops at this coarser
#: tolerance: the weights and the start of the full fit only need φ to a fraction of σ.
COARSE_RTOL = 1e-3
COARSE_POSES = 200
#: Gauss–Newton stops when a step changes the whitened residuals by less than this fraction of
#: their norm (≈ √(6n) σ, so 10⁻⁶ of it moves no parameter by 10⁻⁴ σ). Smaller is not
#: verifiable: ‖P p_i − b_i‖ of 10⁵ µm legs, whitened by leg-space σ of 10 nm, carries
#: rounding of 10⁻⁹ per residual, and a step whose predicted decrease is below the cost's
#: rounding fails the core's line search and falls back to scipy.
RTOL = 1e-6
#: The loop covariances C_k are recomputed at the estimate and the fit repeated (at most
#: REWEIGHT times) until they change by less than WEIGHT_RTOL of their largest element.
REWEIGHT = 3
WEIGHT_RTOL = 1e-3
#: ... the first fit, on COARSE_POSES of the poses (spread over the run), stops at this coarser
#: tolerance: the weights and the start of the full fit only need φ to a fraction of σ.
COARSE_RTOL = 1e-3
COARSE_POSES = 200


@dataclass(frozen=True)
class Identification:
    """Result of :func:`identify`.

    ``free``: the identified parameters (the requested ones less ``dropped``, the combinations
    the QR analysis found not identifiable, which keep their ``initial`` value); ``std``,
    ``correlation``, ``covariance`` of the free parameters (µm, degree, 1, 1/K), scaled by
    ``chi2_dof``; ``chi2_dof``: the whitened residuals' mean square per degree of freedom
    (1 when the residuals are the stated noise); ``residual_rms_um``: RMS of the leg-length
    residuals r; ``rejected``: indices of the input poses rejected as outliers; ``jacobian``:
    the whitened ∂r̃/∂φ of the free parameters at the estimate (6 n_poses × free, 1 per
    parameter unit), for the core's observability indices
    (:func:`calflow.identification.diagnostics.observability`).
    """

    parameters: Parameters
    free: tuple[str, ...]
    std: dict[str, float]
    correlation: np.ndarray
    covariance: np.ndarray
    chi2_dof: float
    residual_rms_um: float
    n_poses: int
    dof: int
    nfev: int
    success: bool
    message: str
    dropped: tuple[str, ...] = ()
    r_diag: np.ndarray | None = None
    rejected: tuple[int, ...] = ()
    loss: str = "none"
    jacobian: np.ndarray | None = None


class _Data:
    """One identification problem: the poses, their whitening and the free columns."""

    def __init__(
        self,
        measured,
        commanded,
        zero_lengths,
        temperature,
        sigma_pose,
        sigma_leg_um,
        initial,
        jacobian: bool = True,
    ):
        self.M, self.lam, self.lam0, self.T = measured, commanded, zero_lengths, temperature
        self.sigma_pose, self.sigma_leg = np.asarray(sigma_pose, dtype=float), float(sigma_leg_um)
        self.base = initial.vector()
        _, J, A = closure(initial, measured, commanded, zero_lengths, temperature, parameters=jacobian)
        S = np.diag(self.sigma_pose**2) if self.sigma_pose.ndim == 1 else self.sigma_pose
        self.C = A @ S @ np.swapaxes(A, -1, -2) + self.sigma_leg**2 * np.eye(6)
        self.W = np.linalg.inv(np.linalg.cholesky(self.C))  # whitening, C_k⁻¹ = W_kᵀ W_k
        self.J0 = None if J is None else self.W @ J  # whitened ∂r/∂φ at the start (n, 6, 61)

    def reweighted(self, phi: Parameters) -> _Data:
        """The same poses with the loop covariances C_k at ``phi``, which becomes the start."""
        return _Data(
            self.M, self.lam, self.lam0, self.T, self.sigma_pose, self.sigma_leg, phi, jacobian=False
        )

    def subset(self, keep: np.ndarray) -> _Data:
        out = object.__new__(_Data)
        out.__dict__.update(self.__dict__)
        out.M, out.lam, out.W, out.C = self.M[keep], self.lam[keep], self.W[keep], self.C[keep]
        out.J0 = None if self.J0 is None else self.J0[keep]
        out.T = None if self.T is None else self.T[keep]
        return out

    def problem(self, cols: list[int], scale: np.ndarray):
        """fun, jac over x = (φ_free − φ₀_free) · scale (whitened residuals, dimensionless).

        ``jac`` writes into buffers of its own, so its result holds until its next call: a
        few-MB Jacobian allocated afresh at every iteration costs more in page faults than
        it takes to compute."""
        start = self.base[cols]
        n = len(self.M)
        J, WJ = np.zeros((n, 6, len(NAMES))), np.empty((n, 6, len(NAMES)))
        out = np.empty((n, 6, len(cols)))
        index = np.asarray(cols)

        def params(x):
            phi = self.base.copy()
            phi[cols] = start + x / scale
            return Parameters.from_vector(phi)

        def fun(x):
            r = closure(params(x), self.M, self.lam, self.lam0, self.T, derivatives=False)
            return (self.W @ r[..., None]).ravel()

        def jac(x):
            closure(params(x), self.M, self.lam, self.lam0, self.T, measurement=False, out=J)
            np.matmul(self.W, J, out=WJ)  # (W J)[cols]: 10 times faster than W (J[cols])
            np.take(WJ, index, axis=-1, out=out)
            np.divide(out, scale, out=out)
            return out.reshape(-1, len(cols))

        return fun, jac, params


def _validated(measured, commanded, temperature):
    M = np.asarray(measured, dtype=float)
    lam = np.asarray(commanded, dtype=float)
    if M.ndim != 2 or M.shape[1] != 6 or lam.shape != M.shape:
        raise CalflowError(
            f"identification: measured poses and commanded leg lengths must both be (n, 6), "
            f"got {M.shape} and {lam.shape}"
        )
    ok = np.all(np.isfinite(M), axis=1) & np.all(np.isfinite(lam), axis=1)
    T = None
    if temperature is not None:
        T = np.broadcast_to(np.asarray(temperature, dtype=float), ok.shape)
        ok &= np.isfinite(T)
    rows = np.flatnonzero(ok)
    return M[ok], lam[ok], None if T is None else T[ok], rows


def identifiable(
    J: np.ndarray, free, rtol: float = QR_RTOL
) -> tuple[tuple[str, ...], tuple[str, ...], np.ndarray]:
    """(kept, dropped, diag R) of the free parameters (names of :data:`NAMES`) for the stacked
    (whitened) Jacobian ``J`` (rows, 61): the core's QR analysis on the free columns scaled to
    unit norm, so that units do not decide. A column dependent on the columns before it is
    dropped; :data:`NAMES` orders the frames before the joints, so the gauge freedoms are
    fixed on joint coordinates."""
    cols = [NAMES.index(name) for name in free]
    A = np.asarray(J)[:, cols]
    norm = np.linalg.norm(A, axis=0)
    A = A / np.where(norm > 0, norm, 1.0)
    r, bad = identifiability(A, list(free), rtol)
    bad = set(bad) | {name for name, v in zip(free, norm) if v == 0}
    return tuple(n for n in free if n not in bad), tuple(n for n in free if n in bad), r


def identify(
    measured,
    commanded,
    zero_lengths,
    free=LADDER["geometric"],
    initial: Parameters | None = None,
    sigma_pose=SIGMA_POSE,
    sigma_leg_um: float = 0.0,
    temperature=None,
    robust: Robust | None = None,
    reduce: bool = True,
) -> Identification:
    """Identify the ``free`` parameters from measured target poses and commanded leg lengths.

    ``measured`` (n, 6) µm/degree: target poses in the measurement frame; ``commanded`` (n, 6)
    µm: the controller's leg lengths λ at each pose (its nominal inverse kinematics of the
    commanded pose, or its encoders); ``zero_lengths`` (6,) µm: its λ₀; ``sigma_pose`` the
    instrument's σ per axis (6,) or its covariance (6, 6) (µm, degree; e.g. of the readings
    of a repeatability run) and ``sigma_leg_um`` the legs' own σ (the weights of the implicit
    loop; their overall scale is re-estimated as ``chi2_dof``); ``temperature`` (n,) degC for
    the thermal term. Rows with a NaN are dropped. With ``reduce``, parameters the QR analysis
    finds not identifiable are fixed at ``initial`` (default: nominal geometry, identity frames)
    and listed in ``dropped``. ``robust``: screen with a robust loss, reject poses beyond
    ``reject_sigma`` robust σ on any leg, refit the rest (as the XYΘ identification does).
    """
    unknown = sorted(set(free) - set(NAMES))
    if unknown:
        raise CalflowError(f"identification: unknown parameters {unknown}; expected names of {NAMES[:3]}…")
    M, lam, T, rows = _validated(measured, commanded, temperature)
    initial = initial or Parameters.nominal()
    data = _Data(M, lam, np.asarray(zero_lengths, dtype=float), T, sigma_pose, sigma_leg_um, initial)
    free, dropped, r_diag = (
        identifiable(data.J0.reshape(-1, len(NAMES)), free) if reduce else (tuple(free), (), None)
    )
    p = len(free)
    if 6 * len(M) <= p:
        raise CalflowError(
            f"identification of {p} parameters needs more than {p / 6:.0f} valid poses, got {len(M)}"
        )
    cols = [NAMES.index(name) for name in free]
    scale = np.linalg.norm(data.J0[..., cols].reshape(-1, p), axis=0)
    scale = np.where(scale > 0, scale, 1.0)
    n = len(M)
    coarse = data if n <= 2 * COARSE_POSES else data.subset(np.linspace(0, n - 1, COARSE_POSES).astype(int))
    fun, jac, params = coarse.problem(cols, scale)
    phi = params(gauss_newton.solve(fun, jac, np.zeros(p), rtol=COARSE_RTOL).x)
    sol = None
    for _ in range(REWEIGHT):  # weights at the estimate, not at the start: a probe far off moves the levers
        again = data.reweighted(phi)
        if sol is not None and np.max(np.abs(again.C - data.C)) <= WEIGHT_RTOL * np.max(np.abs(data.C)):
            break
        data = again
        fun, jac, params = data.problem(cols, scale)
        sol = gauss_newton.solve(fun, jac, np.zeros(p), rtol=RTOL)
        phi = params(sol.x)
    keep = np.ones(len(M), dtype=bool)
    if robust is not None:
        keep, data, sol = _screen(data, cols, scale, sol, robust)
        fun, jac, params = data.problem(cols, scale)
    A = jac(sol.x).copy()
    dof = A.shape[0] - p
    chi2 = float(sol.fun @ sol.fun) / dof
    try:
        cov = chi2 * np.linalg.inv(A.T @ A) / np.outer(scale, scale)
    except np.linalg.LinAlgError:
        cov = np.full((p, p), np.nan)
    sd = np.sqrt(np.diag(cov))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(sd, sd)
    fitted = params(sol.x)
    r = closure(fitted, data.M, data.lam, data.lam0, data.T, derivatives=False)
    return Identification(
        parameters=fitted,
        free=tuple(free),
        std=dict(zip(free, (float(s) for s in sd))),
        correlation=corr,
        covariance=cov,
        chi2_dof=chi2,
        residual_rms_um=float(np.sqrt(np.mean(r**2))),
        n_poses=int(keep.sum()),
        dof=int(dof),
        nfev=int(sol.nfev),
        success=bool(sol.success),
        message=str(sol.message),
        dropped=tuple(dropped),
        r_diag=r_diag,
        rejected=tuple(int(i) for i in rows[~keep]),
        loss="none" if robust is None else robust.loss,
        jacobian=A * scale,
    )


def _screen(data: _Data, cols, scale, sol, robust: Robust):
    """A fit with ``robust.loss`` over every pose, then rounds of rejecting the poses whose
    whitened residual on any leg exceeds ``reject_sigma`` robust σ and refitting the rest by
    least squares, until the rejected set repeats. Returns (kept mask, its data, solution)."""
    fun_all = data.problem(cols, scale)[0]
    x = sol.x
    if robust.loss != "linear":
        f = robust.f_scale_sigma * max(mad_sigma(sol.fun), 1e-12)
        x = gauss_newton.solve(fun_all, data.problem(cols, scale)[1], x, robust.loss, f, rtol=1e-6).x
    keep, sub = None, data
    for _ in range(robust.max_rounds):
        r = fun_all(x).reshape(-1, 6)
        sigma = max(mad_sigma(r if keep is None else r[keep]), 1e-12)
        new = ~outliers(r, sigma, robust.reject_sigma)
        if 6 * int(new.sum()) <= 2 * len(cols):  # too little redundancy left to call a pose an outlier
            new = np.ones(len(r), dtype=bool) if keep is None else keep
        if keep is not None and np.array_equal(new, keep):
            break
        keep = new
        sub = data.subset(keep)
        fun, jac, _ = sub.problem(cols, scale)
        sol = gauss_newton.solve(fun, jac, x, rtol=RTOL)
        x = sol.x
    return keep, sub, sol


def run_inputs(run, controller: Geometry, leg_sensor: str | None = "T2", source: str = "run"):
    """(measured (n, 6), commanded leg lengths λ (n, 6), temperature (n,) or None) of a run dataset.

    ``meas_x`` … ``meas_w`` are the instrument's target poses (µm, degree); λ is the controller's
    inverse kinematics of ``cmd_x`` … ``cmd_w`` through its nominal geometry ``controller`` (about
    its pivot) — what its encoders are servoed to; the temperature is the ``temperature``
    reading of ``leg_sensor`` (degC), when the run has it. ``source`` names the file in errors.
    """
    missing = [f"{kind}_{a}" for kind in ("cmd", "meas") for a in AXES if f"{kind}_{a}" not in run]
    if missing:
        raise CalflowError(
            f"{source}: missing variables {missing}; expected cmd_* and meas_* for x y z u v w"
        )
    commands = np.stack([np.asarray(run[f"cmd_{a}"].values, dtype=float) for a in AXES], axis=-1)
    measured = np.stack([np.asarray(run[f"meas_{a}"].values, dtype=float) for a in AXES], axis=-1)
    temperature = None
    if leg_sensor is not None and "temperature" in run and "sensor" in run["temperature"].dims:
        sensors = [str(v) for v in run["sensor"].values]
        if leg_sensor in sensors:
            temperature = np.asarray(run["temperature"].sel(sensor=leg_sensor).values, dtype=float)
    return measured, kinematics.inverse(controller, commands), temperature


def prediction_rms(fit: Identification, measured, commanded, zero_lengths, temperature=None) -> float:
    """RMS (µm) of the leg-length residuals r of :mod:`calflow_hexapod.models.loop` on poses the fit did
    not see: what a richer model must lower to earn its place."""
    M, lam, T, _ = _validated(measured, commanded, temperature)
    r = closure(fit.parameters, M, lam, np.asarray(zero_lengths, dtype=float), T, derivatives=False)
    return float(np.sqrt(np.mean(r**2)))
