"""The figure of an interim check's report: the visit errors and the sequential test's path."""

from __future__ import annotations

import numpy as np

from calflow.report.figures import COLORS, Figure, Inputs, finish, guarded, legend_below, new_figure


def decision_figure(summary: dict, inputs: Inputs) -> Figure | None:
    """Left: each visit's error (µm) through the reference's bundle, with circles of the
    reference's rms error (H0) and of the tolerance (H1). Right: the SPRT's cumulative
    log-likelihood ratio against the visit, between Wald's bounds (ln B, ln A)."""
    from calflow.lifecycle.decisions.sprt import SPRT
    from calflow.xytheta.report.interim import visit_errors

    run = inputs.runs.get("interim_check")
    k = summary["interim_check"]
    if run is None:
        return None
    e = visit_errors(run)
    test = SPRT(k["reference_rms_um"], k["tolerance_um"], alpha=k["alpha"], beta=k["beta"])
    path = np.cumsum(test.llr(e))
    fig, ax = new_figure(2, height=2.8)
    a, b = ax[0]
    a.plot(e[:, 0], e[:, 1], "o", ms=3, color=COLORS["forward"], label="visits")
    t = np.linspace(0, 2 * np.pi, 200)
    for r, style, label in (
        (k["reference_rms_um"], ":", "reference rms (H0)"),
        (k["tolerance_um"], "--", "tolerance (H1)"),
    ):
        a.plot(r * np.cos(t), r * np.sin(t), style, color="0.3", lw=0.8, label=label)
    a.set_aspect("equal", adjustable="datalim")
    a.set_xlabel("error x (µm)")
    a.set_ylabel("error y (µm)")
    legend_below(fig, a, ncol=3)
    low, high = test.bounds
    b.plot(np.arange(1, path.size + 1), path, ".-", color=COLORS["forward"])
    b.axhline(high, ls="--", color="0.3", lw=0.8)
    b.axhline(low, ls=":", color="0.3", lw=0.8)
    b.text(1, high, " recalibrate", va="bottom", fontsize=6)
    b.text(1, low, " within tolerance", va="top", fontsize=6)
    b.set_xlabel("visit")
    b.set_ylabel("cumulative log-likelihood ratio")
    return finish(
        fig,
        "fig-interim",
        "interim",
        f"Interim check through the bundle of model {k['model']} of {k['reference']}: the "
        f"{e.shape[0]} visit errors (left) and Wald's sequential test (right, α = {k['alpha']}, "
        f"β = {k['beta']}): {k['decision']} after {k['visits']} visit(s).",
        "SPRT (Wald 1945)",
    )


def build(summary: dict, inputs: Inputs) -> tuple[list[Figure], list[str]]:
    notes: list[str] = []
    fig = guarded(notes)(decision_figure, summary, inputs)
    if fig is None and not notes:
        notes.append("The check's run (runs/interim_check.nc) is not among the report inputs: no figure.")
    return [f for f in (fig,) if f is not None], notes
