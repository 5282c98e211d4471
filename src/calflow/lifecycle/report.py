"""The stage history report (``reports/stages/<id>/history.html`` and ``.pdf``).

Figures first (held-out accuracy against time with its control limits, the tolerance and
the due-date trend; the change test's p-values; individuals charts of the parameters),
then the tables, every number tagged with its ``history.json`` key (``data-key``) as the
campaign reports tag theirs, then what the history cannot tell, in words. Rendered with
the campaign reports' machinery (:mod:`calflow.report.render`: Jinja2 autoescaped,
WeasyPrint for the PDF from PNG renderings of the same figures).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from calflow.lifecycle.decisions.due import parse
from calflow.report import figures as common

COLORS = common.CYCLE


def _label(p: str) -> str:
    """``alpha_deg`` → ``alpha (°)``, ``x_R_um`` → ``x R (µm)``."""
    for suffix, unit in (("_deg", "°"), ("_um", "µm")):
        if p.endswith(suffix):
            return f"{p[: -len(suffix)].replace('_', ' ')} ({unit})"
    return p.replace("_", " ")


def _number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and v == v


def _dates(history: dict, names: list[str]) -> list:
    start = {c["campaign"]: parse(c["start"]) for c in history["campaigns"]}
    return [start[n] for n in names]


def accuracy_figure(history: dict) -> common.Figure:
    """Held-out AP of every model against the campaign date; the due model's individuals
    limits, the tolerance and the due date."""
    fig, axes = common.new_figure(height=2.8)
    ax = axes[0][0]
    charts = history["charts"]["accuracy_um"]
    due = history["due"]
    for i, (m, ch) in enumerate(sorted(charts.items())):
        color = common.COLORS.get(m, COLORS[i % len(COLORS)])
        cal = [c for c in history["campaigns"] if c["campaign"] in ch["campaigns"]]
        ax.plot(
            [parse(c["start"]) for c in cal],
            [c["models"][m]["accuracy_um"] for c in cal],
            "o-",
            color=color,
            lw=0.8,
            label=f"model {m}",
        )
        checks = [
            c
            for c in history["campaigns"]
            if c["kind"] == "interim" and _number(c["models"].get(m, {}).get("accuracy_um"))
        ]
        ax.plot(
            [parse(c["start"]) for c in checks],
            [c["models"][m]["accuracy_um"] for c in checks],
            "s",
            mfc="none",
            color=color,
            label=f"model {m}, interim checks" if checks else None,
        )
        if m == due.get("model") and ch["individuals"]["ucl"] is not None:
            ax.axhline(ch["individuals"]["ucl"], color=color, ls=":", lw=0.8, label=f"model {m} UCL")
    trend = due.get("trend")
    if trend:
        when = [parse(d + "T00:00:00+00:00") for d in trend["dates"]]
        ax.plot(when, trend["mean_um"], color="#7f7f7f", lw=0.9, label=f"trend of model {due.get('model')}")
        ax.plot(
            when,
            trend["upper_um"],
            color="#7f7f7f",
            ls="--",
            lw=0.8,
            label=f"upper {due.get('reliability', 0.95):.0%} prediction",
        )
    if due.get("tolerance_um") is not None:
        ax.axhline(due["tolerance_um"], color="#c0392b", ls="--", lw=1.0, label="tolerance")
    if due.get("date"):
        ax.axvline(parse(due["date"] + "T00:00:00+00:00"), color="#c0392b", lw=1.0, label="due")
    ax.set_yscale("log")
    ax.set_ylabel("held-out AP (µm)")
    ax.set_xlabel("campaign start")
    fig.autofmt_xdate()
    common.legend_below(fig, ax, ncol=4)
    return common.finish(
        fig,
        "fig-accuracy",
        "history",
        "Held-out accuracy AP of each model at each calibration (filled, joined) and the AP of each "
        "interim check on its own targets (open squares, not joined: another set of targets), the "
        "due model's upper Shewhart limit from the calibrations, its trend with the upper "
        "prediction bound (the checks fitted with an offset of their own), the tolerance and the "
        "due date.",
        "",
    )


def change_figure(history: dict) -> common.Figure:
    """−log10 p of the change test per model at each consecutive pair, with the Holm levels."""
    fig, axes = common.new_figure(height=2.4)
    ax = axes[0][0]
    changes = history["changes"]
    models = sorted({m for c in changes for m in c["models"]})
    width = 0.8 / max(1, len(models))
    for i, m in enumerate(models):
        x = np.arange(len(changes)) + (i - (len(models) - 1) / 2) * width
        p = [c["models"].get(m, {}).get("p_value") for c in changes]
        y = [-np.log10(max(v, 1e-300)) if isinstance(v, (int, float)) and np.isfinite(v) else 0 for v in p]
        sig = [bool(c["models"].get(m, {}).get("significant")) for c in changes]
        color = common.COLORS.get(m, COLORS[i % len(COLORS)])
        ax.bar(x, y, width, color=color, label=f"model {m}", hatch=None)
        for xi, yi, s in zip(x, y, sig):
            if s:
                ax.text(xi, yi, "*", ha="center", va="bottom", fontsize=9)
    k = max(1, len(models))
    ax.axhline(
        -np.log10(history["alpha"] / k), color="#7f7f7f", ls="--", lw=0.8, label=f"α/{k} (Holm's first)"
    )
    ax.axhline(-np.log10(history["alpha"]), color="#7f7f7f", ls=":", lw=0.8, label="α (Holm's last)")
    ax.set_xticks(np.arange(len(changes)), [f"{c['from']} →\n{c['to']}" for c in changes], fontsize=6.5)
    ax.set_yscale("symlog", linthresh=3.0)  # linear up to p = 0.001, then by decades: both ends readable
    ax.set_ylabel("−log₁₀ p")
    common.legend_below(fig, ax, ncol=4)
    return common.finish(
        fig,
        "fig-changes",
        "history",
        "Change test between consecutive calibrations: −log10 of each model's p-value; "
        "* marks the models Holm's procedure flags at the stated α.",
        "",
    )


def parameter_figure(history: dict, model: str) -> common.Figure | None:
    """Individuals charts of ``model``'s free parameters over the calibrations."""
    charts = history["charts"]["parameters"].get(model) or {}
    if not charts:
        return None
    n = len(charts)
    ncols = min(2, n)
    nrows = -(-n // ncols)
    fig, axes = common.new_figure(ncols=ncols, nrows=nrows, height=1.7 * nrows + 0.4)
    for ax, (p, ch) in zip(axes.flat, charts.items()):
        dates = _dates(history, ch["campaigns"])
        vals = [
            next(
                c["models"][model]["parameters"][p]["value"]
                for c in history["campaigns"]
                if c["campaign"] == n
            )
            for n in ch["campaigns"]
        ]
        stds = [
            next(
                c["models"][model]["parameters"][p]["std"] or 0
                for c in history["campaigns"]
                if c["campaign"] == n
            )
            for n in ch["campaigns"]
        ]
        ax.errorbar(dates, vals, yerr=[2 * s for s in stds], fmt="o-", lw=0.8, capsize=2)
        ind = ch["individuals"]
        if ind["ucl"] is not None:
            for v, ls in ((ind["centre"], "-"), (ind["lcl"], ":"), (ind["ucl"], ":")):
                ax.axhline(v, color="#7f7f7f", ls=ls, lw=0.7)
        ax.set_title(_label(p))
        ax.ticklabel_format(axis="y", useOffset=False)
        ax.tick_params(axis="x", labelrotation=30)
    for ax in list(axes.flat)[n:]:
        ax.set_visible(False)
    return common.finish(
        fig,
        f"fig-parameters-{model}",
        "history",
        f"Model {model}'s parameters at each calibration (± 2σ within the campaign) with the "
        "individuals chart's centre line and 3σ limits from the moving range.",
        "",
    )


def figures(history: dict) -> list[common.Figure]:
    from calflow.lifecycle.interval_figure import interval_figure

    out = [accuracy_figure(history)]
    drift = interval_figure(history)
    if drift:
        out.append(drift)
    if history["changes"]:
        out.append(change_figure(history))
    model = history["due"].get("model")
    for m in ([model] if model else []) + sorted(history["charts"]["parameters"]):
        if m in history["charts"]["parameters"]:
            f = parameter_figure(history, m)
            if f:
                out.append(f)
            break
    return common.number(out)


def render(history: dict, command: str, pdf: bool = True) -> tuple[str, str]:
    """The HTML page (SVG figures) and the page for the PDF (PNG figures)."""
    from calflow.report.figures import RASTER
    from calflow.report.render import TEMPLATES, _machine, _versions, environment

    token = RASTER.set(pdf)
    try:
        figs = figures(history)
    finally:
        RASTER.reset(token)
    template = environment().get_template("history.html.j2")
    context = dict(
        h=history,
        command=command,
        versions=_versions(),
        machine=_machine(),
        css=(TEMPLATES / "style.css").read_text(),
    )
    html = template.render(figures=figs, **context)
    if not pdf:
        return html, html
    return html, template.render(figures=[replace(f, svg=f.raster) for f in figs], **context)
