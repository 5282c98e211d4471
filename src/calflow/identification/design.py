"""Optimal experiment design of linear(ised) models with an unknown offset.

A reading i of m axes is y_i = J_i φ + c + e_i: J_i the m × p Jacobian (or regressor
rows) of the model at the i-th pose or position, c an offset per axis known to no one
(the initial reading of Eq. 4.27, the bias λ of Eq. 5.3), e_i of covariance σ_i² I_m. The
Fisher information of φ with c a nuisance parameter is the Schur complement

    M = Σ w_i J_iᵀ J_i − (Σ w_i J_i)ᵀ (Σ w_i J_i) / Σ w_i,   w_i = 1/σ_i²,

and M⁻¹ is the Cramér–Rao bound of any unbiased estimate (Kay 1993, Ch. 3). The design
chooses n distinct candidates to maximise a criterion of M: ``D`` (log det, default),
``A`` (−tr M⁻¹), ``MV`` (the worst parameter's variance), or the thesis's observability indices ``O1``–``O4`` (Eq. 4.10–4.13 from
the singular values σ_k = √λ_k(M)). Continuous weights by the multiplicative algorithm
(Titterington 1976 for D, Yu 2010's power 1/2 for A), each weight capped at one pose
(a repeated pose repeats its error), rounded to the n largest, then polished by Fedorov
exchange on the exact criterion. Shared by the families: XYΘ poses
(the XYΘ family's design criteria) and the nano training positions (the nano family's plans).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

CRITERIA = ("D", "A", "MV", "O1", "O2", "O3", "O4")


def information(J: np.ndarray, sigma_um: float | np.ndarray = 1.0) -> np.ndarray:
    """Fisher information (p × p) of φ from the Jacobians ``J`` (n, m, p) of n readings of m
    axes, the offset a nuisance parameter; ``sigma_um`` the σ per axis of a reading (scalar or
    per reading), in the unit of the readings."""
    w = np.broadcast_to(1.0 / np.asarray(sigma_um, dtype=float) ** 2, (J.shape[0],))
    A = np.einsum("i,iap,iaq->pq", w, J, J)
    S = np.einsum("i,iap->ap", w, J)
    return A - S.T @ S / w.sum()


def crlb_sigma(J: np.ndarray, sigma_um: float | np.ndarray = 1.0) -> np.ndarray:
    """The Cramér–Rao bound of each parameter's σ (in the parameter's unit): √diag M⁻¹; inf if singular."""
    M = information(J, sigma_um)
    try:
        return np.sqrt(np.diag(np.linalg.inv(M)))
    except np.linalg.LinAlgError:
        return np.full(M.shape[0], np.inf)


def criterion(M: np.ndarray, name: str = "D") -> np.ndarray:
    """Value of a design criterion of information matrices ``M`` (..., p, p); larger is better.

    D: log det M; A: −tr M⁻¹; MV: −max_k (M⁻¹)_kk, the worst parameter's variance (minimax
    variance; on parameters scaled by a reference design's bound, the worst ratio of σ to the
    reference squared); O1: (Π σ_k)^(1/p) / p; O2: σ_p/σ_1; O3: σ_p; O4: σ_p²/σ_1
    with σ_k = √λ_k(M) the singular values of the weighted Jacobian (Eq. 4.10–4.13).
    −inf for a singular M.
    """
    if name == "MV":
        return _minimax_variance(M)
    lam = np.linalg.eigvalsh(M)
    ok = lam[..., 0] > 1e-12 * np.maximum(lam[..., -1], 1e-300)
    lam = np.where(ok[..., None], lam, np.nan)
    s = np.sqrt(lam)
    p = M.shape[-1]
    with np.errstate(invalid="ignore", divide="ignore"):
        value = {
            "D": lambda: np.sum(np.log(lam), axis=-1),
            "A": lambda: -np.sum(1.0 / lam, axis=-1),
            "O1": lambda: np.exp(np.mean(np.log(s), axis=-1)) / p,
            "O2": lambda: s[..., 0] / s[..., -1],
            "O3": lambda: s[..., 0],
            "O4": lambda: s[..., 0] ** 2 / s[..., -1],
        }[name]()
    return np.where(ok, value, -np.inf)


def _minimax_variance(M: np.ndarray) -> np.ndarray:
    """−max_k (M⁻¹)_kk of matrices ``M`` (..., p, p); −inf where M is singular (relative
    eigenvalue below 1e-12) or indefinite. The inverse alone when every M is regular."""
    with np.errstate(all="ignore"):
        try:
            d = np.diagonal(np.linalg.inv(M), axis1=-2, axis2=-1)
        except np.linalg.LinAlgError:  # some singular: by eigenvectors, their null directions infinite
            lam, V = np.linalg.eigh(M)
            ok = lam[..., :1] > 1e-12 * np.maximum(lam[..., -1:], 1e-300)
            d = np.einsum("...kj,...j->...k", V**2, np.where(ok, 1.0 / np.where(ok, lam, 1.0), np.inf))
    ok = np.all(np.isfinite(d) & (d > 0), axis=-1)
    return np.where(ok, -np.max(np.where(ok[..., None], d, 0.0), axis=-1), -np.inf)


def _check(name: str) -> None:
    if name not in CRITERIA:
        raise ValueError(
            f"identification.design.criterion: expected one of {', '.join(CRITERIA)}, got {name!r}"
        )


def multiplicative_weights(
    J: np.ndarray, n: int, name: str = "D", fixed: np.ndarray | None = None, iterations: int = 300
) -> np.ndarray:
    """Approximate design: weights over the candidates ``J`` (N, m, p) summing to 1, each at most
    one pose's share, 1/(n − m) of the n − m poses left besides ``fixed``.

    The multiplicative algorithm w_i ← w_i (d_i / Σ w d)^δ with the sensitivity d_i =
    tr(M⁻¹ F_i) (D, δ = 1) or tr(M⁻² F_i) (A, δ = 1/2), F_i = (J_i − J̄)ᵀ(J_i − J̄) the
    derivative of the nuisance-corrected M by w_i; weights above the cap are clipped and the
    excess spread over the others. ``fixed`` (k, m, p): poses already in the design, one pose
    each. Other criteria use the D weights as a start.
    """
    N, axes, p = J.shape
    if n > N:
        raise ValueError(f"design: {n} poses asked from {N} candidates")
    m = 0 if fixed is None else fixed.shape[0]
    total = n - m  # the free share, in poses; a candidate's weight is capped at one pose
    w = np.full(N, total / N)
    delta = 0.5 if name == "A" else 1.0
    live = np.arange(N)  # weights only shrink below the cap: negligible ones are dropped
    F_A = np.einsum("iap,iaq->pq", fixed, fixed) if m else np.zeros((p, p))
    F_S = fixed.sum(0) if m else np.zeros((axes, p))
    for it in range(iterations):
        Jl, wl = J[live], w[live]
        W = wl.sum() + m
        S = np.tensordot(wl, Jl, axes=1) + F_S
        Jbar = S / W
        flat = Jl.reshape(-1, p)
        M = (flat * np.repeat(wl, axes)[:, None]).T @ flat + F_A - S.T @ S / W
        try:
            Minv = np.linalg.inv(M)
        except np.linalg.LinAlgError:
            break
        K = Minv @ Minv if name == "A" else Minv
        C = (Jl - Jbar).reshape(-1, p)
        d = np.sum((C @ K) * C, axis=1).reshape(-1, axes).sum(1)
        wl = wl * (d / max(float(wl @ d) / total, 1e-300)) ** delta
        wl *= total / wl.sum()  # A (δ < 1) does not keep the total by itself; dropped weights are 0
        for _ in range(50):  # cap at one pose per candidate, conserving the total
            over = wl > 1.0
            if not over.any():
                break
            excess = float(np.sum(wl[over] - 1.0))
            wl[over] = 1.0
            below = wl < 1.0
            wl[below] += excess * wl[below] / wl[below].sum()
        w[live] = wl
        if it % 20 == 19:
            w[live[wl < 1e-6]] = 0.0
            live = live[wl >= 1e-6]
    return w / total


def _exact_criterion(A: np.ndarray, S: np.ndarray, k: int, name: str, scale: np.ndarray) -> np.ndarray:
    M = A - np.einsum("...ap,...aq->...pq", S, S) / k
    return criterion(M * np.outer(scale, scale), name)


def exchange(
    J: np.ndarray,
    chosen: np.ndarray,
    name: str = "D",
    fixed: np.ndarray | None = None,
    scale: np.ndarray | None = None,
    max_swaps: int | None = None,
    full_pairs: int = 200_000,
) -> np.ndarray:
    """Fedorov exchange: swap a chosen candidate for an unchosen one while the exact criterion
    improves; returns the indices of the chosen candidates (distinct).

    Each step removes the chosen pose whose loss is least and adds the candidate whose gain
    is largest (both exact, nuisance included), and keeps the swap if the criterion rises;
    when that swap does not, and chosen × unchosen is at most ``full_pairs``, the best of all
    pairs is tried (Fedorov's exchange proper) before stopping.
    """
    _check(name)
    p = J.shape[-1]
    scale = np.ones(p) if scale is None else np.asarray(scale, dtype=float)
    chosen = np.array(chosen, dtype=int)
    inside = np.zeros(J.shape[0], dtype=bool)
    inside[chosen] = True
    G = np.einsum("iap,iaq->ipq", J, J)
    A = G[chosen].sum(0) + (np.einsum("iap,iaq->pq", fixed, fixed) if fixed is not None else 0.0)
    S = J[chosen].sum(0) + (fixed.sum(0) if fixed is not None else 0.0)
    k = len(chosen) + (0 if fixed is None else len(fixed))
    best = float(_exact_criterion(A, S, k, name, scale))
    for _ in range(max_swaps or 4 * len(chosen) + 20):
        out = np.flatnonzero(inside)
        loss = _exact_criterion(A - G[out], S - J[out], k - 1, name, scale)
        r = out[int(np.argmax(loss))]
        A1, S1 = A - G[r], S - J[r]
        cand = np.flatnonzero(~inside)
        if cand.size == 0:  # every candidate chosen: nothing to exchange
            break
        gain = _exact_criterion(A1 + G[cand], S1 + J[cand], k, name, scale)
        a = cand[int(np.argmax(gain))]
        value = float(np.max(gain))
        if not value > best + 1e-12 * max(1.0, abs(best)) or a == r:
            if out.size * cand.size > full_pairs:
                break
            # the full exchange: every chosen pose against its best replacement (a saturated
            # design, n = p + 1, loses rank whichever pose goes, so the least loss says nothing)
            value, r, a = _best_pair(A, S, G, J, out, cand, k, name, scale)
            if not value > best + 1e-12 * max(1.0, abs(best)):
                break
            A1, S1 = A - G[r], S - J[r]
        inside[r], inside[a] = False, True
        A, S, best = A1 + G[a], S1 + J[a], value
    return np.flatnonzero(inside)


def _best_pair(A, S, G, J, out, cand, k, name, scale) -> tuple[float, int, int]:
    """The swap (value, removed, added) of largest exact criterion over all chosen × unchosen pairs."""
    best = (-np.inf, int(out[0]), int(cand[0]))
    for r in out:
        gain = _exact_criterion(A - G[r] + G[cand], S - J[r] + J[cand], k, name, scale)
        j = int(np.argmax(gain))
        if gain[j] > best[0]:
            best = (float(gain[j]), int(r), int(cand[j]))
    return best


@dataclass(frozen=True)
class Design:
    """An exact design: the chosen candidates' indices, its information and bound."""

    index: np.ndarray
    information: np.ndarray  # p × p, for σ = 1 per axis
    criterion: str
    value: float


def optimal_design(
    J: np.ndarray, n: int, name: str = "D", fixed: np.ndarray | None = None, scale: np.ndarray | None = None
) -> Design:
    """n distinct candidates of ``J`` (N, m, p) maximising the criterion (with ``fixed`` poses).

    ``scale`` (p): the parameters' reference σ, making A and O2–O4 unit-free.
    """
    _check(name)
    m = 0 if fixed is None else len(fixed)
    if n - m < 1:
        raise ValueError(f"design: {n} poses leave none to choose besides the {m} fixed ones")
    scale = np.ones(J.shape[-1]) if scale is None else np.asarray(scale, dtype=float)
    w = multiplicative_weights(
        J * scale, n, "A" if name == "A" else "D", None if fixed is None else fixed * scale
    )
    start = np.argsort(-w, kind="stable")[: n - m]  # rounding: the n − m largest weights
    index = exchange(J, start, name, fixed, scale)
    M = information(J[index] if fixed is None else np.concatenate([fixed, J[index]]))
    return Design(index, M, name, float(criterion(M * np.outer(scale, scale), name)))


def latin_hypercube(rng: np.random.Generator, n: int, lo, hi) -> np.ndarray:
    """``n`` points (n, d) in the box [lo, hi]: each axis cut in n strata, one point in each
    (McKay et al. 1979) — an even cover of every coordinate's range from the generator ``rng``."""
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    u = (np.column_stack([rng.permutation(n) for _ in range(lo.size)]) + rng.random((n, lo.size))) / max(n, 1)
    return lo + (hi - lo) * u


def space_filling(pool: np.ndarray, m: int, lo, hi, start: str = "centre") -> np.ndarray:
    """Indices of ``m`` pool poses spread over the box (greedy maximin in the unit cube), the
    first nearest the box's centre or (``start="corner"``) its lower corner — from a corner
    the first points are the box's extremes (in 1-D: both ends, then the middle, …)."""
    if m <= 0:
        return np.zeros(0, dtype=int)
    u = (pool - np.asarray(lo)) / np.maximum(np.asarray(hi) - np.asarray(lo), 1e-12)
    chosen = [int(np.argmin(np.sum((u - (0.5 if start == "centre" else 0.0)) ** 2, axis=1)))]
    dist = np.sum((u - u[chosen[0]]) ** 2, axis=1)
    for _ in range(m - 1):
        k = int(np.argmax(dist))
        chosen.append(k)
        dist = np.minimum(dist, np.sum((u - u[k]) ** 2, axis=1))
    return np.array(chosen)
