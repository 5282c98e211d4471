"""Which summary section each result file feeds: a family's plan → section registry.

A campaign's summary is assembled from its result files, recognised by their attributes
``calflow_kind`` (run, model, metrics, luts, truth) and ``plan``. A family registers, in
:class:`calflow.family.Family` field ``summary_sections``, the section each kind of file
feeds, as ``"kind:plan"`` (one plan) or ``"kind"`` (any plan of that kind, when no
``"kind:plan"`` entry matches), e.g. ``{"model": "models", "metrics:validation":
"reference_targets"}``. :func:`route` opens the files and groups them by section, so
the family's summary reads sections, not an if/elif chain over plan names;
:func:`summary_head` is the part every summary shares.

A summary job reads its result files for the family's summary, then for the uncertainty of
each figure its certificate states (:mod:`calflow.certificate.annotate`) and the
environment of its runs: within :func:`opened_once` each file is opened once and the
datasets are shared (each reader gets its own shallow copy).
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path

from calflow import __version__
from calflow.errors import DataError

_SHARED: dict[str, object] | None = None  # path -> dataset, within opened_once()


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
    out: dict[str, list[tuple[str, object]]] = {}
    for path in files:
        ds = open_result(path)
        kind, plan = ds.attrs.get("calflow_kind"), ds.attrs.get("plan")
        name = section_of(kind, plan, sections)
        if name is None:
            raise DataError(
                f"{path}: attributes calflow_kind={kind!r}, plan={plan!r}: expected a result file "
                f"of the {family or 'campaign'}'s summary (one of {sorted(sections)})"
            )
        out.setdefault(name, []).append((path, ds))
    return out


@contextmanager
def opened_once() -> Iterator[None]:
    """Within it, :func:`open_result` opens each result file once (a summary job's family
    summary and its certificate read the same files); outside, every call opens the file."""
    global _SHARED
    outer = _SHARED
    _SHARED = {} if outer is None else outer
    try:
        yield
    finally:
        _SHARED = outer


def open_result(path: str):
    """The result file ``path`` (:func:`calflow.data.io.open_dataset`), opened once within
    :func:`opened_once`: a shallow copy of the dataset opened first."""
    from calflow.data.io import open_dataset

    if _SHARED is None:
        return open_dataset(path)
    key = str(Path(path).resolve())
    if key not in _SHARED:
        _SHARED[key] = open_dataset(path)
    return _SHARED[key].copy(deep=False)


def already_open(path: str):
    """The dataset of ``path`` if :func:`open_result` opened it within :func:`opened_once`
    (a shallow copy), else None."""
    found = None if _SHARED is None else _SHARED.get(str(Path(path).resolve()))
    return None if found is None else found.copy(deep=False)
