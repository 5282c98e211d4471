"""Rendering reports: Jinja2 (autoescaped) to HTML, WeasyPrint to PDF from the same HTML.

One template family (``templates/base.html.j2`` and its children, ``macros.html.j2``) and
one stylesheet (``templates/style.css``, screen and print) serve every robot.  Figures are
matplotlib SVG generated in :mod:`calflow.report.figures`; they are the only markup the
templates embed unescaped.  Headline numbers carry ``data-key="dotted.summary.key"`` and
are formatted from the summary, so a test can read them back and compare.
"""

from __future__ import annotations

import math
import platform
import shlex
from dataclasses import replace
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import jinja2
import yaml

from calflow import __version__
from calflow.configuration import layout
from calflow.configuration.campaign import dig, thaw
from calflow.step import Job

TEMPLATES = Path(__file__).resolve().parent / "templates"
DEPENDENCIES = (
    "numpy",
    "scipy",
    "xarray",
    "netCDF4",
    "snakemake",
    "jinja2",
    "matplotlib",
    "weasyprint",
    "statsmodels",
)

_UNITS = {
    "um": "µm",
    "um-1": "µm⁻¹",
    "um-2": "µm⁻²",
    "um degC-1": "µm/°C",
    "degC": "°C",
    "degree": "°",
    "nm": "nm",
    "1": "—",
    "um/h": "µm/h",
    "h": "h",
}


_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


def is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def num(v, digits: int = 3) -> str:
    """Fixed-point text of a number; "—" for None, NaN or non-numbers."""
    if not is_number(v):
        return "—" if v is None or isinstance(v, float) else str(v)
    return f"{v:.{digits}f}"


def sig(v, digits: int = 4) -> str:
    """A number with ``digits`` significant digits; × 10^n notation when small or large."""
    if not is_number(v):
        return "—"
    if v == 0:
        return "0"
    exponent = math.floor(math.log10(abs(v)))
    if exponent < -3 or exponent >= 5:
        mantissa = v / 10**exponent
        if round(abs(mantissa), digits - 1) >= 10:
            mantissa, exponent = mantissa / 10, exponent + 1
        return f"{mantissa:.{digits - 1}f} × 10{str(exponent).translate(_SUPERSCRIPT)}"
    return f"{v:.{max(0, digits - 1 - exponent)}f}"


def unit(u) -> str:
    return _UNITS.get(str(u), str(u)) if u is not None else ""


def _family_templates() -> list[Path]:
    """The ``templates/`` folder of every installed robot family (``<robot>.html.j2``)."""
    from importlib.resources import files

    from calflow.family import families

    return [Path(str(files(family.templates) / "templates")) for family in families()]


def index_row(robot: str) -> str | None:
    """The template of ``robot``'s headline rows in the index (its family's ``index_row``)."""
    from calflow.family import families

    return next((fam.index_row for fam in families() if robot in fam.robots), None)


def environment() -> jinja2.Environment:
    from calflow.family import modes

    labels = modes()
    env = jinja2.Environment(
        loader=jinja2.FileSystemLoader([TEMPLATES, *_family_templates()]),
        autoescape=True,
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
    )
    env.filters.update(
        num=num,
        sig=sig,
        unit=unit,
        label=lambda n: str(n).replace("_", " "),
        mode=lambda n: labels.get(str(n), str(n).replace("_", " ")),
    )
    env.globals.update(dig=dig, is_number=is_number, index_row=index_row)
    return env


def _versions() -> dict[str, str]:
    out = {"calflow": __version__, "python": platform.python_version()}
    for name in DEPENDENCIES:
        try:
            out[name] = version(name)
        except PackageNotFoundError:
            out[name] = "not installed"
    return out


def _machine() -> str:
    return f"{platform.system()} {platform.release()} {platform.machine()}"


def _provenance(summary: dict, campaign: dict, command: str, files: list[str]) -> dict:
    from calflow.data.io import sha256_file

    inputs = dict(summary.get("inputs") or {})
    listed = {str(Path(p)) for p in inputs}
    extra = {}  # files the report draws on that the summary did not record
    for f in files or []:
        if str(Path(f)) not in listed and Path(f).is_file():
            extra[str(f)] = sha256_file(f)
    name = summary.get("campaign", campaign.get("name", "campaign"))
    report_cmd = (
        f"calflow report --campaign config/campaigns/{name}.yaml --summary {layout.summary(name)}"
        + (" --files " + " ".join(shlex.quote(str(f)) for f in files) if files else "")
        + f" --html {layout.report(name)} --pdf {layout.report(name, 'pdf')}"
    )
    return {
        "versions": _versions(),
        "machine": _machine(),
        "campaign_yaml": yaml.safe_dump(
            {k: thaw(v) for k, v in campaign.items() if not str(k).startswith("_")},
            sort_keys=False,
            allow_unicode=True,
            width=90,
            default_flow_style=None,
        ),
        "inputs": inputs,
        "extra_inputs": extra,
        "command": command,
        "report_command": report_cmd,
    }


