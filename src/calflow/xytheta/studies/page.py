"""The page of a Monte-Carlo study (``reports/studies/<name>.html``): Jinja2 (autoescaped)
with inline SVG figures drawn by matplotlib (Agg/SVG, no display, no files)."""

from __future__ import annotations

import io
import json
import re
from pathlib import Path

import jinja2
import matplotlib
import matplotlib.ticker

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from markupsafe import Markup  # noqa: E402

from calflow.xytheta.report.reference import XYTHETA  # noqa: E402

CSS = Path(__file__).resolve().parent / "report" / "templates" / "style.css"
LABELS = {
    "x_R_um": ("x_R", "µm"),
    "y_R_um": ("y_R", "µm"),
    "alpha_deg": ("α", "degree"),
    "beta_deg": ("β", "degree"),
}
STYLE = {
    "font.family": "DejaVu Sans",
    "font.size": 8.0,
    "axes.grid": True,
    "grid.color": "#d9dde3",
    "grid.linewidth": 0.5,
    "axes.spines.top": False,
    "axes.spines.right": False,
    "legend.frameon": False,
    "legend.fontsize": 7.0,
    "lines.linewidth": 1.0,
    "lines.markersize": 3.5,
    "svg.fonttype": "none",
}
COLORS = ["#1f5fa8", "#c0392b", "#2e8b57", "#e67e22", "#7b3fa0", "#17becf", "#7f7f7f", "#bcbd22"]

TEMPLATE = """<!DOCTYPE html>
<html lang="en">
<head><meta charset="utf-8"><title>Monte-Carlo study {{ name }} — calflow</title><style>{{ css }}</style></head>
<body>
<h1>Monte-Carlo study: {{ name }}</h1>
{% if study.description %}<p>{{ study.description }}</p>{% endif %}
<p>{{ agg.n_points }} simulated XYΘ campaigns (base campaign <code>{{ study.campaign }}</code>, Model {{ agg.model }}):
{{ agg.seeds | length }} seeds × sensor noise {{ agg.noise_um | join(", ") }} µm ×
{{ agg.poses | join(", ") }} identification poses; validation on the Table 4.7 targets with
{{ study.validation_cycles }} cycles. Each point identifies the model from its run dataset alone
(pose-difference cost, Eq. 4.28–4.30); the simulator's truth only scores the estimates afterwards.
{% if agg.get("missing") %}<strong>{{ agg.missing }} grid points are missing.</strong>{% endif %}
{% if failed %}<strong>{{ failed }} identifications failed</strong> (left out of the statistics).{% endif %}</p>
{% if study.rig_options %}<p class="muted">Rig options over the base campaign's: <code>{{ rig_options }}</code></p>{% endif %}

<h2>Headline</h2>
<table>
<caption>Largest pose count ({{ best.poses }}), per noise level: median over seeds.</caption>
<thead><tr><th>noise (µm)</th>{% for k in params %}<th>|Δ{{ labels[k][0] }}| ({{ labels[k][1] }})</th>{% endfor %}
<th>AP max (µm)</th><th class="ref">thesis AP (µm)</th></tr></thead>
<tbody>{% for c in headline %}<tr><td>{{ c.noise_um }}</td>
{% for k in params %}<td>{{ c.parameters[k].abs_error.median | num(4) }}</td>{% endfor %}
<td>{{ c.accuracy_um.median | num(3) }}</td><td class="ref">{{ thesis_ap | num(3) }}</td></tr>{% endfor %}</tbody>
</table>

{% for f in figures %}
<figure id="{{ f.key }}">{{ f.svg }}<figcaption id="{{ f.key }}-caption">Figure {{ loop.index }}. {{ f.caption }}</figcaption></figure>
{% endfor %}

<h2>All grid cells</h2>
<table>
<caption>Median over seeds (n per cell); spread/std = sample std of the error over seeds divided by the RMS of the
reported std (1 when the reported uncertainty is honest); coverage = fraction of seeds whose 95 % interval
(estimate ± 1.96 σ) holds the rig's truth (0.95 when σ are honest and the model is the rig's); σ/CRLB = sample std of
the error over seeds divided by the RMS of the Cramér–Rao bound at the rig's true geometry and noise (1 for an
efficient estimator when the model is the rig's; above where errors the model lacks add to the noise); O2, O4 of the identification Jacobian (Eq. 4.11, 4.13).</caption>
<thead><tr><th>noise (µm)</th><th>poses</th><th>n</th>{% for k in params %}<th>|Δ{{ labels[k][0] }}|</th>{% endfor %}
{% for k in params %}<th>spread/std {{ labels[k][0] }}</th>{% endfor %}{% for k in params %}<th>coverage {{ labels[k][0] }}</th>{% endfor %}{% for k in params %}<th>σ/CRLB {{ labels[k][0] }}</th>{% endfor %}<th>AP max (µm)</th><th>RP max (µm)</th><th>O2</th><th>O4</th></tr></thead>
<tbody>{% for c in agg.cells %}<tr><td>{{ c.noise_um }}</td><td>{{ c.poses }}</td><td>{{ c.n - c.failed }}</td>
{% for k in params %}<td>{{ c.parameters[k].abs_error.median | num(4) }}</td>{% endfor %}
{% for k in params %}<td>{{ c.parameters[k].std_ratio | num(2) }}</td>{% endfor %}
{% for k in params %}<td>{{ c.parameters[k].coverage_95 | num(2) }}</td>{% endfor %}
{% for k in params %}<td>{{ c.parameters[k].sigma_ratio_crlb | num(2) }}</td>{% endfor %}
<td>{{ c.accuracy_um.median | num(3) }}</td><td>{{ c.repeatability_um.median | num(3) }}</td>
<td>{{ c.O2.median | sci }}</td><td>{{ c.O4.median | sci }}</td></tr>{% endfor %}</tbody>
</table>

<h2>Study file</h2>
<pre>{{ study_json }}</pre>
<p class="muted">calflow {{ version }}. Rerun: <code>snakemake --cores 2 reports/studies/{{ name }}.html</code></p>
</body>
</html>
"""


