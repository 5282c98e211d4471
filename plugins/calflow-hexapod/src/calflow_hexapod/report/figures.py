"""The hexapod report's figure: held-out ISO 9283 accuracy of each model of the ladder,
position (µm) and orientation (degree), beside its repeatability."""

from __future__ import annotations

import numpy as np


def heldout_accuracy(summary: dict, names: list[str]):
    """The bar chart of the held-out accuracy of each model."""
    from calflow.report.figures import finish, new_figure

    fig, axes = new_figure(ncols=2, height=2.6)
    ax1, ax2 = axes[0]
    x = np.arange(len(names))
    h = [summary["models"][n]["heldout"] for n in names]
    ax1.bar(x - 0.2, [e["accuracy_um"] or np.nan for e in h], 0.4, label="AP (worst target)")
    ax1.bar(x + 0.2, [e["repeatability_um"] or np.nan for e in h], 0.4, label="RP (worst target)")
    ax1.set_xticks(x, names)
    ax1.set_ylabel("position (µm)")
    ax1.set_yscale("log")
    ax1.legend(fontsize=7)
    for k, axis in enumerate("abc"):
        values = [e[f"accuracy_{axis}_deg"] or np.nan for e in h]
        ax2.bar(x + (k - 1) * 0.25, values, 0.25, label=f"AP_{axis}")
    ax2.set_xticks(x, names)
    ax2.set_ylabel("orientation (°)")
    ax2.set_yscale("log")
    ax2.legend(fontsize=7)
    return finish(
        fig,
        "fig-hexapod-heldout",
        "validation",
        "Held-out ISO 9283 pose accuracy of each model (worst target): position beside its "
        "repeatability, and orientation about x, y and z.",
        "ISO 9283:1998 7.2",
    )


def build(summary: dict, inputs) -> tuple[list, list[str]]:
    """(figures, notes) of a hexapod campaign's report (:func:`calflow.report.render.figures_for`)."""
    from calflow.report.figures import guarded

    notes: list[str] = []
    names = [n for n, m in summary.get("models", {}).items() if m.get("heldout")]
    if not names:
        return [], ["No model was validated on held-out targets: no accuracy figure."]
    fig = guarded(notes)(heldout_accuracy, summary, names)
    return [f for f in (fig,) if f is not None], notes


def figures(c, args) -> tuple[list, list[str]]:
    """The family's step hook ``figures(c, args)`` (:mod:`calflow.family_contract`): the
    report's figures of ``args.summary`` and notes on omitted ones, from ``args.inputs``."""
    return build(args.summary, args.inputs)
