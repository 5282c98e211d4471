"""Coverage of the 95 % interval of AP, a maximum over targets, whatever the ties.

ISO 9283's AP is max_j |b̄_j − c_j| over the targets; its measurand the maximum of the true
deviations |μ_j − c_j|. When several targets are (nearly) equally far from their commands,
the measured maximum is biased upwards and an interval built around the one target that
happened to come out largest misses the truth too often. Each case below draws, per seed,
T targets' readings around their true deviations (norms as the case says, directions at
random), with Gaussian or heavy-tailed (Student t, ν = 3, scaled to the same σ) noise,
n cycles, and counts how often calflow's interval (``iso9283_uncertainty``, no declared
terms: the sample term alone, so the truth is known exactly) covers the true AP.

    .venv/bin/python benchmarks/bench_max_coverage.py --seeds 400 --trials 4000 --json

The Monte Carlo error of a coverage p over N seeds is √(p(1−p)/N) (± 1.1 % at 95 %, N = 400).
"""

from __future__ import annotations

import argparse
import json
import math
import time
import zlib

import numpy as np

from calflow.metrics.uncertainty_iso import iso9283_uncertainty

SIGMA = 0.5  # µm per axis, each reading

#: name → (targets, cycles, norms of the true deviations as a function of T, noise)
CASES = {
    "8-way tie, 5 cycles, Gaussian": (8, 5, lambda T, rng: np.full(T, 2.0), "normal"),
    "8-way tie, 5 cycles, heavy-tailed": (8, 5, lambda T, rng: np.full(T, 2.0), "t3"),
    "8-way tie, 2 cycles, Gaussian": (8, 2, lambda T, rng: np.full(T, 2.0), "normal"),
    "8-way tie, 10 cycles, Gaussian": (8, 10, lambda T, rng: np.full(T, 2.0), "normal"),
    "near-tie (spread 0.1 σ), 5 cycles": (8, 5, lambda T, rng: 2.0 + rng.uniform(0, 0.05, T), "normal"),
    "3-way tie among 8, 3 cycles": (
        8,
        3,
        lambda T, rng: np.r_[np.full(3, 2.0), np.full(T - 3, 1.0)],
        "normal",
    ),
    "one clear maximum, 3 cycles": (8, 3, lambda T, rng: np.r_[4.0, np.full(T - 1, 1.0)], "normal"),
    "spread biases, 3 cycles": (8, 3, lambda T, rng: rng.uniform(0.2, 3.0, T), "normal"),
    "spread biases, 5 cycles, heavy-tailed": (8, 5, lambda T, rng: rng.uniform(0.2, 3.0, T), "t3"),
    "20-way tie, 3 cycles, Gaussian": (20, 3, lambda T, rng: np.full(T, 2.0), "normal"),
}


def noise(rng, kind: str, shape) -> np.ndarray:
    if kind == "normal":
        return rng.normal(0.0, SIGMA, shape)
    nu = 3.0  # Student t with ν = 3 has variance ν/(ν − 2): scaled to σ
    return rng.standard_t(nu, shape) * SIGMA / math.sqrt(nu / (nu - 2.0))


def one(rng, T, n, norms, kind, trials) -> tuple[int, float, float]:
    """One validation: -1 if the interval lies below the true AP, 1 above it, 0 if it covers
    it; AP's U and the truth."""
    size = norms(T, rng)
    angle = rng.uniform(0, 2 * np.pi, T)
    b = np.column_stack([size * np.cos(angle), size * np.sin(angle)])
    cmd = np.column_stack([rng.uniform(-2000, 2000, T), rng.uniform(-1500, 1500, T)])
    att = [cmd[j] + b[j] + noise(rng, kind, (n, 2)) for j in range(T)]
    r = iso9283_uncertainty(cmd, att, trials=trials, seed=int(rng.integers(1 << 31)))["accuracy"]
    truth = float(size.max())
    lo, hi = r.interval
    return (-1 if hi < truth else 1 if lo > truth else 0), r.U, truth


def coverage(seeds: int, trials: int) -> dict:
    out = {}
    for name, (T, n, norms, kind) in CASES.items():
        rng = np.random.default_rng(zlib.crc32(name.encode()))
        t0 = time.process_time()
        hits, us = [], []
        for _ in range(seeds):
            ok, U, _ = one(rng, T, n, norms, kind, trials)
            hits.append(ok)
            us.append(U)
        hits = np.array(hits)
        p = float(np.mean(hits == 0))
        out[name] = {
            "coverage": p,
            "below": float(np.mean(hits < 0)),
            "above": float(np.mean(hits > 0)),
            "mc_error": math.sqrt(max(p * (1 - p), 1e-12) / seeds),
            "median_U_um": float(np.median(us)),
            "cpu_s": time.process_time() - t0,
        }
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, default=400)
    p.add_argument("--trials", type=int, default=4000)
    p.add_argument("--json", action="store_true")
    a = p.parse_args()
    res = {"seeds": a.seeds, "trials": a.trials, "sigma_um": SIGMA, "cases": coverage(a.seeds, a.trials)}
    if a.json:
        print(json.dumps(res, indent=1))
    else:
        for name, r in res["cases"].items():
            print(
                f"{name:40s} {r['coverage']:.3f} ± {r['mc_error']:.3f} (below {r['below']:.3f}, "
                f"above {r['above']:.3f})  U {r['median_U_um']:.3f} µm"
            )


if __name__ == "__main__":
    main()
