"""The history page's figure of the interval from as-found drift (:mod:`calflow.lifecycle.decisions.interval`)."""

from __future__ import annotations

import numpy as np

from calflow.report import figures as common


def interval_figure(history: dict) -> common.Figure | None:
    """As found − as left against the days since the adjustment, the variables method's drift
    line and upper prediction bound (both for the compensation in use), the margin the latest
    as-left value leaves to the tolerance, and the interval; None without as-found values."""
    iv = history.get("interval") or {}
    x = iv.get("inputs") or {}
    if not x.get("days_since_adjustment"):
        return None
    fig, axes = common.new_figure(height=2.6)
    ax = axes[0][0]
    t = np.asarray(x["days_since_adjustment"], float)
    y = np.asarray(x["as_found_minus_as_left"], float)
    chk = np.asarray(x["interim_check"], bool)
    step = np.asarray(x["level"], int) > 0
    for mask, marker, label in (
        (~chk & ~step, "o", "recalibration, as found"),
        (chk & ~step, "s", "interim check (own targets)"),
        (step, "x", "after a detected change"),
    ):
        if mask.any():
            ax.plot(
                t[mask], y[mask], marker, mfc="none" if marker == "s" else None, color="#1f5fa8", label=label
            )
    left = (iv.get("as_left") or {}).get("accuracy_um")
    trend = iv.get("trend")
    if trend and left is not None:
        d = np.asarray(trend["days"], float)
        ax.plot(
            d, np.asarray(trend["mean_um"]) - left, color="#7f7f7f", lw=0.9, label="drift (OLS through 0)"
        )
        ax.plot(
            d,
            np.asarray(trend["upper_um"]) - left,
            color="#7f7f7f",
            ls="--",
            lw=0.8,
            label=f"upper {iv.get('reliability', 0.95):.0%} prediction",
        )
    if left is not None and iv.get("tolerance_um") is not None:
        ax.axhline(
            iv["tolerance_um"] - left, color="#c0392b", ls="--", lw=1.0, label="tolerance − latest as left"
        )
    if iv.get("interval_days"):
        ax.axvline(iv["interval_days"], color="#c0392b", lw=1.0, label="interval")
    ax.axhline(0.0, color="#bbbbbb", lw=0.6)
    ax.set_xlabel("days since the adjustment")
    ax.set_ylabel(f"found − left, AP {iv.get('model')} (µm)")
    common.legend_below(fig, ax, ncol=3)
    return common.finish(
        fig,
        "fig-interval",
        "history",
        "The drift the interval is computed from: each value found through an earlier adjustment minus the "
        "value that adjustment left, against the days since it; the variables method's drift line and its "
        "one-sided upper prediction bound for the compensation in use (no check offset, no level of a "
        "change); the margin the latest as-left value leaves to the tolerance; and the interval where the "
        "bound reaches it.",
        "",
    )