def _env() -> jinja2.Environment:
    env = jinja2.Environment(
        autoescape=True, undefined=jinja2.StrictUndefined, trim_blocks=True, lstrip_blocks=True
    )
    env.filters["num"] = lambda v, d=3: "—" if v is None else f"{v:.{d}f}"
    env.filters["sci"] = lambda v: "—" if v is None else f"{v:.3g}"
    return env


def _figure(fig, key: str, caption: str) -> dict:
    """A figure of the page: laid out, drawn as SVG under ``key``, with its caption."""
    fig.tight_layout(pad=0.4)
    return {"key": key, "svg": to_svg(fig, key), "caption": caption}


def to_svg(fig, key: str) -> Markup:
    """One ``<svg>`` element (no prolog, no date); ids prefixed with ``key`` so inline figures never clash."""
    buf = io.StringIO()
    with plt.rc_context({**STYLE, "svg.hashsalt": key}):
        fig.savefig(buf, format="svg", bbox_inches="tight", pad_inches=0.04, metadata={"Date": None})
    plt.close(fig)
    text = buf.getvalue()
    text = re.sub(r"<metadata>.*?</metadata>", "", text[text.index("<svg") :], count=1, flags=re.S)
    # every id (and reference to it) gets the figure's key: matplotlib numbers "patch_1" etc. per figure
    text = re.sub(r'(\sid="|url\(#|href="#)([^")]+)', lambda m: f"{m.group(1)}{key}-{m.group(2)}", text)
    end = text.index(">")
    head = (
        re.sub(r'\s(width|height)="[^"]*"', "", text[:end])
        + f' role="img" aria-labelledby="{key}-caption" style="width:100%;height:auto"'
    )
    return Markup(head + text[end:])  # generated here from numbers and fixed labels only


def _series(agg, noise, path):
    """(poses, values) of one noise level; ``path`` walks into a cell (e.g. ("accuracy_um", "p50"))."""
    xs, ys = [], []
    for c in agg["cells"]:
        if c["noise_um"] == noise:
            v = c
            for p in path:
                v = v[p] if v is not None else None
            xs.append(c["poses"])
            ys.append(np.nan if v is None else v)
    return np.asarray(xs, dtype=float), np.asarray(ys, dtype=float)


def _noise_lines(ax, agg, path, lo=None, hi=None, ref=None):
    for i, noise in enumerate(agg["noise_um"]):
        color = COLORS[i % len(COLORS)]
        x, y = _series(agg, noise, path)
        ax.plot(x, y, "o-", color=color, label=f"{noise:g} µm")
        if lo and hi:
            ax.fill_between(
                x,
                _series(agg, noise, path[:-1] + (lo,))[1],
                _series(agg, noise, path[:-1] + (hi,))[1],
                color=color,
                alpha=0.15,
                lw=0,
            )
        if ref:
            ax.plot(*_series(agg, noise, ref), ":", color=color)
    ax.set_xscale("log")
    ax.set_xlabel("identification poses")