def figures_for(summary: dict, files: list[str] | None, campaign: dict | None = None):
    """The numbered figures of a campaign's report, by section, and notes on omitted ones."""
    from calflow.family import family_of
    from calflow.report import figures as common

    inputs = common.classify(files)
    step = family_of(summary["robot"]).step("figures")  # a step hook: figures(c, args)
    figs, notes = step(campaign, Job.of("report", summary=summary, inputs=inputs))
    return common.by_section(common.number(figs)), notes


def render_campaign(summary: dict, campaign: dict, command: str, files: list[str] | None = None) -> str:
    """The HTML report of one campaign; ``files`` are the result files its figures draw on."""
    return render_campaign_pages(summary, campaign, command, files, pdf=False)[0]


def render_campaign_pages(
    summary: dict, campaign: dict, command: str, files: list[str] | None = None, pdf: bool = True
) -> tuple[str, str]:
    """The HTML report of one campaign (SVG figures) and the same page for the PDF, whose
    figures are the PNG renderings of the same matplotlib figures (:func:`write_pdf`).
    Figures are drawn once for both; with ``pdf=False`` no PNG is rendered and the second
    page is the first."""
    from calflow.report.figures import RASTER

    token = RASTER.set(pdf)
    try:
        figures, notes = figures_for(summary, files, campaign)
    finally:
        RASTER.reset(token)
    from calflow.family_contract import TEMPLATE

    template = environment().get_template(TEMPLATE.format(robot=summary["robot"]))
    declared = campaign.get("reference")
    context = dict(
        s=summary,
        reference_name=declared if isinstance(declared, str) else None,  # a family's named set
        notes=notes,
        prov=_provenance(summary, campaign, command, files or []),
        css=(TEMPLATES / "style.css").read_text(),
    )
    html = template.render(figures=figures, **context)
    if not pdf:
        return html, html
    printed = {section: [replace(f, svg=f.raster) for f in figs] for section, figs in figures.items()}
    return html, template.render(figures=printed, **context)


def render_index(
    catalogue: dict | list[dict], histories: list[dict] | None = None, fleets: list[dict] = ()
) -> str:
    """``reports/index.html``: every campaign on disk (:func:`calflow.report.catalogue.catalogue`)
    grouped by stage, newest first, with its headline beside the published values it declares,
    and the stage histories (``results/stages/<id>/history.json``) with a link to each report.
    A list of summaries renders them as done campaigns of no stage, in the order given.
    ``fleets``: the fleet table's rows, :func:`calflow.lifecycle.fleet.fleets` of the histories
    (the lifecycle computes them; the report renders what it is given)."""
    if isinstance(catalogue, list):
        rows = [
            {
                "campaign": s["campaign"],
                "robot": s.get("robot"),
                "rig": s.get("rig"),
                "summary": s,
                "status": "done",
                "date": "—",
                "written": "—",
                "error": None,
                "stale": [],
                "current": None,
                "report": True,
                "headline": None,
            }
            for s in catalogue
        ]
        catalogue = {
            "groups": [{"stage": None, "history": False, "campaigns": rows}] if rows else [],
            "histories": histories or [],
        }
    template = environment().get_template("index.html.j2")
    hist = histories if histories is not None else catalogue.get("histories") or []
    rows = [c for g in catalogue["groups"] for c in g["campaigns"]]
    return template.render(
        groups=catalogue["groups"],
        rows=rows,
        measured=[c for c in rows if c.get("footprint")],  # what the jobs measured of themselves
        histories=hist,
        fleets=list(fleets),
        versions=_versions(),
        machine=_machine(),
        css=(TEMPLATES / "style.css").read_text(),
    )


def write_pdf(html: str, base_url: str | Path, attachments: dict[str, bytes] | None = None) -> bytes:
    """The PDF rendering of ``html`` (WeasyPrint, print media of the same stylesheet).

    For a campaign report pass the second page of :func:`render_campaign_pages`: inline SVG
    figures cost WeasyPrint seconds each (CSS on every element, then drawing), PNGs nothing.
    ``attachments``: files embedded in the PDF (name → bytes; a certificate carries its DCC).
    """
    import logging

    import weasyprint

    logging.getLogger("weasyprint").setLevel(logging.ERROR)
    logging.getLogger("fontTools").setLevel(logging.ERROR)
    import datetime as dt
    import os
    from io import BytesIO

    # the embedded files' dates: SOURCE_DATE_EPOCH when set (WeasyPrint stamps them "now"
    # otherwise), so the same results give the same PDF bytes
    epoch = os.environ.get("SOURCE_DATE_EPOCH", "")
    when = dt.datetime.fromtimestamp(int(epoch), dt.UTC) if epoch.isdigit() else None
    files = [
        weasyprint.Attachment(
            file_obj=BytesIO(data), name=name, relationship="Data", created=when, modified=when
        )
        for name, data in (attachments or {}).items()
    ]
    return weasyprint.HTML(string=html, base_url=str(base_url)).write_pdf(attachments=files)
