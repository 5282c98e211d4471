"""Which summary section each result file feeds: a family's plan → section registry.

A campaign's summary is assembled from its result files, recognised by their attributes
``calflow_kind`` (run, model, metrics, luts, truth) and ``plan``. A family registers, in
:class:`calflow.family.Family` field ``summary_sections``, the section each kind of file
feeds, as ``"kind:plan"`` (one plan) or ``"kind"`` (any plan of that kind, when no
``"kind:plan"`` entry matches), e.g. ``{"model": "models", "metrics:validation":
"reference_targets"}``. :func:`route` opens the files once and groups them by section, so
the family's summary reads sections, not an if/elif chain over plan names;
:func:`summary_head` is the part every summary shares.
"""

from __future__ import annotations

from collections.abc import Mapping

from calflow import __version__
from calflow.errors import DataError


def summary_head(campaign: Mapping, robot: str | None = None) -> dict:
    """The fields every campaign summary opens with: the campaign's name, its robot (the
    campaign's unless a family names its own), description, the calflow version that wrote
    it, the seed and the rig's factory."""
    return {
        "campaign": campaign["name"],
        "robot": campaign["robot"] if robot is None else robot,
        "description": campaign.get("description", ""),
        "calflow_version": __version__,
        "seed": campaign.get("seed"),
        "rig": (campaign.get("rig") or {}).get("factory"),
    }


def section_of(kind: str | None, plan: str | None, sections: Mapping[str, str]) -> str | None:
    """The section a file of ``kind`` and ``plan`` feeds; None when the registry has none."""
    return sections.get(f"{kind}:{plan}", sections.get(str(kind)))


def route(
    files: list[str], sections: Mapping[str, str], family: str = ""
) -> dict[str, list[tuple[str, object]]]:
    """Open each netCDF result file and group ``(path, dataset)`` by summary section, in the
    order of ``files``. A file whose kind and plan feed no section is bad input: the one-line
    error names the file, its kind and plan and the sections the family registers."""
    from calflow.data.io import open_dataset

    out: dict[str, list[tuple[str, object]]] = {}
    for path in files:
        ds = open_dataset(path)
        kind, plan = ds.attrs.get("calflow_kind"), ds.attrs.get("plan")
        name = section_of(kind, plan, sections)
        if name is None:
            raise DataError(
                f"{path}: attributes calflow_kind={kind!r}, plan={plan!r}: expected a result file "
                f"of the {family or 'campaign'}'s summary (one of {sorted(sections)})"
            )
        out.setdefault(name, []).append((path, ds))
    return out
