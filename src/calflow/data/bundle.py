"""An export bundle of a calibrated model: its provenance, its ``bundle.json``, its Compensator.

A family's export folder holds ``bundle.json`` (the model's parameters and what the family
adds: tables, geometry, conventions) beside its own files; this module writes and reads the
parts every family shares — the provenance (campaign, configuration hash, the model file's
metadata and SHA-256, calflow's version), the JSON written last as the marker of a complete
export, the format and parameter checks of a bundle read back — and the shell of the
family's ``Compensator`` (load a bundle, hold the model, give its parameters).
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any, ClassVar

from calflow import __version__
from calflow.data.io import sha256_file, write_json
from calflow.errors import DataError

BUNDLE = "bundle.json"


def provenance(model_path) -> dict:
    """Where the model came from: the model file's metadata and hash, and this calflow."""
    import xarray as xr

    with xr.open_dataset(model_path, engine="netcdf4", decode_times=False) as ds:
        attrs = dict(ds.attrs)
    return {
        "campaign": attrs.get("campaign"),
        "config_sha256": attrs.get("config_sha256"),
        "source": attrs.get("source"),
        "model_created": attrs.get("created"),
        "model_calflow_version": attrs.get("calflow_version"),
        "export_calflow_version": __version__,
        "model_file": Path(model_path).name,
        "model_sha256": sha256_file(model_path),
    }


def write_bundle(folder, document: Callable[[Path], dict]) -> Path:
    """Create ``folder``, build the bundle's content with ``document(folder)`` (which may write
    the family's own files there first) and write it as ``bundle.json``, last; returns its path."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    return write_json(document(folder), folder / BUNDLE)


def read_bundle(path, fmt: str, version: int, parameters: Iterable[str]) -> tuple[Path, dict[str, Any]]:
    """``bundle.json`` of a folder (or the file itself) and its content, checked: the file
    exists, is JSON, has ``format`` ``fmt`` and ``version``, and a number as the ``value`` of
    each of ``parameters``. A failure is a :class:`DataError` naming the file and the field."""
    path = Path(path)
    path = path / BUNDLE if path.is_dir() else path
    if not path.exists():
        raise DataError(f"{path}: file not found")
    try:
        doc = json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise DataError(f"{path}: not JSON ({exc})") from None
    if doc.get("format") != fmt or doc.get("version") != version:
        raise DataError(
            f"{path}: fields 'format', 'version': expected {fmt!r} {version}, "
            f"got {doc.get('format')!r} {doc.get('version')!r}"
        )
    params = doc.get("parameters") or {}
    for name in parameters:
        if not isinstance((params.get(name) or {}).get("value"), (int, float)):
            raise DataError(f"{path}: field 'parameters.{name}.value': expected a number")
    return path, doc


class Compensator:
    """The shell of a family's Compensator: an exported model for users' own code.

    A family subclasses it with ``read_model = staticmethod(its_reader)`` (path → model) and
    adds what its model computes; ``model.parameters.as_dict()`` gives :attr:`parameters`."""

    read_model: ClassVar[Callable[[Any], Any]]

    def __init__(self, model):
        self.model = model

    @classmethod
    def load(cls, path):
        """From an export folder or its ``bundle.json``."""
        return cls(cls.read_model(path))

    @property
    def parameters(self) -> dict[str, float]:
        """Every identified parameter by name, in its unit (the bundle's ``parameters``)."""
        return self.model.parameters.as_dict()
