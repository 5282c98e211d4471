"""Optimal design of the XYΘ identification poses (thesis Sec. 4.2.3, 4.5.4).

The measured tool point of pose i is P_m,i = P(q_i; φ) − c + e_i (Eq. 4.27 with the
initial reading c = (x_m0, y_m0) unknown), e_i of covariance σ² I₂ per axis. The Fisher
information of φ with c a nuisance parameter is the Schur complement

    M = (1/σ²) [Σ J_iᵀ J_i − (Σ J_i)ᵀ (Σ J_i) / n] = (1/σ²) Σ (J_i − J̄)ᵀ (J_i − J̄),

J_i the 2 × p Jacobian of Eq. (4.18) at the pose (:func:`calflow.xytheta.models.kinematics.forward_jacobian`);
this is the information of the pose differences of Eq. (4.29) weighted by their
correlation (GLS), and M⁻¹ is the Cramér–Rao bound of any unbiased estimate.

The design chooses n distinct poses from a candidate pool to maximise a criterion of M:
``D`` (log det, default), ``A`` (−tr M⁻¹), or the thesis's observability indices ``O1``–``O4``
(Eq. 4.10–4.13 from the singular values of the weighted Jacobian, σ_k = √λ_k(M)). The
criteria are evaluated on the information of the parameters scaled by a reference design's
bound (unit-free: A and O2–O4 would otherwise compare µm with degrees; D and O1 do not
change). Continuous weights by the multiplicative algorithm (Titterington 1976 for D,
Yu 2010's power 1/2 for A) with each weight capped at 1/n (a pose is measured once: a
repeated pose repeats its decoding error), rounded to the n largest, then polished by
Fedorov exchange on the exact criterion: the machinery shared with the nano training design
lives in :mod:`calflow.identification.design` and is re-exported here.
"""

from __future__ import annotations

import numpy as np

from calflow.identification.design import (  # noqa: F401 (the shared machinery, re-exported)
    CRITERIA,
    Design,
    criterion,
    crlb_sigma,
    exchange,
    information,
    multiplicative_weights,
    optimal_design,
)
from calflow.xytheta.models.kinematics import PARAMETER_NAMES, PARAMETER_UNITS, Parameters, forward_jacobian


def parameter_key(name: str) -> str:
    """A parameter's key with its unit, as the summary writes it: ``x_R_um``, ``alpha_deg``."""
    return f"{name}_{'um' if PARAMETER_UNITS[name] == 'um' else 'deg'}"


def pose_jacobians(q: np.ndarray, phi: Parameters, free=PARAMETER_NAMES) -> np.ndarray:
    """∂(x_P, y_P)/∂φ_free at joint poses ``q`` (n, 3: X µm, Y µm, Θ degree), shape (n, 2, p).

    Eq. (4.18); angles per degree, so the information is in µm⁻² and (µm/degree)⁻².
    """
    q = np.asarray(q, dtype=float)
    jx, jy = forward_jacobian(q[:, 0], q[:, 1], q[:, 2], phi)
    idx = [PARAMETER_NAMES.index(name) for name in free]
    return np.stack([jx[:, idx], jy[:, idx]], axis=1)
