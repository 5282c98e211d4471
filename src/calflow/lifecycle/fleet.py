"""Stages of one product model as a fleet: pooled reproducibility, typical and guaranteed figures.

One stage's history is short (a handful of calibrations), so its own between-campaign
spread of the held-out AP is poorly known. Stages of one product model (a *fleet*: the
stage settings' ``fleet``, else the robot) may share it — the NASA RP-1342 argument for
pooling the variability of like instruments — when a homogeneity test does not reject
equal variances:

* each stage's reproducibility is the sample variance s_i² of its calibrations' held-out
  AP of the watched model about the mean of its segment (a detected change starts a new
  level), with ν_i = n_i − segments_i degrees of freedom;
* Bartlett's test (Bartlett 1937; the statistic from the (s_i², ν_i), which scipy's
  ``bartlett`` takes only as raw samples with n_i − 1 dof) at α = 0.05: not rejected, the
  pooled s_p² = Σ ν_i s_i² / Σ ν_i (Σ ν_i dof) is every stage's reproducibility, and a
  stage with fewer than two dof of its own *borrows* it; rejected, each keeps its own and
  the fleet says so.

Over the fleet, the latest calibration's held-out AP of each stage gives the *typical*
figure (median and mean) and the *guaranteed* one: the one-sided 95 %/95 % upper
tolerance bound x̄ + k s, k = t'_{0.95}(n − 1, z_{0.95} √n) / √n (noncentral t; ISO
16269-6), the AP that 95 % of the fleet's stages stay below, with 95 % confidence.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import stats

ALPHA = 0.05


def bartlett(variances, dofs) -> tuple[float, float]:
    """Bartlett's statistic and p-value for equal variances from (s_i², ν_i), ν_i ≥ 1."""
    s2, nu = np.asarray(variances, float), np.asarray(dofs, float)
    k, N = s2.size, nu.sum()
    sp2 = float(np.sum(nu * s2) / N)
    if k < 2 or sp2 <= 0 or np.any(s2 <= 0):
        return math.nan, math.nan
    c = 1.0 + (np.sum(1.0 / nu) - 1.0 / N) / (3.0 * (k - 1))
    chi2 = float((N * math.log(sp2) - np.sum(nu * np.log(s2))) / c)
    return chi2, float(stats.chi2.sf(chi2, k - 1))


def tolerance_factor(n: int, coverage: float = 0.95, confidence: float = 0.95) -> float:
    """k of the one-sided normal tolerance bound x̄ + k s (noncentral t, ISO 16269-6)."""
    z = stats.norm.ppf(coverage)
    return float(stats.nct.ppf(confidence, n - 1, z * math.sqrt(n)) / math.sqrt(n))


def _stage_values(history: dict) -> tuple[str | None, list[tuple[float, int]]]:
    """The watched model and its calibrations' (held-out AP, segment) of one history."""
    model = (history.get("due") or {}).get("model")
    out = []
    for e, seg in zip(history.get("campaigns") or [], history.get("segments") or []):
        if e.get("kind") != "calibration" or model not in (e.get("models") or {}):
            continue
        ap = e["models"][model].get("accuracy_um")
        if isinstance(ap, (int, float)) and math.isfinite(ap):
            out.append((float(ap), int(seg)))
    return model, out


def fleets(histories: list[dict]) -> list[dict]:
    """Per fleet: its stages' reproducibility (own, pooled, used), the homogeneity test, and
    the typical and guaranteed held-out AP over its stages (module notes)."""
    groups: dict[str, list[dict]] = {}
    for h in histories:
        name = (h.get("settings") or {}).get("fleet") or h.get("robot") or "?"
        groups.setdefault(str(name), []).append(h)
    return [fleet(name, hs) for name, hs in sorted(groups.items())]


def fleet(name: str, histories: list[dict]) -> dict:
    stages, latest = [], []
    for h in histories:
        model, vals = _stage_values(h)
        segs = {s for _, s in vals}
        nu = len(vals) - len(segs)
        if vals:
            latest.append(vals[-1][0])
        s2 = None
        if nu >= 1:
            ap = np.array([v for v, _ in vals])
            seg = np.array([s for _, s in vals])
            resid = ap - np.array([ap[seg == s].mean() for s in seg])
            s2 = float(np.sum(resid**2) / nu)
        stages.append(
            {
                "stage": h.get("stage"),
                "model": model,
                "calibrations": len(vals),
                "dof": nu,
                "own_sd_um": None if s2 is None else math.sqrt(s2),
            }
        )
    usable = [s for s in stages if s["dof"] >= 1 and s["own_sd_um"] and s["own_sd_um"] > 0]
    out: dict = {
        "fleet": name,
        "stages": stages,
        "alpha": ALPHA,
        "test": "Bartlett's test of equal variances",
    }
    if len(usable) >= 2:
        chi2, p = bartlett([s["own_sd_um"] ** 2 for s in usable], [s["dof"] for s in usable])
        nu = sum(s["dof"] for s in usable)
        pooled = math.sqrt(sum(s["dof"] * s["own_sd_um"] ** 2 for s in usable) / nu)
        homogeneous = bool(p >= ALPHA)
        out.update(statistic=chi2, p_value=p, homogeneous=homogeneous, pooled_sd_um=pooled, pooled_dof=nu)
        for s in stages:
            own = s["own_sd_um"] is not None and s["dof"] >= 2
            s["borrowed"] = bool(homogeneous and not own)
            s["used_sd_um"] = pooled if s["borrowed"] else s["own_sd_um"]
        out["statement"] = f"{len(usable)} stages with a spread of their own; Bartlett p = {p:.3g}: " + (
            f"homogeneous at α = {ALPHA}, pooled reproducibility {pooled:.3g} µm ({nu} dof); "
            "stages with fewer than 2 dof of their own borrow it"
            if homogeneous
            else f"the spreads differ at α = {ALPHA}: each stage keeps its own, nothing is pooled"
        )
    else:
        out.update(homogeneous=None, pooled_sd_um=None)
        for s in stages:
            s["used_sd_um"], s["borrowed"] = s["own_sd_um"], False
        out["statement"] = (
            f"{len(usable)} stage(s) with a between-campaign spread of their own: at least 2 are needed "
            "to test homogeneity and pool"
        )
    out["latest_ap_um"] = latest
    out.update(typical_fleet(latest))
    return out


def typical_fleet(values: list[float]) -> dict:
    """``typical`` (median, mean) and ``guaranteed`` (95/95 upper tolerance bound) of one value per stage."""
    x = np.asarray(values, float)
    if x.size == 0:
        return {"typical_um": None, "guaranteed_um": None, "guarantee": "no stage with a held-out AP"}
    typical = {"median": float(np.median(x)), "mean": float(x.mean())}
    if x.size < 3:
        return {
            "typical_um": typical,
            "guaranteed_um": None,
            "guarantee": f"{x.size} stage(s): a 95/95 tolerance bound needs at least 3",
        }
    k = tolerance_factor(x.size)
    return {
        "typical_um": typical,
        "guaranteed_um": float(x.mean() + k * x.std(ddof=1)),
        "guarantee": f"one-sided 95 %/95 % upper tolerance bound over {x.size} stages (k = {k:.3f}, normal)",
    }
