"""Shared figure machinery of the reports: one style, matplotlib figures as inline SVG.

Figures are drawn with the Agg/SVG backends only (no display, no files): each figure
function returns a :class:`Figure` whose ``svg`` is the markup of one ``<svg>`` element,
generated here and nowhere else, so the templates may embed it unescaped.  Captions are
plain text and stay autoescaped.

The result files a report draws on are recognised by their attributes (``calflow_kind``,
``plan``, ``model``, ``compensation``), as the summary does (:func:`classify`).
"""

from __future__ import annotations

import io
import re
from contextvars import ContextVar
from dataclasses import dataclass, field
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import xarray as xr  # noqa: E402
from markupsafe import Markup  # noqa: E402

#: Text width of the A4 page (210 mm − 2 × 16 mm margins) in inches: figures are drawn at
#: print size so that their 8–9 pt text stays 8–9 pt in the PDF.
TEXT_WIDTH_IN = 6.9

#: One palette for every report: calflow's results in saturated colours, the thesis grey.
COLORS = {
    "forward": "#1f5fa8",
    "backward": "#c0392b",
    "none": "#7f7f7f",
    "linear": "#1f5fa8",
    "cubic": "#e67e22",
    "no_calibration": "#7f7f7f",
    "single": "#1f5fa8",
    "adaptive_kmz": "#2e8b57",
    "I": "#7f7f7f",
    "II": "#c0392b",
    "III": "#e67e22",
    "IV": "#1f5fa8",
    "V": "#2e8b57",
    "thesis": "#9aa0a6",
    "shade": "#dbe7f5",
}
#: Resolution of the artists drawn ``rasterized=True`` (dense scatters of thousands of
#: readings): embedded as one image in the SVG, which keeps pages light and fast to print.
RASTER_DPI = 200

CYCLE = ["#1f5fa8", "#c0392b", "#2e8b57", "#e67e22", "#7b3fa0", "#17becf", "#7f7f7f", "#bcbd22"]

STYLE = {
    "font.family": "DejaVu Sans",
    "font.size": 8.0,
    "axes.titlesize": 8.5,
    "axes.labelsize": 8.0,
    "legend.fontsize": 7.0,
    "xtick.labelsize": 7.5,
    "ytick.labelsize": 7.5,
    "axes.grid": True,
    "grid.color": "#d9dde3",
    "grid.linewidth": 0.5,
    "axes.spines.top": False,
    "axes.spines.right": False,
    "axes.prop_cycle": matplotlib.cycler(color=CYCLE),
    "lines.linewidth": 1.0,
    "lines.markersize": 3.5,
    "legend.frameon": True,
    "legend.framealpha": 0.85,
    "legend.edgecolor": "none",
    "legend.borderpad": 0.3,
    "svg.fonttype": "none",  # text stays text: searchable, small, rendered in the page's font
    "figure.dpi": 72,
}


@dataclass
class Figure:
    """One report figure: ``key`` (HTML id), ``section`` (where the template puts it),
    ``caption`` (plain text, without its number), ``thesis`` (the figure it mirrors),
    ``svg`` (generated markup), ``raster`` (the same figure as an ``<img>`` of a PNG at
    :data:`RASTER_DPI`, for the PDF: WeasyPrint lays out a PNG in milliseconds where it
    spends seconds on each inline SVG) and ``number`` (set by :func:`number`)."""

    key: str
    section: str
    caption: str
    thesis: str
    svg: Markup
    number: int = 0
    raster: Markup = Markup("")


def mode_label(name: str) -> str:
    """The report label of a test mode or model name, as its family registers it."""
    from calflow.family import modes

    return modes().get(name, name.replace("_", " "))


def new_figure(ncols: int = 1, nrows: int = 1, height: float = 2.6, width: float = TEXT_WIDTH_IN, **kw):
    """A figure at print size with the report style."""
    with plt.rc_context(STYLE):
        fig, axes = plt.subplots(nrows, ncols, figsize=(width, height), squeeze=False, **kw)
    return fig, axes


def to_svg(fig, key: str) -> Markup:
    """The figure as one ``<svg>`` element sized by its container (closes the figure).

    The XML prolog and doctype go; width and height become CSS so the figure scales to the
    column on screen and to the text width in print; ids are salted with ``key`` so that
    several inline SVGs in one page never share an id; no date, so output is reproducible. Its
    text alternative is the figure's caption, ``<figcaption id="<key>-caption">`` (WCAG 1.1.1).
    """
    buf = io.StringIO()
    with plt.rc_context({**STYLE, "svg.hashsalt": key}):
        # no bbox_inches="tight" (it draws the figure once more): finish()'s tight_layout
        # already leaves a margin of 0.4 font size around the axes, as in to_png
        fig.savefig(buf, format="svg", dpi=RASTER_DPI, metadata={"Date": None})
    plt.close(fig)
    text = buf.getvalue()
    text = text[text.index("<svg") :]
    text = re.sub(r"<metadata>.*?</metadata>", "", text, count=1, flags=re.S)
    head_end = text.index(">")
    head = text[:head_end]
    m = re.search(r'viewBox="[\d.]+ [\d.]+ ([\d.]+) ([\d.]+)"', head)
    head = re.sub(r'\s(width|height)="[^"]*"', "", head)
    width_pt = float(m.group(1)) if m else TEXT_WIDTH_IN * 72
    # never wider than the text, never blown up beyond print size on a wide screen
    head += f' role="img" aria-labelledby="{key}-caption" class="plot"'
    head += f' style="width:100%;max-width:{width_pt:.1f}pt;height:auto"'
    return Markup(head + text[head_end:])