def _figures(agg: dict) -> list[dict]:
    params = [k for k in agg["parameters"] if any(c["parameters"][k]["free"] for c in agg["cells"])]
    figs = []
    with plt.rc_context(STYLE):
        fig, axes = plt.subplots(1, len(params), figsize=(7.0, 2.4), squeeze=False)
        for ax, k in zip(axes[0], params):
            _noise_lines(
                ax,
                agg,
                ("parameters", k, "abs_error", "p50"),
                "p25",
                "p75",
                ref=("parameters", k, "reported_std_rms"),
            )
            ax.set_yscale("log")
            ax.set_title(f"|Δ{LABELS[k][0]}| ({LABELS[k][1]})")
        axes[0][0].legend(title="sensor noise")
        figs.append(
            _figure(
                fig,
                "fig-error",
                "Identification error |estimate − truth| against the number of poses, per sensor noise: "
                "median over seeds (line), 25–75 % (band), and the RMS of the std the identification reported "
                "(dotted). An error that stops falling while the reported std does is a bias: errors the "
                "model does not describe (e.g. the angle-dependent errors of Sec. 4.5.5).",
            )
        )

        fig, axes = plt.subplots(1, len(params), figsize=(7.0, 2.2), squeeze=False)
        for ax, k in zip(axes[0], params):
            _noise_lines(ax, agg, ("parameters", k, "std_ratio"), ref=("parameters", k, "rms_z"))
            ax.axhline(1.0, color="#7f7f7f", lw=0.8, ls="--")
            ax.set_yscale("log")
            ax.yaxis.set_major_locator(matplotlib.ticker.LogLocator(subs=(1.0, 2.0, 5.0)))
            ax.yaxis.set_major_formatter(matplotlib.ticker.FormatStrFormatter("%g"))
            ax.yaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
            ax.set_title(LABELS[k][0])
        axes[0][0].set_ylabel("error / reported std")
        axes[0][0].legend(title="sensor noise")
        figs.append(
            _figure(
                fig,
                "fig-std",
                "Honesty of the reported uncertainty: sample std of the error over seeds divided by the RMS "
                "of the reported std (solid), and RMS of error/std, which includes the bias (dotted). 1 "
                "(dashed) is honest; above 1 the reported std is optimistic.",
            )
        )

        fig, ax = plt.subplots(figsize=(4.2, 2.6))
        _noise_lines(ax, agg, ("accuracy_um", "p50"), "p05", "p95")
        ref = XYTHETA["models"].get(agg["model"], {}).get("accuracy_um")
        if ref is not None:
            ax.axhline(
                ref, color="#9aa0a6", ls="--", lw=1.0, label=f"thesis Model {agg['model']} (1200 poses)"
            )
        ax.set_ylabel("ISO 9283 AP, max over targets (µm)")
        ax.legend()
        figs.append(
            _figure(
                fig,
                "fig-accuracy",
                f"Validation accuracy of Model {agg['model']} (ISO 9283 AP, max over the Table 4.7 targets) "
                "against the number of identification poses: median over seeds, 5–95 % band.",
            )
        )

        fig, (a, b) = plt.subplots(1, 2, figsize=(7.0, 2.5))
        low = min(agg["noise_um"])
        for name, color in (("O2", COLORS[0]), ("O4", COLORS[1])):
            x, y = _series(agg, low, (name, "p50"))
            a.plot(x, y / np.nanmax(y), "o-", color=color, label=f"{name} / max")
        plateau = XYTHETA["observability_poses"]["O2_plateau"]
        a.axvline(plateau, color="#9aa0a6", ls="--", lw=1.0, label=f"thesis O2 plateau ≈ {plateau}")
        a.set_xscale("log")
        a.set_xlabel("identification poses")
        a.set_title("observability (Fig. 4.21)")
        a.legend()
        for k, color in zip(params, COLORS):
            x, y = _series(agg, low, ("parameters", k, "abs_error", "p50"))
            b.plot(x, y / y[0], "o-", color=color, label=f"|Δ{LABELS[k][0]}|")
        b.set_xscale("log")
        b.set_yscale("log")
        b.set_xlabel("identification poses")
        b.set_title(f"median error / error at {int(agg['poses'][0])} poses ({low:g} µm noise)")
        b.legend()
        figs.append(
            _figure(
                fig,
                "fig-observability",
                "What the observability indices predict: O2 and O4 of the identification Jacobian (median "
                "over seeds, normalised to their maximum) beside the identification error they stand for, "
                "at the lowest noise level.",
            )
        )
    return figs


def render(agg: dict, study: dict) -> str:
    """The HTML page of study ``study`` (a loaded study) from its aggregate."""
    from calflow import __version__

    cells = [c for c in agg["cells"] if c["poses"] == max(agg["poses"])]
    shown = {k: v for k, v in study.items() if k not in ("base", "name", "file")}
    return (
        _env()
        .from_string(TEMPLATE)
        .render(
            name=study["name"],
            study=study,
            agg=agg,
            css=Markup(CSS.read_text()) if CSS.exists() else "",
            figures=_figures(agg),
            headline=cells,
            best=cells[0],
            params=agg["parameters"],
            labels=LABELS,
            thesis_ap=XYTHETA["models"].get(agg["model"], {}).get("accuracy_um"),
            failed=sum(c["failed"] for c in agg["cells"]),
            rig_options=json.dumps(study.get("rig_options", {})),
            study_json=json.dumps(shown, indent=2, sort_keys=True),
            version=__version__,
        )
    )
