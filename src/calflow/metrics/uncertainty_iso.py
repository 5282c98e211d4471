"""U of ISO 9283 AP and RP and of ISO 230-2 E, M, B, A, R, B̄ (:mod:`.uncertainty` for the method)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from calflow.metrics.uncertainty import (
    MAX_METHOD,
    P95,
    TRIALS,
    Draws,
    Term,
    Uncertainty,
    check_terms,
    chi_rp_factor,
    effective_count,
    gum_linear,
    largest_bounds,
    maximum_interval,
    mc_result,
    pooled_scatter,
    reading_budget,
    sigma_interval,
)

__all__ = ["iso230_2_uncertainty", "iso9283_uncertainty", "rp_factor"]


def rp_factor(ratios) -> float:
    """E[l] + 3 SD[l] of l = |(r_1 z_1, …, r_d z_d)|, z standard normal, for axis ratios r (rms 1):
    RP∞ / σ of a normal scatter whose axes differ (:func:`chi_rp_factor` when they do not).
    By a fixed sample of 200 000 draws (reproducible; relative error ~1e-3)."""
    r = np.asarray(ratios, float)
    if np.allclose(r, r[0]):
        return chi_rp_factor(r.size)
    z = np.random.default_rng(9283).standard_normal((200_000, r.size))
    length = np.linalg.norm(z * r, axis=1)
    return float(length.mean() + 3.0 * length.std())


def iso9283_uncertainty(
    command, attained: Sequence, terms: Sequence[Term] = (), origin=None, trials: int = TRIALS, seed: int = 0
) -> dict[str, Uncertainty]:
    """U of a test's AP = max_j AP_j and RP = max_j RP_j (ISO 9283, thesis Sec. 3.2.3).

    ``command``: (T, d) command poses; ``attained``: T arrays (n_j, d) of the readings at
    each (any length unit, the unit of the results and of the terms); ``origin``: (d,) the
    sensor's zero, which relative (ppm) terms scale from (default 0). AP by Monte Carlo
    (:func:`maximum_interval`); RP's measurand is RP∞ = c σ (:func:`rp_factor`) of the
    normal scatter with the per-axis σ pooled over targets, its interval exact (χ², on the
    axes' common scale). Returns ``{"accuracy", "repeatability"}``.
    """
    cmd = np.atleast_2d(np.asarray(command, float))
    T, d = cmd.shape
    if len(attained) != T:
        raise ValueError(f"{T} commands but {len(attained)} groups of readings")
    groups = [np.asarray(a, float).reshape(len(a), d) for a in attained]
    groups = [g[np.all(np.isfinite(g), axis=1)] for g in groups]
    n = np.array([len(g) for g in groups], float)
    if np.any(n < 2):
        raise ValueError("every target needs two or more valid readings")
    terms = check_terms(terms)
    dev = np.array([g.mean(axis=0) for g in groups]) - cmd
    s_axis, dof = pooled_scatter(groups)
    pos = cmd - (np.zeros(d) if origin is None else np.asarray(origin, float))
    draws = Draws(s_axis, dof, (T, d), terms, trials, seed)

    def per_target(only=None):
        return np.linalg.norm(dev[None] + draws.error(pos, n, only), axis=2)

    y = np.linalg.norm(dev, axis=1)
    full = per_target()
    lo, hi, t_eff = maximum_interval(y, full)
    parts = {"sample": per_target("sample").max(axis=1)}
    for t in draws.terms:
        parts[t.name] = per_target(t.name).max(axis=1)
    accuracy = mc_result(
        float(y.max()),
        full.max(axis=1),
        parts,
        {"sample": float(dof)},
        (lo, hi),
        MAX_METHOD.format(M=trials, t=t_eff),
    )
    accuracy.budget.update(reading_budget(terms))

    from calflow.metrics.iso9283 import iso9283

    # RP∞ of the normal scatter with the per-axis pooled σ (axes may differ: a tracker's beam
    # and transverse errors); the axes' common scale carries the uncertainty (Satterthwaite dof)
    s_iso = math.sqrt(float(np.mean(s_axis**2)))
    dof_iso = float(np.sum(s_axis**2) ** 2 / np.sum(s_axis**4 / dof)) if s_iso > 0 else float(dof * d)
    c = rp_factor(s_axis / s_iso) if s_iso > 0 else chi_rp_factor(d)
    rp_value = float(max(iso9283(cmd[j], groups[j]).rp for j in range(T)))
    lo, hi = (c * v for v in sigma_interval(s_iso, dof_iso))
    rp_draws = c * s_iso * np.sqrt(dof_iso / draws.rng.chisquare(dof_iso, size=trials))
    note = ""
    if not lo <= rp_value <= hi:
        note = (
            f"the ISO value ({rp_value:.4g}) from {int(n.min())}–{int(n.max())} cycles lies outside the interval "
            f"of the population RP (c·σ = {c * s_iso:.4g}): few cycles make l̄ + 3 S_l a poor estimate"
        )
    repeatability = mc_result(
        rp_value,
        rp_draws,
        {"sample": rp_draws},
        {"sample": dof_iso},
        (lo, hi),
        f"RP∞ = {c:.4f} σ, σ the rms over {d} axes of the scatter pooled over {T} targets "
        f"({dof_iso:.3g} dof, Satterthwaite); exact χ² interval of σ; k from Student's t at those dof",
        note,
    )
    repeatability.budget.update(reading_budget(terms))
    return {"accuracy": accuracy, "repeatability": repeatability}


def iso230_2_uncertainty(
    targets,
    forward,
    backward,
    terms: Sequence[Term] = (),
    origin: float = 0.0,
    trials: int = TRIALS,
    seed: int = 0,
) -> dict[str, Uncertainty]:
    """U of ISO 230-2's E, M, B, A, R (Monte Carlo) and of B̄, the signed mean reversal (GUM).

    ``targets`` (P,), ``forward`` (P, n↑), ``backward`` (P, n↓): attained positions per
    target and cycle, one length unit for all (and the terms'). ``origin``: the sensor's
    zero, which relative terms scale from. Measurands: cell means μ_i↑, μ_i↓ and a common
    σ (pooled over cells): E = range of μ, M = range of (μ↑ + μ↓)/2, B = max |μ↑ − μ↓|,
    A = E + 4σ (range of μ ± 2σ), R = B + 4σ — the standard's formulas with its per-target
    s replaced by the pooled σ. A range's bounds are those of its maximum and minimum
    as maxima over pairs of cells (:func:`maximum_interval`); A and R carry σ's spread.
    Returns ``{"E", "M", "B", "A", "R", "B_mean"}``.
    """
    t = np.asarray(targets, float)
    f, b = np.atleast_2d(np.asarray(forward, float)), np.atleast_2d(np.asarray(backward, float))
    P = t.size
    if f.shape[0] != P or b.shape[0] != P:
        raise ValueError(f"{P} targets but tables of {f.shape[0]} and {b.shape[0]} rows")
    terms = check_terms(terms)
    rows = [f[i] for i in range(P)] + [b[i] for i in range(P)]
    s, dof = pooled_scatter([r[:, None] for r in rows])
    sigma = float(s[0])
    n = np.array([np.isfinite(r).sum() for r in rows], float)
    mean = np.array([np.nanmean(r) for r in rows]) - np.concatenate([t, t])
    pos = (np.concatenate([t, t]) - origin)[:, None]
    draws = Draws(s, dof, (2 * P, 1), terms, trials, seed)

    def cells(only=None):
        mu = draws.error(pos, n, only)[:, :, 0]
        mu += mean[None, :]  # in place: an (M, 2P) array is 1.5 GB for a 5 µm sweep of 9.45 mm
        return mu, (mu[:, :P] + mu[:, P:]) / 2.0, mu[:, :P] - mu[:, P:]

    def span(est, dr, add_est=0.0, add_dr=0.0):
        """95 % interval of a range as a maximum over pairs: max_{i,j} (μ_i − μ_j) over the
        cells that can be the maximum (i) or the minimum (j) in some trial. A pair's draws
        are made when its percentiles are needed (:func:`largest_bounds`), never all at once."""
        top = np.unique(np.argmax(dr, axis=1))
        bottom = np.unique(np.argmin(dr, axis=1))
        e = (est[top][:, None] - est[bottom][None, :]).ravel() + add_est
        add = np.reshape(add_dr, -1)
        hi_top, lo_bottom = dr[:, top].max(axis=0), dr[:, bottom].min(axis=0)
        # no pair's draw exceeds this (with a margin for the rounding of the differences)
        size = np.abs(hi_top)[:, None] + np.abs(lo_bottom)[None, :] + np.abs(add).max()
        upper = ((hi_top[:, None] - lo_bottom[None, :]) + add.max() + 1e-12 * size).ravel()
        nb = bottom.size
        # the candidates' draws as rows: a pair's draws are then two contiguous rows apart
        rows_top, rows_bottom = np.ascontiguousarray(dr[:, top].T), np.ascontiguousarray(dr[:, bottom].T)

        def column(k):
            return (rows_top[k // nb] - rows_bottom[k % nb]) + add

        # the pairs share their cells: as many candidates as the maximum's and the minimum's
        t_eff = effective_count(dr) + effective_count(-dr) - 1.0
        return (*largest_bounds(e, column, upper, len(dr), P95, t_eff), t_eff)

    mu, mid, rev = cells()
    est_mid, est_rev = (mean[:P] + mean[P:]) / 2.0, mean[:P] - mean[P:]
    # the estimator's σ̂ around the pooled s (the cells' bias-corrected intervals need it)
    sig_hat = sigma * np.sqrt(draws.rng.chisquare(dof, size=trials) / dof)
    bounds = {
        "E": span(mean, mu),
        "M": span(est_mid, mid),
        "B": maximum_interval(np.abs(est_rev), np.abs(rev)),
        "A": span(mean, mu, 4 * sigma, 4 * sig_hat),
        "R": maximum_interval(np.abs(est_rev) + 4 * sigma, np.abs(rev) + 4 * sig_hat[:, None]),
    }
    stats_of = {
        "E": lambda m, md, r: m.max(1) - m.min(1),
        "M": lambda m, md, r: md.max(1) - md.min(1),
        "B": lambda m, md, r: np.abs(r).max(1),
        "A": lambda m, md, r: m.max(1) - m.min(1) + 4 * sig_hat,
        "R": lambda m, md, r: np.abs(r).max(1) + 4 * sig_hat,
    }

    def reduced(name):
        """The five statistics of the cells with one term alone (the cells themselves are
        (M, 2P) arrays: one term's at a time)."""
        c = cells(name)
        return {key: fn(*c) for key, fn in stats_of.items()}

    full = {key: fn(mu, mid, rev) for key, fn in stats_of.items()}
    del mu, mid, rev  # the cells of one term at a time from here
    parts_of = {"sample": reduced("sample"), **{term.name: reduced(term.name) for term in draws.terms}}

    from calflow.metrics.iso230_2 import iso230_2

    iso = iso230_2(t, f, b)
    out: dict[str, Uncertainty] = {}
    for key in stats_of:
        reported = float(getattr(iso, key))
        lo, hi, t_eff = bounds[key]
        note = ""
        if not lo <= reported <= hi:
            note = f"the standard's value ({reported:.4g}, per-target s) lies outside the interval of the measurand"
        parts = {name: stat[key] for name, stat in parts_of.items()}
        out[key] = mc_result(
            reported,
            full[key],
            parts,
            {"sample": float(dof)},
            (max(lo, 0.0), hi),
            MAX_METHOD.format(M=trials, t=t_eff),
            note,
        )
        out[key].budget.update(reading_budget(terms))
    # B̄ is linear in the cell means: GUM
    contrib = {"sample": sigma / P * math.sqrt(float(np.sum(1 / n[:P]) + np.sum(1 / n[P:])))}
    for term in terms:
        if term.scope == "target":
            contrib[term.name] = float(term.per_axis(1)[0]) * math.sqrt(2.0 / P)
    out["B_mean"] = gum_linear(float(np.mean(est_rev)), contrib, {"sample": float(dof)})
    return out