def to_png(fig, key: str) -> Markup:
    """The figure as one ``<img class="plot">`` holding a PNG at :data:`RASTER_DPI` (a data
    URI), sized like :func:`to_svg`'s element: at most its print width, else the column's.
    Leaves the figure open."""
    import base64

    buf = io.BytesIO()
    with plt.rc_context(STYLE):
        # no bbox_inches="tight": it draws the figure twice, and finish()'s tight_layout
        # already leaves the SVG's margin (0.4 font size ≈ 0.04 in) around the axes
        fig.savefig(buf, format="png", dpi=RASTER_DPI, metadata={"Software": None})
    data = buf.getvalue()
    width_pt = int.from_bytes(data[16:20], "big") / RASTER_DPI * 72  # IHDR width, pixels
    return Markup(
        f'<img id="{key}-png" class="plot" alt="" style="width:100%;max-width:{width_pt:.1f}pt;'
        f'height:auto" src="data:image/png;base64,{base64.b64encode(data).decode()}">'
    )


def legend_below(fig, ax, ncol: int = 3) -> None:
    """One legend for the figure, under its axes, where it hides no data."""
    handles, labels = ax.get_legend_handles_labels()
    if not handles:
        return
    rows = -(-len(handles) // ncol)
    fig.legend(handles, labels, loc="lower center", ncol=ncol, bbox_to_anchor=(0.5, 0.0))
    fig.calflow_bottom = (0.18 * rows + 0.16) / fig.get_figheight()  # legend height as a figure fraction


#: Whether :func:`finish` also renders each figure as PNG (:attr:`Figure.raster`): set by
#: :func:`calflow.report.render.render_campaign_pages` when a PDF will be made.
RASTER = ContextVar("calflow_report_raster", default=False)


def finish(fig, key: str, section: str, caption: str, thesis: str) -> Figure:
    with plt.rc_context(STYLE):
        fig.tight_layout(pad=0.4, rect=(0, getattr(fig, "calflow_bottom", 0.0), 1, 1))
    raster = to_png(fig, key) if RASTER.get() else Markup("")
    return Figure(key, section, caption, thesis, to_svg(fig, key), raster=raster)


def guarded(notes: list[str]):
    """``draw(fn, *args)``: the figure of ``fn``, or None with a note when it fails — one bad
    input file costs its figure, not the report.  Set ``CALFLOW_REPORT_STRICT=1`` to raise."""
    import logging
    import os

    def draw(fn, *args):
        try:
            return fn(*args)
        except Exception as exc:  # noqa: BLE001 — reported in the document and the log
            if os.environ.get("CALFLOW_REPORT_STRICT"):
                raise
            plt.close("all")
            logging.getLogger("calflow.report").warning("figure %s failed: %s", fn.__name__, exc)
            notes.append(f"The figure '{fn.__name__.replace('_', ' ')}' could not be drawn: {exc}")
            return None

    return draw


def number(figures: list[Figure]) -> list[Figure]:
    """Number figures 1, 2, … in the order given (the order of the report's sections)."""
    for i, f in enumerate(figures, start=1):
        f.number = i
    return figures


def by_section(figures: list[Figure]) -> dict[str, list[Figure]]:
    out: dict[str, list[Figure]] = {}
    for f in figures:
        out.setdefault(f.section, []).append(f)
    return out


@dataclass
class Inputs:
    """A campaign's result files by role: ``runs[plan]``, ``metrics[plan][tag]`` (tag = model,
    compensation, or ""), ``models[name]`` (paths), ``luts`` (dataset or None)."""

    runs: dict[str, xr.Dataset] = field(default_factory=dict)
    metrics: dict[str, dict[str, xr.Dataset]] = field(default_factory=dict)
    models: dict[str, Path] = field(default_factory=dict)
    luts: xr.Dataset | None = None
    unknown: list[str] = field(default_factory=list)


def classify(files) -> Inputs:
    """Open the result files (decoded lazily, no CF time decoding) and sort them by role."""
    out = Inputs()
    for path in files or []:
        path = Path(path)
        if path.suffix != ".nc" or not path.exists():
            out.unknown.append(str(path))
            continue
        with xr.open_dataset(path, engine="netcdf4", decode_times=False) as ds:
            attrs = dict(ds.attrs)
            kind, plan = attrs.get("calflow_kind"), attrs.get("plan", "")
            if kind == "model":
                out.models[str(attrs.get("model", path.stem))] = path
                continue
            ds = ds.load()
        if kind == "run":
            out.runs[plan] = ds
        elif kind == "metrics":
            tag = str(attrs.get("model") or attrs.get("compensation") or "")
            out.metrics.setdefault(plan, {})[tag] = ds
        elif kind == "luts":
            out.luts = ds
        else:
            out.unknown.append(str(path))
    return out


def finite(values) -> np.ndarray:
    """Floats with None → NaN (summary lists carry None for missing values)."""
    return np.array([np.nan if v is None else v for v in values], dtype=float)


def hours(run: xr.Dataset) -> np.ndarray:
    """Sample times of an undecoded run in hours since the campaign start."""
    t = np.asarray(run["time"].values, dtype=float)
    units = str(run["time"].attrs.get("units", "seconds"))
    scale = {"seconds": 1 / 3600, "minutes": 1 / 60, "hours": 1.0, "days": 24.0}.get(
        units.split()[0], 1 / 3600
    )
    return t * scale
