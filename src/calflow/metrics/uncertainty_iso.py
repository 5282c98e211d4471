"""U of ISO 9283 AP and RP and of ISO 230-2 E, M, B, A, R, B̄ (:mod:`.uncertainty` for the method)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from calflow.metrics.uncertainty import (
    MAX_METHOD,
    TRIALS,
    Draws,
    Term,
    Uncertainty,
    check_terms,
    chi_rp_factor,
    gum_linear,
    how_drawn,
    mc_record,
    mc_result,
    pooled_scatter,
    reading_budget,
    sigma_interval,
    standard_u,
)
from calflow.metrics.uncertainty.draws import GROUP
from calflow.metrics.uncertainty.stream import Maximum, Span, simulate

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
    command,
    attained: Sequence,
    terms: Sequence[Term] = (),
    origin=None,
    trials: int | None = TRIALS,
    seed: int = 0,
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
    draws = Draws(s_axis, dof, T, d, terms, seed)
    y = np.linalg.norm(dev, axis=1)

    def cells(error, g):
        idx = draws.groups[g]
        v = dev[idx][None] + error
        return {"ap": (np.sqrt(np.sum(v * v, axis=2)), idx)}

    dofs = {"sample": float(dof)}
    out = simulate(
        draws,
        pos,
        n,
        cells,
        {"ap": T},
        {"accuracy": Maximum("ap", y)},
        lambda name, tmax, tmin, ext: tmax["ap"],
        trials=trials,
        u_of=lambda name, U, parts: standard_u(U, parts, dofs),
    )
    lo, hi, t_eff = out.intervals["accuracy"]
    M = out.record["trials"]
    accuracy = mc_result(
        float(y.max()),
        out.stats["accuracy"],
        out.parts["accuracy"],
        dofs,
        (lo, hi),
        MAX_METHOD.format(M=M, t=t_eff, how=how_drawn(out.record, "accuracy")),
        monte_carlo=mc_record(out.record, "accuracy"),
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
    rp_draws = c * s_iso * np.sqrt(dof_iso / draws.chisquare(0, M, dof_iso, which=1))
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
    trials: int | None = TRIALS,
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
    # a group: a run of targets, both directions (a target's mid-point and reversal are its own)
    runs = [np.arange(a, min(a + GROUP // 2, P)) for a in range(0, P, GROUP // 2)]
    draws = Draws(s, dof, 2 * P, 1, terms, seed, groups=[np.concatenate([r, P + r]) for r in runs])

    def cells(error, g):
        idx = draws.groups[g]
        G = idx.size // 2
        e = error[:, :, 0]  # the means in the error's own memory when it may be written (simulate's)
        mu = np.add(e, mean[idx][None], out=e if e.flags.writeable else None)
        mid = np.add(mu[:, :G], mu[:, G:])
        mid /= 2.0
        rev = np.subtract(mu[:, :G], mu[:, G:])
        return {"mu": (mu, idx), "mid": (mid, idx[:G]), "absrev": (np.abs(rev, out=rev), idx[:G])}

    def extras(block, m):
        # the estimator's σ̂ around the pooled s (A's and R's cells carry its spread)
        return {"4sig": 4.0 * sigma * np.sqrt(draws.chisquare(block, m, dof) / dof)}

    def statistic(name, tmax, tmin, ext):
        base = {"E": "mu", "A": "mu", "M": "mid"}.get(name)
        value = tmax[base] - tmin[base] if base else tmax["absrev"].copy()
        return value + ext["4sig"] if name in ("A", "R") else value

    est_mid, est_rev = (mean[:P] + mean[P:]) / 2.0, mean[:P] - mean[P:]
    intervals = {
        "E": Span("mu", mean),
        "M": Span("mid", est_mid),
        "B": Maximum("absrev", np.abs(est_rev)),
        "A": Span("mu", mean, 4 * sigma, "4sig"),
        "R": Maximum("absrev", np.abs(est_rev) + 4 * sigma, "4sig"),
    }
    dofs = {"sample": float(dof)}
    sim = simulate(
        draws,
        pos,
        n,
        cells,
        {"mu": 2 * P, "mid": P, "absrev": P},
        intervals,
        statistic,
        extras,
        trials=trials,
        u_of=lambda name, U, parts: standard_u(U, parts, dofs),
    )

    from calflow.metrics.iso230_2 import iso230_2

    iso = iso230_2(t, f, b)
    out: dict[str, Uncertainty] = {}
    for key in intervals:
        reported = float(getattr(iso, key))
        lo, hi, t_eff = sim.intervals[key]
        note = ""
        if not lo <= reported <= hi:
            note = f"the standard's value ({reported:.4g}, per-target s) lies outside the interval of the measurand"
        out[key] = mc_result(
            reported,
            sim.stats[key],
            sim.parts[key],
            dofs,
            (max(lo, 0.0), hi),
            MAX_METHOD.format(M=sim.record["trials"], t=t_eff, how=how_drawn(sim.record, key)),
            note,
            monte_carlo=mc_record(sim.record, key),
        )
        out[key].budget.update(reading_budget(terms))
    # B̄ is linear in the cell means: GUM
    contrib = {"sample": sigma / P * math.sqrt(float(np.sum(1 / n[:P]) + np.sum(1 / n[P:])))}
    for term in terms:
        if term.scope == "target":
            contrib[term.name] = float(term.per_axis(1)[0]) * math.sqrt(2.0 / P)
    out["B_mean"] = gum_linear(float(np.mean(est_rev)), contrib, {"sample": float(dof)})
    return out
