"""Aggregation of a Monte-Carlo study's points (:mod:`calflow.xytheta.studies.montecarlo`): per noise
level × number of poses, the identification error of every parameter against its reported σ
and its Cramér–Rao bound, the validation accuracy and the observability indices over seeds."""

from __future__ import annotations

import math

import numpy as np
from scipy.stats import norm

from calflow.xytheta.studies.montecarlo import PARAMETERS

PERCENTILES = (5, 25, 50, 75, 95)


def _stats(values) -> dict:
    """n, mean, std and percentiles of the finite values (None when there are none)."""
    a = np.asarray([v for v in values if v is not None], dtype=float)
    a = a[np.isfinite(a)]
    out = {"n": int(a.size), "mean": None, "std": None, **{f"p{q:02d}": None for q in PERCENTILES}}
    if a.size:
        out["mean"] = float(a.mean())
        out["std"] = float(a.std(ddof=1)) if a.size > 1 else None
        out.update({f"p{q:02d}": float(v) for q, v in zip(PERCENTILES, np.percentile(a, PERCENTILES))})
    out["median"] = out["p50"]
    return out


def _rms(values) -> float | None:
    a = np.asarray([v for v in values if v is not None], dtype=float)
    a = a[np.isfinite(a)]
    return float(np.sqrt(np.mean(a**2))) if a.size else None


def parameter_stats(points: list[dict], key: str) -> dict:
    """Error statistics of one parameter over the points of one grid cell.

    ``spread`` is the sample std of the signed error over seeds, ``reported_std_rms`` the
    RMS of the std each identification reported; ``std_ratio`` = spread / reported_std_rms
    is 1 when the reported uncertainty is honest, above 1 when it is optimistic (e.g.
    unmodelled errors). ``rms_z`` = RMS of error/std includes the bias.
    ``sigma_ratio_crlb`` = spread / RMS of the Cramér–Rao bound of each point: 1 for an
    efficient estimator on a rig whose errors the model represents.
    """
    rows = [pt["parameters"][key] for pt in points if not pt.get("failed")]
    err = [r["error"] for r in rows]
    spread = _stats(err)["std"]
    rep = _rms([r["std"] for r in rows])
    bound = _rms([r.get("crlb") for r in rows])
    return {
        "free": any(r["free"] for r in rows),
        "units": rows[0]["units"] if rows else None,
        "abs_error": _stats([r["abs_error"] for r in rows]),
        "bias": _stats(err)["mean"],
        "spread": spread,
        "rms_error": _rms(err),
        "reported_std": _stats([r["std"] for r in rows]),
        "reported_std_rms": rep,
        "std_ratio": spread / rep if spread is not None and rep else None,
        "crlb_rms": bound,
        "sigma_ratio_crlb": spread / bound if spread is not None and bound else None,
        "rms_z": _rms([r["z"] for r in rows]),
        "coverage_95": coverage(rows),
    }


#: The two-sided 95 % normal quantile, Φ⁻¹(0.975) ≈ 1.96.
Z_95 = float(norm.ppf(0.975))


def coverage(rows: list[dict], z: float = Z_95) -> float | None:
    """Fraction of the points whose 95 % interval, estimate ± z σ (z = Φ⁻¹(0.975)), holds the truth.

    0.95 when the reported σ are honest and the model is the rig's; below when the σ are
    optimistic or the estimate biased (an inadequate model). None for a fixed parameter.
    """
    scored = [
        r for r in rows if r["free"] and r["std"] is not None and np.isfinite(r["std"]) and r["std"] > 0
    ]
    if not scored:
        return None
    return float(np.mean([abs(r["error"]) <= z * r["std"] for r in scored]))


def aggregate(points: list[dict]) -> dict:
    """Per noise level × number of poses: identification error, validation accuracy and
    observability statistics over the seeds."""
    if not points:
        raise ValueError("aggregate: no points")
    models = sorted({pt["model"] for pt in points})
    if len(models) > 1:
        raise ValueError(f"aggregate: points of several models {models}; expected one")
    cells: dict[tuple[float, int], list[dict]] = {}
    for pt in points:
        cells.setdefault((float(pt["noise_um"]), int(pt["poses"])), []).append(pt)
    out = []
    for (noise, poses), pts in sorted(cells.items()):
        ok = [pt for pt in pts if not pt.get("failed")]
        out.append(
            {
                "noise_um": noise,
                "poses": poses,
                "n": len(pts),
                "failed": len(pts) - len(ok),
                "seeds": sorted(pt["seed"] for pt in pts),
                "parameters": {key: parameter_stats(pts, key) for _, key, _ in PARAMETERS},
                "accuracy_um": _stats([pt["accuracy_um"] for pt in ok]),
                "repeatability_um": _stats([pt["repeatability_um"] for pt in ok]),
                **{o: _stats([pt["diagnostics"][o] for pt in pts]) for o in ("O1", "O2", "O3", "O4")},
                "residual_rms_um": _stats([pt["diagnostics"]["residual_rms_um"] for pt in pts]),
            }
        )
    return {
        "model": models[0],
        "campaign": points[0].get("campaign"),
        "n_points": len(points),
        "noise_um": sorted({c["noise_um"] for c in out}),
        "poses": sorted({c["poses"] for c in out}),
        "seeds": sorted({pt["seed"] for pt in points}),
        "parameters": [key for _, key, _ in PARAMETERS],
        "cells": out,
    }


def cell(agg: dict, noise_um: float, poses: int) -> dict:
    """The aggregate's cell of one noise level and number of poses."""
    for c in agg["cells"]:
        if c["poses"] == int(poses) and math.isclose(c["noise_um"], float(noise_um)):
            return c
    raise KeyError(f"no cell noise_um={noise_um}, poses={poses}")
