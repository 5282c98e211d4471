"""Identifiability (Sec. 4.2.3, QR of the Jacobian) and observability (Eq. 4.10–4.13)."""

from __future__ import annotations

import numpy as np


def identifiability(J: np.ndarray, names, rtol: float = 1e-10) -> tuple[np.ndarray, list[str]]:
    """diag(R) of the QR decomposition J = QR (Sec. 4.2.3) and the non-identifiable names.

    A parameter is not identifiable when its |R_kk| is zero relative to the largest,
    below ``rtol`` (exact zeros do not survive floating point).
    """
    r = np.diag(np.linalg.qr(np.asarray(J, dtype=float), mode="r"))
    scale = np.max(np.abs(r)) if r.size else 0.0
    bad = [name for name, value in zip(names, r) if not scale or abs(value) <= rtol * scale]
    return r, bad


def observability(J: np.ndarray) -> dict[str, float]:
    """Observability indices O1–O4 of Eq. (4.10)–(4.13) from the singular values of J.

    O1 = (σ1 σ2 ⋯ σm)^(1/m) / m (the m-th root, Eq. 4.10); O2 = σm/σ1; O3 = σm;
    O4 = σm²/σ1 (noise amplification index).
    """
    s = np.linalg.svd(np.asarray(J, dtype=float), compute_uv=False)
    m = s.size
    if m == 0 or s[0] == 0:
        return {"O1": 0.0, "O2": 0.0, "O3": 0.0, "O4": 0.0}
    with np.errstate(divide="ignore"):
        log_mean = np.mean(np.log(s)) if np.all(s > 0) else -np.inf
    return {
        "O1": float(np.exp(log_mean) / m),
        "O2": float(s[-1] / s[0]),
        "O3": float(s[-1]),
        "O4": float(s[-1] ** 2 / s[0]),
    }
