"""Rendering reports: Jinja2 (autoescaped) to HTML, WeasyPrint to PDF from the same HTML."""

from __future__ import annotations

import json
import platform
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import jinja2

from calflow import __version__

TEMPLATES = Path(__file__).resolve().parent / "templates"
DEPENDENCIES = ("numpy", "scipy", "xarray", "netCDF4", "snakemake", "jinja2", "matplotlib", "weasyprint", "statsmodels")


def environment() -> jinja2.Environment:
    env = jinja2.Environment(
        loader=jinja2.FileSystemLoader(TEMPLATES),
        autoescape=True,
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
    )
    env.filters["num"] = lambda v, digits=3: "—" if v is None else f"{v:.{digits}f}"
    return env


def _versions() -> dict[str, str]:
    out = {"calflow": __version__, "python": platform.python_version()}
    for name in DEPENDENCIES:
        try:
            out[name] = version(name)
        except PackageNotFoundError:
            out[name] = "not installed"
    return out


def render_campaign(summary: dict, campaign: dict, command: str, files: list[str] | None = None) -> str:
    """The HTML report of one campaign; ``files`` are the result files its figures draw on."""
    template = environment().get_template(f"{summary['robot']}.html.j2")
    return template.render(
        s=summary,
        campaign_yaml=json.dumps({k: v for k, v in campaign.items() if k != "name"}, indent=2, sort_keys=True),
        versions=_versions(),
        command=command,
        css=(TEMPLATES / "style.css").read_text(),
    )


def render_index(summaries: list[dict]) -> str:
    """``reports/index.html``: every campaign's headline numbers beside the thesis's."""
    template = environment().get_template("index.html.j2")
    return template.render(summaries=summaries, versions=_versions(), css=(TEMPLATES / "style.css").read_text())


def write_pdf(html: str, base_url: str | Path) -> bytes:
    """The PDF rendering of ``html`` (WeasyPrint)."""
    import logging

    import weasyprint

    logging.getLogger("weasyprint").setLevel(logging.ERROR)
    logging.getLogger("fontTools").setLevel(logging.ERROR)
    return weasyprint.HTML(string=html, base_url=str(base_url)).write_pdf()
