"""Loop-closure residuals of the hexapod and their derivatives.

For pose k and leg i the inverse-kinematic residual of Zhuang, Yan & Masory (1998, "Calibration
of Stewart platforms and other parallel manipulators by minimizing inverse kinematic
residuals", J. Robotic Systems 15(7)) is

    r_ki(φ) = ‖P_k p_i − b_i‖ − l_ki,    P_k = F M_k G⁻¹,

the length leg i must have for the platform to be where the instrument saw it, minus the
length the model says it has (:class:`calflow_hexapod.models.ladder.Parameters`): no forward
kinematics, six scalar equations per pose, each touching only its own leg's joint
parameters. :func:`closure` returns r (n, 6) µm, its Jacobian ∂r/∂φ (n, 6, 61) over every
parameter of :data:`calflow_hexapod.models.ladder.NAMES`, and ∂r/∂M (n, 6, 6), the derivative with
respect to the measured pose, with which the implicit-loop method of Wampler, Hollerbach &
Arai (1995) weights each pose's six equations by the noise of the measurement they carry.
All derivatives are analytic; angles in degree.
"""

from __future__ import annotations

import numpy as np

from calflow_hexapod.models.geometry import rotation, rotation_derivatives
from calflow_hexapod.models.ladder import NAMES, T_REF_DEGC, Parameters

N_PARAMETERS = len(NAMES)


def closure(
    phi: Parameters,
    measured,
    commanded,
    zero_lengths,
    temperature=None,
    derivatives: bool = True,
    measurement: bool = True,
    parameters: bool = True,
    out: np.ndarray | None = None,
):
    """r (n, 6) µm and, with ``derivatives``, ∂r/∂φ (n, 6, 61; None without ``parameters``) and
    (with ``measurement``) ∂r/∂M (n, 6, 6). ``out``: an array (n, 6, 61) to write ∂r/∂φ into,
    zero where ∂r/∂φ is structurally zero (as a previous call leaves it).

    ``measured`` (n, 6): target poses M_k in the measurement frame (µm, degree, the C-887
    convention about the target's origin); ``commanded`` (n, 6): the controller's leg lengths
    λ_k (µm); ``zero_lengths`` (6,): its λ₀; ``temperature`` (n,) degC or None.
    """
    M = np.asarray(measured, dtype=float)
    lam = np.asarray(commanded, dtype=float)
    n = M.shape[0]
    RF = rotation(*phi.frame[3:])
    RG = rotation(*phi.tool[3:])
    RM = rotation(M[:, 3], M[:, 4], M[:, 5])
    z = (phi.platform - phi.tool[:3]) @ RG  # G⁻¹ p_i = R_Gᵀ (p_i − t_G), (6, 3)
    y = z @ np.swapaxes(RM, -1, -2) + M[:, None, :3]  # M_k G⁻¹ p_i
    x = y @ RF.T + phi.frame[:3]  # P_k p_i in the work frame
    d = x - phi.base
    rho = np.linalg.norm(d, axis=-1)
    dT = np.zeros(n) if temperature is None else np.asarray(temperature, dtype=float) - T_REF_DEGC
    r = rho - phi.leg_lengths(lam, zero_lengths, dT + T_REF_DEGC)
    if not derivatives:
        return r
    u = d / rho[..., None]  # unit leg vectors n_ki
    uF = u @ RF  # n̂ᵀ R_F
    uFM = uF @ RM  # n̂ᵀ R_F R_M
    J = _parameter_jacobian(phi, lam, zero_lengths, dT, y, u, uFM, RG, out) if parameters else None
    if not measurement:
        return r, J
    A = np.empty((n, 6, 6))
    A[..., :3] = uF
    dRM = rotation_derivatives(M[:, 3], M[:, 4], M[:, 5])  # (3, n, 3, 3)
    A[..., 3:] = np.moveaxis(_dot(uF, z @ np.swapaxes(dRM, -1, -2)), 0, -1)
    return r, J, A


def _parameter_jacobian(phi: Parameters, lam, zero_lengths, dT, y, u, uFM, RG, out=None) -> np.ndarray:
    """∂r/∂φ (n, 6, 61) from the unit leg vectors u, y = M_k G⁻¹ p_i and n̂ᵀ R_F R_M."""
    n = u.shape[0]
    uP = uFM @ RG.T  # n̂ᵀ R_P, R_P = R_F R_M R_Gᵀ
    J = np.zeros((n, 6, N_PARAMETERS)) if out is None else out
    J[..., 0:3] = u
    J[..., 3:6] = np.moveaxis(
        _dot(u, y @ np.swapaxes(rotation_derivatives(*phi.frame[3:]), -1, -2)[:, None]), 0, -1
    )
    J[..., 6:9] = -uP
    arm = phi.platform - phi.tool[:3]
    J[..., 9:12] = np.moveaxis(_dot(uFM, (arm @ rotation_derivatives(*phi.tool[3:]))[:, None]), 0, -1)
    legs = np.arange(6)
    for a in range(3):
        J[:, legs, 12 + 3 * legs + a] = -u[..., a]
        J[:, legs, 30 + 3 * legs + a] = uP[..., a]
    J[:, legs, 48 + legs] = -1.0
    J[:, legs, 54 + legs] = -(lam - zero_lengths)
    J[..., 60] = -lam * dT[:, None]
    return J


def _dot(a, b):
    """Σ_a a[..., a] b[..., a] over the last axis, broadcast."""
    return (a * b).sum(axis=-1)
