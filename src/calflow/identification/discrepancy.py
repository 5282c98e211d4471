"""Design for a model that is not exact: expected integrated squared prediction error under a
Gaussian-process discrepancy.

A reading i of m axes is y_i = J_i φ + c + δ(q_i) + e_i: J_i the m × p Jacobian at pose
q_i, c an unknown offset per axis, e_i of covariance σ² I_m, and δ what the model does not
represent — a Gaussian process of covariance k(q, q') I_m (Kennedy & O'Hagan 2001; Box &
Draper 1959 for the bias of a fitted polynomial). With the augmented rows
Ĵ_i = [J_i, I_m] (the offset a parameter), A = Σ Ĵ_iᵀ Ĵ_i over the design, the least-squares
fit is off by A⁻¹ Σ Ĵ_iᵀ (δ_i + e_i), and the model's prediction at a pose t of the
workspace, where the frame is anchored at a home pose q₀ (J(q₀) = 0, so δ(q₀) is
subtracted: δ̃(q) = δ(q) − δ(q₀), of covariance k̃), errs by

    r_t = δ̃_t − T_t A⁻¹ Σ_i Ĵ_iᵀ (δ̃_i + e_i),   T_t = [J_t, 0].

Averaged over test poses t (the workspace measure the model will serve) and over δ and e:

    IMSE = k̄ − 2 tr(A⁻¹ G) + tr(A⁻¹ B A⁻¹ W) + σ² tr(A⁻¹ W)   (µm²)

with W = mean_t T_tᵀ T_t, G = Σ_i Ĵ_iᵀ ḡ_i, ḡ_i = mean_t k̃(q_i, t) T_t,
B = Σ_ij k̃(q_i, q_j) Ĵ_iᵀ Ĵ_j and k̄ = m mean_t k̃(t, t). The last term is the variance
(I-optimality); the others are the expected squared bias, zero when δ is in the span of the
model (δ̃ = J a) and growing with the discrepancy's amplitude. The exchange here swaps poses
to lower it, optionally keeping every parameter's Cramér–Rao σ within a bound.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Discrepancy:
    """An additive squared-exponential kernel over the joints, the same for every reading axis:
    k(q, q') = Σ_j s_j² exp(−(q_j − q'_j)² / (2 ℓ_j²)) — ``amplitude`` s_j in the readings' unit
    (µm), ``length`` ℓ_j in the joints' units (µm, degree); a zero amplitude drops the joint."""

    amplitude: tuple[float, ...]
    length: tuple[float, ...]

    def __call__(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """k(a_i, b_j) for poses ``a`` (n, d) and ``b`` (k, d): (n, k)."""
        a, b = np.atleast_2d(a), np.atleast_2d(b)
        out = np.zeros((len(a), len(b)))
        for j, (s, ell) in enumerate(zip(self.amplitude, self.length)):
            if s > 0:
                out += s**2 * np.exp(-0.5 * ((a[:, j, None] - b[None, :, j]) / ell) ** 2)
        return out

    def diag(self, a: np.ndarray) -> np.ndarray:
        """k(a_i, a_i) (n): Σ_j s_j²."""
        return np.full(len(np.atleast_2d(a)), float(np.sum(np.square(self.amplitude))))


def anchored(kernel, home: np.ndarray):
    """k̃(a, b) = k(a, b) − k(a, q₀) − k(q₀, b) + k(q₀, q₀): the covariance of δ(q) − δ(q₀)."""
    h = np.atleast_2d(np.asarray(home, dtype=float))

    def k(a, b):
        return kernel(a, b) - kernel(a, h) - kernel(h, b) + kernel(h, h)

    return k


def augmented(J: np.ndarray) -> np.ndarray:
    """Ĵ = [J, I_m] (n, m, p + m): the offset of each axis as a parameter."""
    n, m, _ = J.shape
    return np.concatenate([J, np.broadcast_to(np.eye(m), (n, m, m))], axis=2)


@dataclass(frozen=True)
class Workspace:
    """The test side of the criterion: W, the per-candidate ḡ_i (N, m, P) and k̄ (µm²)."""

    W: np.ndarray
    g: np.ndarray
    kbar: float


def workspace(J_test: np.ndarray, K_cand_test: np.ndarray, k_test_diag: np.ndarray) -> Workspace:
    """From the test poses' Jacobians ``J_test`` (T, m, p), k̃(candidate, test) (N, T) and
    k̃(t, t) (T): W, ḡ and k̄."""
    T_aug = np.concatenate([J_test, np.zeros(J_test.shape[:2] + (J_test.shape[1],))], axis=2)
    W = np.einsum("tap,taq->pq", T_aug, T_aug) / len(J_test)
    g = np.einsum("nt,tap->nap", K_cand_test, T_aug) / len(J_test)
    return Workspace(W, g, float(J_test.shape[1] * np.mean(k_test_diag)))


def imse(A: np.ndarray, G: np.ndarray, B: np.ndarray, ws: Workspace, sigma_um: float) -> np.ndarray:
    """IMSE (µm²) of designs given their sums A, G, B (..., P, P); +inf where A is singular."""
    with np.errstate(all="ignore"):
        Ai = _inverse(A)
        bias = -2.0 * np.einsum("...pq,...qp->...", Ai, G) + np.einsum("...pq,qp->...", Ai @ B @ Ai, ws.W)
        value = ws.kbar + bias + sigma_um**2 * np.einsum("...pq,qp->...", Ai, ws.W)
    return np.where(np.isfinite(value), value, np.inf)


def _inverse(A: np.ndarray) -> np.ndarray:
    """Inverses of matrices ``A`` (..., P, P); NaN for the singular ones (which then count as
    +inf IMSE or infeasible) — one by one only when the batch holds a singular matrix."""
    try:
        return np.linalg.inv(A)
    except np.linalg.LinAlgError:
        flat = A.reshape(-1, *A.shape[-2:])
        out = np.full(flat.shape, np.nan)
        for i, a in enumerate(flat):
            try:
                out[i] = np.linalg.inv(a)
            except np.linalg.LinAlgError:
                pass
        return out.reshape(A.shape)


def design_sums(Jh: np.ndarray, K: np.ndarray, ws: Workspace, index: np.ndarray):
    """A, G, B (P × P) of the design ``index`` from augmented Jacobians ``Jh`` (N, m, P) and the
    anchored kernel between candidates ``K`` (callable on indices: K(i, j) → matrix)."""
    Ji = Jh[index]
    A = np.einsum("iap,iaq->pq", Ji, Ji)
    G = np.einsum("iap,iaq->pq", Ji, ws.g[index])
    U = np.einsum("ij,jaq->iaq", K(index, index), Ji)
    return A, G, np.einsum("iap,iaq->pq", Ji, U)


def expected_error(
    J: np.ndarray,
    q: np.ndarray,
    J_test: np.ndarray,
    q_test: np.ndarray,
    kernel,
    home: np.ndarray,
    sigma_um: float,
) -> dict:
    """The criterion of one design: poses ``q`` (n, d) with Jacobians ``J`` (n, m, p), test poses
    ``q_test`` (T, d) with ``J_test``, ``kernel`` k(a, b) → (len a, len b), frame anchored at
    ``home``. Returns ``imse``, ``variance`` and ``bias`` (µm², bias = imse − variance)."""
    kt = anchored(kernel, home)
    ws = workspace(J_test, kt(q, q_test), anchored_diag(kernel, home, q_test))
    Jh = augmented(J)
    Kqq = kt(q, q)
    A, G, B = design_sums(Jh, lambda i, j: Kqq[np.ix_(i, j)], ws, np.arange(len(q)))
    total = float(imse(A, G, B, ws, sigma_um))
    variance = float(imse(A, np.zeros_like(G), np.zeros_like(B), Workspace(ws.W, ws.g, 0.0), sigma_um))
    return {"imse": total, "variance": variance, "bias": total - variance}


def exchange(
    J: np.ndarray,
    q: np.ndarray,
    chosen: np.ndarray,
    J_test: np.ndarray,
    q_test: np.ndarray,
    kernel,
    home: np.ndarray,
    sigma_um: float,
    sigma_max: np.ndarray | None = None,
    keep: np.ndarray | None = None,
    max_swaps: int | None = None,
) -> np.ndarray:
    """Swap chosen candidates (indices into ``q`` (N, d), Jacobians ``J`` (N, m, p)) for others
    while the IMSE falls: each step adds the candidate that lowers it most, then drops the pose
    whose removal raises it least (the added one's information gives the σ bound room to
    move), kept if the IMSE fell. ``sigma_max`` (p): every parameter's
    Cramér–Rao σ (noise ``sigma_um``) must stay at most this after the swap; ``keep``: chosen
    indices never swapped out (a home reading the plan always makes). Returns the indices.

    Cost per swap O(N (m P² + d)) with the running sums U_c = Σ_design k̃(q_c, q_i) Ĵ_i.
    """
    kt = anchored(kernel, home)
    ws = workspace(J_test, kt(q, q_test), anchored_diag(kernel, home, q_test))
    Jh = augmented(J)
    p = J.shape[2]
    F = np.einsum("nap,naq->npq", Jh, Jh)
    Gc = np.einsum("nap,naq->npq", Jh, ws.g)
    kdiag = anchored_diag(kernel, home, q)
    inside = np.zeros(len(q), dtype=bool)
    inside[np.asarray(chosen, dtype=int)] = True
    removable = np.ones(len(q), dtype=bool)
    if keep is not None:
        removable[np.asarray(keep, dtype=int)] = False
    idx = np.flatnonzero(inside)
    U = kt(q, q[idx]) @ Jh[idx].reshape(len(idx), -1)
    U = U.reshape(len(q), *Jh.shape[1:])  # U_c = Σ_design k̃(c, i) Ĵ_i
    A, G = F[idx].sum(0), Gc[idx].sum(0)
    B = np.einsum("iap,iaq->pq", Jh[idx], U[idx])
    best = float(imse(A, G, B, ws, sigma_um))
    limit = None if sigma_max is None else (np.asarray(sigma_max, dtype=float) / sigma_um) ** 2

    def feasible(As):
        if limit is None:
            return np.ones(As.shape[0], dtype=bool)
        with np.errstate(all="ignore"):
            d = np.diagonal(_inverse(As), axis1=1, axis2=2)[:, :p]
        return np.all(d <= limit * (1 + 1e-9), axis=1) & np.all(d > 0, axis=1)  # NaN: infeasible

    for _ in range(max_swaps or 4 * len(idx) + 20):
        cand = np.flatnonzero(~inside)  # add first: the design gains information ...
        JU = np.einsum("iap,iaq->ipq", Jh[cand], U[cand])
        B_a = B + JU + JU.transpose(0, 2, 1) + kdiag[cand, None, None] * F[cand]
        k = int(np.argmin(imse(A + F[cand], G + Gc[cand], B_a, ws, sigma_um)))
        a = cand[k]
        A1, G1, B1 = A + F[a], G + Gc[a], B_a[k]
        out = np.flatnonzero(inside & removable)  # ... then loses the pose that costs least, σ kept
        U1 = U[out] + kt(q[out], q[a : a + 1])[:, 0, None, None] * Jh[a]
        JU = np.einsum("iap,iaq->ipq", Jh[out], U1)
        A2 = A1 - F[out]
        B2 = B1 - JU - JU.transpose(0, 2, 1) + kdiag[out, None, None] * F[out]
        loss = imse(A2, G1 - Gc[out], B2, ws, sigma_um)
        loss = np.where(feasible(A2), loss, np.inf)
        j = int(np.argmin(loss))
        r = out[j]
        if not loss[j] < best - 1e-9 * max(1.0, abs(best)):
            break
        inside[r], inside[a] = False, True
        U += kt(q, q[a : a + 1])[:, 0, None, None] * Jh[a] - kt(q, q[r : r + 1])[:, 0, None, None] * Jh[r]
        JUr = Jh[r].T @ U1[j]
        A, G, B, best = A2[j], G1 - Gc[r], B1 - JUr - JUr.T + kdiag[r] * F[r], float(loss[j])
    return np.flatnonzero(inside)


def anchored_diag(kernel, home: np.ndarray, q: np.ndarray) -> np.ndarray:
    """k̃(q_c, q_c) = k(q_c, q_c) − 2 k(q_c, q₀) + k(q₀, q₀) for every pose of ``q`` (N); the
    kernel's own ``diag`` when it has one (a :class:`Discrepancy`), else one call per pose."""
    h = np.atleast_2d(np.asarray(home, dtype=float))
    own = kernel.diag(q) if hasattr(kernel, "diag") else np.array([kernel(x[None], x[None])[0, 0] for x in q])
    return own - 2.0 * kernel(q, h)[:, 0] + kernel(h, h)[0, 0]
