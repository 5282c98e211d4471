"""Extrapolation said in words: does a validation day leave the conditions training saw?

A model fitted on training data (Eq. 5.3, 5.6, 5.10) describes the drift only over the
temperatures (and humidities) training covered; the thesis found the single model's
accuracy "getting much larger when temperature goes out of the temperature range of
training phase" (Sec. 5.3.3, Fig. 5.20). For each day of validation (days since its start,
as ``max_accuracy_nm_by_day``) this module compares the thermocouples' range (the mean of the
four, per test: ``temperature_min_c``/``temperature_max_c`` of the metrics, degC) and, when
known, the relative humidity's range (%RH: a simulated rig's room; the runs record none)
with training's, and writes one sentence per day. The same sentence stands beside every
model's figure for that day (``tests.<t>.extrapolation_by_day``): the conditions are the
room's, whichever model ran.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["extrapolation_block"]


def _beyond(lo: float, hi: float, t_lo: float, t_hi: float) -> float:
    """How far [lo, hi] leaves [t_lo, t_hi] (>= 0, same units)."""
    return max(0.0, t_lo - lo, hi - t_hi)


def _day_words(day: int, kind: str, unit: str, rng, train, fmt: str) -> tuple[str, bool]:
    lo, hi = rng
    out = _beyond(lo, hi, *train)
    span = f"{lo:{fmt}}–{hi:{fmt}} {unit}"
    if out > 0:
        return (
            f"{kind} {span}, beyond training's {train[0]:{fmt}}–{train[1]:{fmt}} {unit} by up to {out:{fmt}} {unit}",
            True,
        )
    return f"{kind} {span}, within training's", False


def extrapolation_block(metrics, training_range_c, tests: dict, humidity: dict | None = None) -> dict | None:
    """Per validation day: the sentence and flags (module docstring); adds
    ``extrapolation_by_day`` (a list over days: the sentence when the day leaves training's
    range, else None) to every mode of ``tests``. ``humidity``: ``{"training_pct": [lo, hi],
    "tests_pct": [[lo, hi] per test of the metrics]}`` or None. None without a training range."""
    if training_range_c is None or metrics is None:
        return None
    start = float(metrics.attrs.get("start_time_h", np.nanmin(metrics["time_start_h"].values)))
    end = float(metrics.attrs.get("end_time_h", np.nanmax(metrics["time_end_h"].values)))
    day = np.floor((metrics["time_h"].values - start) / 24.0).astype(int)
    n_days = int(math.floor((end - start) / 24.0)) + 1
    lo_t, hi_t = metrics["temperature_min_c"].values, metrics["temperature_max_c"].values
    hum = np.asarray(humidity["tests_pct"], dtype=float) if humidity else None
    days = []
    for d in range(n_days):
        rows = (day == d) & np.isfinite(lo_t) & np.isfinite(hi_t)
        if not rows.any():
            days.append({"day": d, "words": None, "temperature_outside": None, "humidity_outside": None})
            continue
        words, t_out = _day_words(
            d, "thermocouples", "°C", (lo_t[rows].min(), hi_t[rows].max()), training_range_c, ".2f"
        )
        parts, h_out = [words], None
        if hum is not None:
            h_words, h_out = _day_words(
                d,
                "humidity",
                "%RH",
                (hum[rows, 0].min(), hum[rows, 1].max()),
                humidity["training_pct"],
                ".1f",
            )
            parts.append(h_words)
        leaves = [k for k, flag in (("temperature", t_out), ("humidity", h_out)) if flag]
        verdict = (
            f"every model extrapolates in {' and '.join(leaves)} on this day"
            if leaves
            else "no model extrapolates"
        )
        days.append(
            {
                "day": d,
                "temperature_outside": t_out,
                "humidity_outside": h_out,
                "words": f"Day {d + 1}: " + "; ".join(parts) + f" — {verdict}.",
            }
        )
    for t in tests.values():
        t["extrapolation_by_day"] = [
            x["words"] if (x["temperature_outside"] or x["humidity_outside"]) else None for x in days
        ]
    return {
        "training_temperature_c": list(training_range_c),
        "training_humidity_pct": list(humidity["training_pct"]) if humidity else None,
        "days": days,
        "humidity_source": "the simulated rig's room (the runs record no humidity)" if humidity else None,
    }
